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


@register("lunar_lander_vertical",
          description="vertical lunar descent (theta fixed, u = 0), constant thrust straight "
                      "up: the seed's strategy-3 second phase",
          options={"units": "km (default) | m"})
def build_vertical(options: dict) -> Model:
    """r' = v, v' = -mu/r^2 + T/m, m' = -T/(Isp g0): the polar lander with u = 0 and
    beta = pi/2 (no control; same units and parameters as ``lunar_lander_polar``)."""
    units = options.get("units", "km")
    c = constants(units)
    r, v, m = syms("r v m")
    T, Isp, g0, mu, R = syms("T Isp g0 mu R")
    acc = T / (1000 * m) if units == "km" else T / m
    dist, speed = ("km", "km/s") if units == "km" else ("m", "m/s")
    return Model(
        "lunar_lander_vertical", (r, v, m), (),
        {r: v, v: -mu / r ** 2 + acc, m: -T / (Isp * g0)},
        parameters={T: c["T"], Isp: c["Isp"], g0: c["g0"], mu: c["mu"], R: c["R"]},
        units={"r": dist, "v": speed, "m": "kg", "T": "N", "Isp": "s", "g0": "m/s^2",
               "mu": f"{dist}^3/s^2", "R": dist, "t": "s"},
        description=f"Vertical lunar descent under constant upward thrust, units {units}",
        positions=("r",),
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


# ---------------------------------------------------------------------------------------
# The seed's three strategies as flat B-spline problems (Pyomo imported lazily so that
# loading the model registry stays light).
# ---------------------------------------------------------------------------------------
#: Seed Tables 2 and 3 as printed: strategy 1/2 rows keyed by the intermediate-orbit
#: altitude (100 = strategy 1, direct from the parking orbit): (landing time s, final
#: mass kg, final thrust angle deg); strategy 3 rows keyed by the vertical-descent start
#: altitude: (v12 m/s, braking time s, descent time s, final mass kg).
TABLE2 = {100: (1036.458, 149.932, 122.853), 50: (1012.252, 152.384, 127.473),
          25: (1001.326, 153.395, 130.186), 20: (999.288, 153.575, 130.757),
          15: (997.303, 153.747, 131.337), 10: (995.371, 153.911, 131.927),
          5: (993.586, 154.053, 133.528)}
TABLE3 = {5: (-109.201, 959.520, 83.436, 147.140), 4: (-95.115, 963.165, 72.497, 148.195),
          3: (-81.685, 967.450, 61.752, 149.130), 2: (-62.442, 974.204, 46.391, 150.376),
          1: (-39.145, 983.827, 27.584, 151.705)}


def initial_conditions(h_i: float) -> dict[str, float]:
    """Descent start (km units): strategy 1 for h_i equal to the parking altitude (100 km:
    circular speed, no burn), else the Hohmann entry of strategy 2/3."""
    c = constants("km")
    if h_i == c["h_p"]:
        r0 = c["R"] + h_i
        return {"r0": r0, "u0": math.sqrt(c["mu"] / r0), "dv": 0.0, "m0": c["M"]}
    return hohmann_entry(h_i)


def seed_problem(h_i: float, h_v: float | None = None, degree: int = 5, n_ctrl: int = 15,
                 n_col: int = 15, v_land: float = -5.0, descent_ctrl: int | None = None,
                 descent_col: int | None = None):
    """Phases and links of one row of the seed's tables (flat B-spline transcription).

    ``h_i``: intermediate-orbit altitude in km (100 = strategy 1); ``h_v``: altitude of the
    vertical-descent start in km (strategy 3, two phases ``braking`` and ``descent``);
    None for strategies 1-2 (one phase ``main``). ``v_land`` in m/s. Returns
    ``(phases, links)`` for :func:`ocdsl.transcribe.flat_bspline.build_flat_bspline`.
    """
    from ocdsl.transcribe.flat_bspline import FlatBSplineOptions, FlatPhase

    from ocdsl.symbolic.flatness import flatten

    c = constants("km")
    R = c["R"]
    ic = initial_conditions(h_i)
    r0, u0, m0 = ic["r0"], ic["u0"], ic["m0"]
    model = build({})
    opts = FlatBSplineOptions(degree, n_ctrl, n_col)
    start = {("r", "t0"): r0, ("theta", "t0"): 0.0, ("u", "t0"): u0, ("v", "t0"): 0.0,
             ("m", "t0"): m0}
    bounds = {"r": (R, r0 + 30.0), "theta": (0.0, 1.5)}
    fm = flatten(model, ["r", "theta"], bounds=bounds)
    land = {("r", "tf"): R, ("u", "tf"): 0.0, ("v", "tf"): v_land / 1000.0}
    if h_v is None:
        tf = 1000.0
        main = FlatPhase("main", model, {**start, **land}, (300.0, 3000.0), tf, ["r", "theta"],
                         bounds, guess={"r": lambda t: r0 + (R - r0) * (3 * t ** 2 - 2 * t ** 3),
                                        "theta": lambda t: u0 * tf / r0 * (t - t * t / 2)},
                         options=opts, flatmap=fm)
        return [main], []
    r12 = R + h_v
    # guess: vertical descent at constant net deceleration a ~ T/m - g_moon from v12 to
    # v_land over h_v; braking as in strategy 2, ending at r12 with speed v12
    a = (c["T"] / 160.0 - c["mu"] / R ** 2 * 1000.0) / 1000.0          # km/s^2
    vl = v_land / 1000.0
    v12 = -math.sqrt(vl ** 2 + 2 * a * h_v)
    td = (vl - v12) / a
    tb = 1000.0 - td

    def r_brake(t):   # cubic Hermite: r0 (slope 0) to r12 (slope v12 * tb)
        h00, h01, h11 = 2 * t ** 3 - 3 * t ** 2 + 1, -2 * t ** 3 + 3 * t ** 2, t ** 3 - t ** 2
        return h00 * r0 + h01 * r12 + h11 * v12 * tb

    braking = FlatPhase("braking", model, {**start, ("r", "tf"): r12, ("u", "tf"): 0.0},
                        (300.0, 3000.0), tb, ["r", "theta"], bounds,
                        guess={"r": r_brake,
                               "theta": lambda t: u0 * tb / r0 * (t - t * t / 2)},
                        options=opts, flatmap=fm)
    # vertical descent: theta constant and u = 0, thrust straight up (no control left);
    # flat output r, residual r'' + mu/r^2 - T/m = 0 (see docs/flatness.md)
    vmodel = build_vertical({})
    dopts = FlatBSplineOptions(degree, descent_ctrl or n_ctrl, descent_col or n_col)
    descent = FlatPhase("descent", vmodel,
                        {("r", "t0"): r12, ("r", "tf"): R, ("v", "tf"): v_land / 1000.0},
                        (1.0, 500.0), td, ["r"], {"r": (R, r12 + 5.0)},
                        guess={"r": lambda t: r12 + v12 * td * t + a * (td * t) ** 2 / 2,
                               "m_t0": m0 - mass_flow() * tb},
                        options=dopts)
    links = [(("braking", s, "tf"), ("descent", s, "t0")) for s in ("v", "m")]
    return [braking, descent], links
