"""6DOF rendezvous of a rigid chaser near a target in a circular orbit (seed 0).

Mousavi, Esmailifar, Chiniforoushan, JSSTA 2022 (digest: ../shared/seeds/seed_000.md).

Frames: L is the target's LVLH frame (x along-track, z toward the Earth's centre, y
completing the triad, i.e. minus the orbit normal); B is the chaser's principal-axis body
frame. States, in this order:

* ``omega1 omega2 omega3``: angular velocity w of B relative to L, in B components (rad/s);
* ``sigma1 sigma2 sigma3``: MRPs of B relative to L;
* ``vx vy vz``: velocity of the chaser relative to L, in L components (m/s);
* ``x y z``: position of the chaser relative to the target, in L components (m).

Controls: body-axis torques ``T1 T2 T3`` (N m) and body-axis forces ``F1 F2 F3`` (N).

Equations (digest section 2):

* MRP kinematics: sigma' = B(sigma) w / 4;
* C = C(sigma) = [BL] (L -> B), orbit rate in B (named expressions ``omega_o1..3``):
  w_o = C [0, -wn, 0]^T (the sign matters: y_L is minus the orbit normal);
* Euler equation, option ``euler``:
  - ``printed`` (default, the paper's eq. 13): I w' = T - w x (I w) - w_o x (I (w + w_o));
  - ``exact`` (rigid body, derived): I w' = T - w_BI x (I w_BI) + I (w x w_o), w_BI = w + w_o;
* Hill / Clohessy-Wiltshire translation with the body thrust rotated into L, F_L = C^T F
  (named expressions ``F_L1..3``):
  vx' = 2 wn vz + F_L1/m, vy' = -wn^2 y + F_L2/m, vz' = -2 wn vx + 3 wn^2 z + F_L3/m,
  (x, y, z)' = (vx, vy, vz);
* orbit rate wn = ``omega_n`` = sqrt(mu / (R_E + h)^3), with h, R_E in km and mu in km^3/s^2.

A 90 deg rotation about body axis 2 is the MRP [0, tan(pi/8), 0] (not tan(pi/4)).
"""
from __future__ import annotations

import sympy as sp

from ocdsl.symbolic.model import Model, sym, syms
from ocdsl.symbolic.registry import register
from ocdsl.symbolic.vectors import cross, mrp_kinematics_matrix, mrp_to_dcm

EULER_FORMS = ("printed", "exact")

# Table 2 of the paper; mu and R_E as in the digest (their choice is immaterial at 4 decimals)
DEFAULTS = {"I1": 5621.0, "I2": 4547.0, "I3": 2364.0, "m": 3200.0,
            "h": 580.0, "mu": 398600.4418, "R_E": 6378.137}


@register("rendezvous_6dof",
          description="rigid chaser near a circular-orbit target: relative Euler equation, MRP "
                      "attitude, Clohessy-Wiltshire translation with body-axis thrust",
          options={"euler": "printed | exact: the paper's eq. (13) (default) or the exact "
                            "rigid-body relative Euler equation"})
def build(options: dict) -> Model:
    euler = str(options.get("euler", "printed"))
    if euler not in EULER_FORMS:
        raise ValueError(f"rendezvous_6dof: option euler must be one of {EULER_FORMS}, got {euler!r}")

    w = sp.Matrix(syms("omega1 omega2 omega3"))
    sig = sp.Matrix(syms("sigma1 sigma2 sigma3"))
    v = sp.Matrix(syms("vx vy vz"))
    r = sp.Matrix(syms("x y z"))
    T = sp.Matrix(syms("T1 T2 T3"))
    F = sp.Matrix(syms("F1 F2 F3"))
    I1, I2, I3, m, h, mu, R_E = syms("I1 I2 I3 m h mu R_E")
    wn = sym("omega_n")
    wo = sp.Matrix(syms("omega_o1 omega_o2 omega_o3"))  # orbit rate [w_LI]^B
    FL = sp.Matrix(syms("F_L1 F_L2 F_L3"))     # thrust in L components

    C = mrp_to_dcm(sig)                     # [BL]
    Ib = sp.diag(I1, I2, I3)
    expressions = {wn: sp.sqrt(mu / (R_E + h) ** 3)}
    expressions.update(dict(zip(wo, C * sp.Matrix([0, -wn, 0]))))
    expressions.update(dict(zip(FL, C.T * F)))

    if euler == "printed":
        torque = T - cross(w, Ib * w) - cross(wo, Ib * (w + wo))
    else:
        wbi = w + wo
        torque = T - cross(wbi, Ib * wbi) + Ib * cross(w, wo)
    wdot = sp.Matrix([torque[i] / Ib[i, i] for i in range(3)])
    sigdot = mrp_kinematics_matrix(sig) * w / 4
    vdot = sp.Matrix([2 * wn * v[2] + FL[0] / m,
                      -wn**2 * r[1] + FL[1] / m,
                      -2 * wn * v[0] + 3 * wn**2 * r[2] + FL[2] / m])

    states = (*w, *sig, *v, *r)
    dynamics = dict(zip(states, (*wdot, *sigdot, *vdot, *v)))
    parameters = {s: DEFAULTS[s.name] for s in (I1, I2, I3, m, h, mu, R_E)}
    units = {**{f"omega{i}": "rad/s" for i in (1, 2, 3)}, **{f"sigma{i}": "1" for i in (1, 2, 3)},
             "vx": "m/s", "vy": "m/s", "vz": "m/s", "x": "m", "y": "m", "z": "m",
             **{f"T{i}": "N*m" for i in (1, 2, 3)}, **{f"F{i}": "N" for i in (1, 2, 3)},
             "I1": "kg*m^2", "I2": "kg*m^2", "I3": "kg*m^2", "m": "kg", "h": "km",
             "mu": "km^3/s^2", "R_E": "km", "omega_n": "rad/s",
             **{f"omega_o{i}": "rad/s" for i in (1, 2, 3)}, **{f"F_L{i}": "N" for i in (1, 2, 3)}}
    return Model(
        name="rendezvous_6dof",
        states=states,
        controls=(*T, *F),
        dynamics=dynamics,
        parameters=parameters,
        expressions=expressions,
        units=units,
        description=f"6DOF rendezvous, MRP attitude relative to LVLH, CW translation, "
                    f"Euler equation {euler}",
        positions=("x", "y", "z"),
    )
