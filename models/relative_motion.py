"""Relative motion near a passive spacecraft on a circular orbit (seed 4, ../shared/seeds/seed_004.md).

* ``hcw``: dimensional linearised (Hill-Clohessy-Wiltshire) model in the orbital
  cylindrical frame, state (dr, dL, dVr, dVu), thrust accelerations (aS, aT), orbital rate
  ``omega`` (digest §2.3); option ``lateral: true`` adds (dz, dVz) and aW.
* ``relative_motion_secular``: dimensionless secular/periodic model (15) in
  (r_av, L_av, l_x, l_y) with time tau = omega t, lengths / K, K = 2a/omega**2 and the
  transversal switch ``delta`` = aT/a (digest §2.6).

The map between the two is in :mod:`ocdsl.symbolic.relative_motion`
(``to_dimensionless``/``from_dimensionless``).
"""
import sympy as sp

from ocdsl.symbolic.model import Model, sym, syms
from ocdsl.symbolic.registry import register


def _flag(options, key, default=False) -> bool:
    v = options.get(key, default)
    if isinstance(v, str):
        if v.lower() not in ("true", "false"):
            raise ValueError(f"model option {key!r} must be true or false, got {v!r}")
        return v.lower() == "true"
    return bool(v)


@register("hcw", description="Hill-Clohessy-Wiltshire relative motion, orbital cylindrical frame "
                             "(dr, dL = r1*du, dVr, dVu), thrust accelerations aS, aT",
          options={"lateral": "false | true: add the lateral block (dz, dVz) and aW"})
def hcw(options) -> Model:
    dr, dL, dVr, dVu = syms("dr dL dVr dVu")
    aS, aT = syms("aS aT")
    omega = sym("omega")
    dyn = {dr: dVr,
           dL: dVu - omega * dr,
           dVr: omega**2 * dr + 2 * omega * dVu + aS,
           dVu: -omega * dVr + aT}
    states, controls = [dr, dL, dVr, dVu], [aS, aT]
    units = {"dr": "m", "dL": "m", "dVr": "m/s", "dVu": "m/s", "aS": "m/s^2", "aT": "m/s^2",
             "omega": "rad/s"}
    if _flag(options, "lateral"):
        dz, dVz, aW = syms("dz dVz aW")
        dyn[dz] = dVz
        dyn[dVz] = -omega**2 * dz + aW
        states += [dz, dVz]
        controls.append(aW)
        units.update({"dz": "m", "dVz": "m/s", "aW": "m/s^2"})
    return Model("hcw", tuple(states), tuple(controls), dyn,
                 parameters={omega: 7.292116e-5},  # GEO rate (digest §3), override per problem
                 units=units,
                 description="linearised relative motion about a circular orbit (HCW)",
                 positions=("dL", "dr"))


@register("relative_motion_secular",
          description="dimensionless secular/periodic relative motion, transversal thrust switch delta: "
                      "r_av' = delta, L_av' = -3/2 r_av, l_x' = -l_y - delta, l_y' = l_x",
          options={"radial": "false | true: add a radial thrust switch delta_s = aS/a"})
def relative_motion_secular(options) -> Model:
    r_av, L_av, l_x, l_y = syms("r_av L_av l_x l_y")
    delta = sym("delta")
    dyn = {r_av: delta, L_av: -sp.Rational(3, 2) * r_av, l_x: -l_y - delta, l_y: l_x}
    controls = [delta]
    if _flag(options, "radial"):
        ds = sym("delta_s")
        dyn[L_av] = dyn[L_av] - ds
        dyn[l_y] = l_x - ds / 2
        controls.append(ds)
    units = {n: "K" for n in ("r_av", "L_av", "l_x", "l_y")}
    units.update({"delta": "1", "delta_s": "1", "t": "1/omega"})
    return Model("relative_motion_secular", (r_av, L_av, l_x, l_y), tuple(controls), dyn,
                 units=units,
                 description="secular (r_av, L_av) and periodic (l_x, l_y) variables, "
                             "tau = omega t, lengths in K = 2a/omega^2",
                 positions=("L_av", "r_av"))
