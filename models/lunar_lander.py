"""Planar lunar soft landing in polar coordinates (seed 002, Jamilnia 2017, eqs (1)-(5)).

States: r (radius from the Moon's centre), theta (position angle from the descent
start), u (tangential speed), v (radial speed, positive outward), m (mass).
Control: beta, the thrust angle from the local horizontal (beta = 0 thrusts along +u,
beta = pi/2 straight up). Constant thrust T, always on:

    r' = v,  theta' = u/r,
    u' = -u v / r + (T/m) cos(beta),
    v' = u^2/r - mu/r^2 + (T/m) sin(beta),
    m' = -T / (Isp g0).

Units (option ``units``):

* ``"km"`` (default): r in km, u and v in km/s, mu in km^3/s^2, R in km; thrust T is in
  newtons and mass in kg, so the thrust acceleration is written ``T/(1000 m)`` km/s^2;
  Isp in s, g0 in m/s^2 (so ``T/(Isp g0)`` is kg/s). Time in s, angles in rad.
* ``"m"``: SI throughout (r in m, speeds in m/s, mu in m^3/s^2, R in m).

Parameters (Table 1 of the seed): T = 440 N, Isp = 310 s, g0 = 9.807 m/s^2,
mu = 4904.8695 km^3/s^2, R = 1737.1 km (lunar radius), M = 300 kg (mass in the 100 km
parking orbit), h_p = 100 km (parking-orbit altitude).

:func:`hohmann_entry` computes the Hohmann pre-phase (seed eqs (13)-(15)): the speed at
the transfer's periapsis and the mass left after the impulsive de-orbit burn (rocket
equation).
"""
from __future__ import annotations

import math

import sympy as sp

from ocdsl.symbolic.model import Model, sym, syms
from ocdsl.symbolic.registry import register

#: Table 1 of the seed, in the model's "km" units (T in N, Isp in s, g0 in m/s^2).
CONSTANTS_KM = {"T": 440.0, "Isp": 310.0, "g0": 9.807, "mu": 4904.8695, "R": 1737.1,
                "M": 300.0, "h_p": 100.0}


def constants(units: str = "km") -> dict[str, float]:
    """Table-1 constants in the given unit system ("km" or "m")."""
    c = dict(CONSTANTS_KM)
    if units == "m":
        c.update(mu=c["mu"] * 1e9, R=c["R"] * 1e3, h_p=c["h_p"] * 1e3)
    elif units != "km":
        raise ValueError(f"units must be 'km' or 'm', not {units!r}")
    return c


@register("lunar_lander_polar",
          description="planar lunar soft landing, polar coordinates, constant thrust, "
                      "control = thrust angle (Jamilnia 2017)",
          options={"units": "km (default: km, km/s, km^3/s^2) | m (SI)"})
def build(options: dict) -> Model:
    units = options.get("units", "km")
    c = constants(units)
    r, theta, u, v, m = syms("r theta u v m")
    beta = sym("beta")
    T, Isp, g0, mu, R, M, h_p = syms("T Isp g0 mu R M h_p")
    acc = T / (1000 * m) if units == "km" else T / m   # thrust acceleration
    dist, speed = ("km", "km/s") if units == "km" else ("m", "m/s")
    return Model(
        "lunar_lander_polar",
        (r, theta, u, v, m), (beta,),
        {r: v,
         theta: u / r,
         u: -u * v / r + acc * sp.cos(beta),
         v: u ** 2 / r - mu / r ** 2 + acc * sp.sin(beta),
         m: -T / (Isp * g0)},
        parameters={T: c["T"], Isp: c["Isp"], g0: c["g0"], mu: c["mu"], R: c["R"],
                    M: c["M"], h_p: c["h_p"]},
        units={"r": dist, "theta": "rad", "u": speed, "v": speed, "m": "kg", "beta": "rad",
               "T": "N", "Isp": "s", "g0": "m/s^2", "mu": f"{dist}^3/s^2", "R": dist,
               "M": "kg", "h_p": dist, "t": "s"},
        description="Planar lunar landing (r, theta, u, v, m), thrust angle beta from the "
                    f"local horizontal, units {units}",
        positions=("r", "theta"),
    )


def hohmann_entry(h_i: float, units: str = "km") -> dict[str, float]:
    """Hohmann transfer from the parking orbit down to altitude ``h_i`` (seed (13)-(15)).

    Returns ``r0`` (periapsis radius), ``u0`` (periapsis speed, the descent's initial
    tangential speed), ``dv`` (de-orbit burn, positive), ``m0`` (mass after the burn,
    rocket equation m0 = M exp(-dv/(Isp g0))), all in the model's units.
    """
    c = constants(units)
    to_ms = 1000.0 if units == "km" else 1.0
    r_p = c["R"] + c["h_p"]
    r_i = c["R"] + h_i
    v_circ = math.sqrt(c["mu"] / r_p)
    v_apo = math.sqrt(c["mu"] * (2 / r_p - 2 / (r_i + r_p)))
    u0 = math.sqrt(c["mu"] * (2 / r_i - 2 / (r_i + r_p)))
    dv = v_circ - v_apo
    m0 = c["M"] * math.exp(-dv * to_ms / (c["Isp"] * c["g0"]))
    return {"r0": r_i, "u0": u0, "dv": dv, "m0": m0}


def mass_flow(units: str = "km") -> float:
    """Propellant mass flow T/(Isp g0) in kg/s."""
    c = constants(units)
    return c["T"] / (c["Isp"] * c["g0"])
