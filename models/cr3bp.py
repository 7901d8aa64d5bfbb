"""Earth-Moon circular restricted three-body problem with a low-thrust engine (seed 1).

Two registered forms of the same dynamics (digest seed_001 §2.3, §2.7):

- ``cr3bp_cartesian``: synodic barycentric rotating frame, state (x, y, z, vx, vy, vz, m),
  thrust along the control vector (ux, uy, uz) (a unit direction; option
  ``mass_flow: norm`` makes the mass flow proportional to its norm so that |u| <= 1 can
  be a throttle);
- ``cr3bp_polar``: the paper's Earth-centred rotating polar form (eq. 28), state
  (r, theta, z, rdot, thetadot, zdot, m), thrust direction from the angles delta
  (in-plane, from the transverse direction toward the radial one) and phi (from +z).

Units: lengths in LU (Earth-Moon distance, parameter ``LU`` in km), times in TU (1/n,
parameter ``TU`` in s), mass in units of the initial mass (parameter ``m0`` in kg).
The thrust (N), Isp (s) and g0 (m/s^2) are parameters; the non-dimensional exhaust
velocity ``c`` and thrust acceleration ``T_max`` are named expressions derived from them.

Option ``sundman_k`` (with ``sundman_c``, default 1) regularises the independent
variable: dt = c * R^k ds with R the distance to the Earth. The model is then written in
s, with an extra state ``time`` (physical time, dtime/ds = c R^k); controls that depend
on time must use the state ``time`` (the simulator's ``clock`` state).
"""
from __future__ import annotations

import sympy as sp

from ocdsl.symbolic.model import Model, syms
from ocdsl.symbolic.registry import register

MU = 0.0121506683
LU_KM = 384405.0
TU_S = 375676.967

_OPTIONS = {
    "sundman_k": "exponent k of the Sundman regularisation dt = c R^k ds (R: distance to Earth); off when absent",
    "sundman_c": "constant c of the Sundman regularisation (default 1)",
}


def _parameters():
    mu, LU, TU, Isp, g0, thrust, m0 = syms("mu LU TU Isp g0 thrust m0")
    params = {mu: MU, LU: LU_KM, TU: TU_S, Isp: 3000.0, g0: 9.80665, thrust: 10.0, m0: 1500.0}
    c, T_max = syms("c T_max")
    # VU = LU*1000/TU m/s; acceleration unit LU*1000/TU**2 m/s^2
    exprs = {c: Isp * g0 * TU / (LU * 1000),
             T_max: thrust / m0 * TU**2 / (LU * 1000)}
    units = {"mu": "-", "LU": "km", "TU": "s", "Isp": "s", "g0": "m/s^2", "thrust": "N",
             "m0": "kg", "c": "LU/TU", "T_max": "LU/TU^2"}
    return params, exprs, units, (mu, c, T_max)


EARTH_RADIUS_KM = 6378.137
MOON_RADIUS_KM = 1737.4


def l1_distance(mu: float) -> float:
    """Distance gamma of L1 from the Moon toward the Earth (Szebehely's quintic
    gamma^5 - (3 - mu) gamma^4 + (3 - 2 mu) gamma^3 - mu gamma^2 + 2 mu gamma - mu = 0, by
    Newton from Hill's approximation (mu/3)^(1/3))."""
    g = (mu / 3.0) ** (1.0 / 3.0)
    for _ in range(50):
        f = g**5 - (3 - mu) * g**4 + (3 - 2 * mu) * g**3 - mu * g**2 + 2 * mu * g - mu
        df = 5 * g**4 - 4 * (3 - mu) * g**3 + 3 * (3 - 2 * mu) * g**2 - 2 * mu * g + 2 * mu
        step = f / df
        g -= step
        if abs(step) < 1e-15:
            break
    return g


def _frame(earth_centred: bool):
    """The synodic frame's Earth, Moon and L1 for the reports (positions in LU: barycentric
    for the Cartesian form, Earth-centred for the polar one)."""
    def frame(values) -> dict:
        mu = float(values.get("mu", MU))
        lu = float(values.get("LU", LU_KM))
        shift = mu if earth_centred else 0.0        # barycentre -> Earth-centred
        return {"name": "Earth-Moon synodic frame (rotating with the Moon; "
                        + ("Earth-centred)" if earth_centred else "barycentric)"),
                "coordinates": "cylindrical" if earth_centred else "cartesian",
                "bodies": [{"name": "Earth", "at": [-mu + shift, 0.0, 0.0], "radius": EARTH_RADIUS_KM / lu},
                           {"name": "Moon", "at": [1 - mu + shift, 0.0, 0.0], "radius": MOON_RADIUS_KM / lu}],
                "points": [{"name": "L1", "at": [1 - mu - l1_distance(mu) + shift, 0.0, 0.0]}]}
    return frame


def _maybe_sundman(model: Model, options: dict, distance: sp.Expr) -> Model:
    k = options.get("sundman_k")
    if k is None:
        return model
    from ocdsl.simulate.sundman import sundman     # with ocdsl.simulate: only for this option

    return sundman(model, distance, float(k), float(options.get("sundman_c", 1.0)))


@register("cr3bp_cartesian",
          description="Earth-Moon CR3BP, synodic Cartesian, low thrust along (ux, uy, uz) with mass flow",
          options={**_OPTIONS, "mass_flow": "'constant' (T_max/c, default) or 'norm' (T_max |u|/c)"})
def cartesian(options) -> Model:
    x, y, z, vx, vy, vz, m = syms("x y z vx vy vz m")
    ux, uy, uz = syms("ux uy uz")
    params, exprs, units, (mu, c, T_max) = _parameters()
    r1, r2 = syms("r1 r2")
    exprs = {r1: sp.sqrt((x + mu) ** 2 + y**2 + z**2),
             r2: sp.sqrt((x + mu - 1) ** 2 + y**2 + z**2), **exprs}
    flow = options.get("mass_flow", "constant")
    if flow not in ("constant", "norm"):
        raise ValueError(f"cr3bp_cartesian: mass_flow must be 'constant' or 'norm', not {flow!r}")
    mdot = -T_max / c if flow == "constant" else -T_max * sp.sqrt(ux**2 + uy**2 + uz**2) / c
    dyn = {
        x: vx, y: vy, z: vz,
        vx: 2 * vy + x - (1 - mu) * (x + mu) / r1**3 - mu * (x + mu - 1) / r2**3 + T_max / m * ux,
        vy: -2 * vx + y - (1 - mu) * y / r1**3 - mu * y / r2**3 + T_max / m * uy,
        vz: -(1 - mu) * z / r1**3 - mu * z / r2**3 + T_max / m * uz,
        m: mdot,
    }
    units.update({n: "LU" for n in ("x", "y", "z", "r1", "r2")})
    units.update({n: "LU/TU" for n in ("vx", "vy", "vz")})
    units.update({"m": "m0", "ux": "-", "uy": "-", "uz": "-", "t": "TU"})
    model = Model("cr3bp_cartesian", (x, y, z, vx, vy, vz, m), (ux, uy, uz), dyn, params,
                  exprs, units, "Earth-Moon CR3BP, synodic frame, low thrust with mass flow (eq. 8)",
                  ("x", "y", "z"), frame=_frame(earth_centred=False))
    return _maybe_sundman(model, options, sp.sqrt((x + mu) ** 2 + y**2 + z**2))


@register("cr3bp_polar",
          description="Earth-Moon CR3BP in the Earth-centred rotating polar frame (seed 1, eq. 28), thrust angles delta, phi",
          options=dict(_OPTIONS))
def polar(options) -> Model:
    r, theta, z, rdot, thetadot, zdot, m = syms("r theta z rdot thetadot zdot m")
    delta, phi = syms("delta phi")
    params, exprs, units, (mu, c, T_max) = _parameters()
    R_SE, R_SM = syms("R_SE R_SM")
    exprs = {R_SE: sp.sqrt(r**2 + z**2),
             R_SM: sp.sqrt(r**2 - 2 * r * sp.cos(theta) + z**2 + 1), **exprs}
    acc = T_max / m
    dyn = {
        r: rdot, theta: thetadot, z: zdot,
        rdot: (r * (1 + thetadot) ** 2 - mu * sp.cos(theta) - (1 - mu) * r / R_SE**3
               - mu * (r - sp.cos(theta)) / R_SM**3 + acc * sp.sin(delta) * sp.sin(phi)),
        thetadot: (-2 * rdot * (1 + thetadot) + mu * sp.sin(theta) * (1 - 1 / R_SM**3)
                   + acc * sp.cos(delta) * sp.sin(phi)) / r,
        zdot: (-(1 - mu) / R_SE**3 - mu / R_SM**3) * z + acc * sp.cos(phi),
        m: -T_max / c,
    }
    units.update({"r": "LU", "z": "LU", "R_SE": "LU", "R_SM": "LU", "theta": "rad",
                  "rdot": "LU/TU", "zdot": "LU/TU", "thetadot": "rad/TU", "m": "m0",
                  "delta": "rad", "phi": "rad", "t": "TU"})
    model = Model("cr3bp_polar", (r, theta, z, rdot, thetadot, zdot, m), (delta, phi), dyn,
                  params, exprs, units,
                  "Earth-Moon CR3BP, Earth-centred rotating polar frame (ECRF, eq. 28), thrust angles",
                  ("r", "theta", "z"), frame=_frame(earth_centred=True))
    return _maybe_sundman(model, options, sp.sqrt(r**2 + z**2))
