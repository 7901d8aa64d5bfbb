"""Rigid spacecraft with reaction wheels, 3-2-1 Euler angles (seed 3: Navabi, Tavana &
Mirzaei 2015, model of Xin & Lam 2010). See ../shared/seeds/seed_003.md.

States: phi, theta, psi (roll, pitch, yaw, rad), their integrals iphi, itheta, ipsi, the
body rates wx, wy, wz (rad/s) and the wheel-assembly momentum hx, hy, hz (N m s, body
frame) as auxiliary states (``AUXILIARY``): the controller does not regulate them, but
they enter the gyroscopic term of the dynamics (paper eq. 4, 7).

    I w' = -w x (I w) - w x h + T_rwa,      h' = -T_rwa,      I = diag(J1, J2, J3)

Options
-------
``wheels``:
  ``torque`` (default): T_rwa = [Tx, Ty, Tz] is the control (the paper's simulation model,
  eqs. 32, 38: B = I^-1, R 3x3).
  ``2``: only wheels 3 and 4 of the skewed pyramid work (paper eq. 2), controls T3, T4,
  T_rwa = C34 [T3, T4] with C34 = [[0.67, 0.67], [0.53, 0.53], [-0.53, 0.53]]; the
  9-state (A0, B) pair then has controllability rank 6 of 9 (seed check B6).
  ``4``: the full pyramid, wheel i along [0.67, +-0.53, +-0.53] (wheels 1, 2 mirrored from 3, 4
  as the seed reconstructs them), controls T1..T4.
``momentum``: ``state`` (default; h carried as auxiliary states, h(0) free) or ``zero``
  (h dropped from the dynamics, 9 states only).

J1 is unreadable in the paper (``diag[(0 40 60)]``); 50 is the seed's placeholder.
"""
from __future__ import annotations

import sympy as sp

from ocdsl.symbolic.model import Model, sym, syms
from ocdsl.symbolic.registry import register

AUXILIARY = ("hx", "hy", "hz")
C_PYRAMID = {  # wheel spin axes in the body frame (paper eq. 2 for wheels 3 and 4)
    1: (0.67, -0.53, -0.53),
    2: (0.67, -0.53, 0.53),
    3: (0.67, 0.53, -0.53),
    4: (0.67, 0.53, 0.53),
}


def _skew(v):
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


@register("spacecraft_wheels",
          description="rigid spacecraft, 3-2-1 Euler angles + integrals + body rates, "
                      "reaction-wheel momentum as auxiliary states (seed 3)",
          options={"wheels": "torque (3-axis body torque, default) | 2 (wheels 3, 4 of the "
                             "pyramid) | 4 (full pyramid)",
                   "momentum": "state (h as auxiliary states, default) | zero"})
def build(options: dict) -> Model:
    wheels = str(options.get("wheels", "torque"))
    momentum = str(options.get("momentum", "state"))
    if wheels not in ("torque", "2", "4"):
        raise ValueError(f"spacecraft_wheels: option wheels={wheels!r}; use torque, 2 or 4")
    if momentum not in ("state", "zero"):
        raise ValueError(f"spacecraft_wheels: option momentum={momentum!r}; use state or zero")
    phi, theta, psi = syms("phi theta psi")
    iphi, itheta, ipsi = syms("iphi itheta ipsi")
    wx, wy, wz = syms("wx wy wz")
    J1, J2, J3, Iw = syms("J1 J2 J3 Iw")
    w = sp.Matrix([wx, wy, wz])
    I = sp.diag(J1, J2, J3)
    if wheels == "torque":
        controls = syms("Tx Ty Tz")
        torque = sp.Matrix(controls)
    else:
        ids = (3, 4) if wheels == "2" else (1, 2, 3, 4)
        controls = tuple(sym(f"T{i}") for i in ids)
        C = sp.Matrix([[sp.Float(c) for c in C_PYRAMID[i]] for i in ids]).T
        torque = C * sp.Matrix(controls)
    if momentum == "state":
        hx, hy, hz = syms("hx hy hz")
        h = sp.Matrix([hx, hy, hz])
    else:
        h = sp.zeros(3, 1)
    wdot = I.inv() * (-_skew(w) * (I * w) - _skew(w) * h + torque)
    dyn = {
        phi: wx + (wy * sp.sin(phi) + wz * sp.cos(phi)) * sp.tan(theta),
        theta: wy * sp.cos(phi) - wz * sp.sin(phi),
        psi: (wy * sp.sin(phi) + wz * sp.cos(phi)) / sp.cos(theta),
        iphi: phi, itheta: theta, ipsi: psi,
        wx: wdot[0], wy: wdot[1], wz: wdot[2],
    }
    states = [phi, theta, psi, iphi, itheta, ipsi, wx, wy, wz]
    units = {"phi": "rad", "theta": "rad", "psi": "rad", "iphi": "rad s", "itheta": "rad s",
             "ipsi": "rad s", "wx": "rad/s", "wy": "rad/s", "wz": "rad/s",
             "J1": "kg m^2", "J2": "kg m^2", "J3": "kg m^2", "Iw": "kg m^2"}
    if momentum == "state":
        for hi, ti in zip(h, torque):
            dyn[hi] = -ti
            units[str(hi)] = "N m s"
        states += list(h)
    for c in controls:
        units[str(c)] = "N m"
    return Model("spacecraft_wheels", tuple(states), tuple(controls), dyn,
                 parameters={J1: 50.0, J2: 40.0, J3: 60.0, Iw: 0.01}, units=units,
                 description="rigid spacecraft with reaction wheels, 3-2-1 Euler angles "
                             f"(wheels={wheels}, momentum={momentum})")


def paper_sdc_matrix(model: Model) -> sp.Matrix:
    """The paper's F(x) (eqs. 36-37) for the 9 controlled states of ``build({})``."""
    s = {n: model.symbol(n) for n in ("phi", "theta", "wx", "wy", "wz", "J1", "J2", "J3")}
    phi, theta = s["phi"], s["theta"]
    w = sp.Matrix([s["wx"], s["wy"], s["wz"]])
    I = sp.diag(s["J1"], s["J2"], s["J3"])
    try:
        h = sp.Matrix([model.symbol(n) for n in AUXILIARY])
    except KeyError:
        h = sp.zeros(3, 1)
    F = sp.zeros(9, 9)
    F[0, 6] = 1
    F[0, 7] = sp.sin(phi) * sp.tan(theta)
    F[0, 8] = sp.cos(phi) * sp.tan(theta)
    F[1, 7] = sp.cos(phi)
    F[1, 8] = -sp.sin(phi)
    F[2, 7] = sp.sin(phi) / sp.cos(theta)
    F[2, 8] = sp.cos(phi) / sp.cos(theta)
    F[3, 0] = F[4, 1] = F[5, 2] = 1
    F[6:9, 6:9] = I.inv() * (-_skew(w) * I + _skew(h))
    return F
