"""Sundman regularisation of a model: dt = c * R^k ds, with a clock state for t."""
from __future__ import annotations

import sympy as sp

from ocdsl.symbolic.model import Model, sym


def sundman(model: Model, distance: sp.Expr, k: float, c: float = 1.0,
            clock: str = "time") -> Model:
    """The model in the Sundman variable s: d()/ds = c R^k d()/dt, plus a clock state.

    ``distance`` is R written with the model's symbols (states or named expressions).
    The result's independent variable (``TIME`` in the expressions) is s; physical time
    is the new state ``clock`` (d clock/ds = c R^k). Perigee passages, which dominate
    the step count of an adaptive integrator in t, get steps that scale with R^k.
    """
    if clock in {s.name for s in model.states}:
        raise ValueError(f"model {model.name!r} already has a state {clock!r}")
    tau = sym(clock)
    rate_sym = sym("sundman_rate")
    kk = sp.Integer(int(k)) if float(k) == int(k) else sp.Float(k)
    rate = sp.Float(c) * distance ** kk
    dyn = {s: rate_sym * f for s, f in model.dynamics.items()}
    dyn[tau] = rate_sym
    # later named expressions may use earlier ones: the rate goes last, so the
    # distance may be one of the model's named expressions (e.g. R_SE).
    exprs = {**dict(model.expressions), rate_sym: rate}
    units = dict(model.units)
    units[clock] = units.get("t", "")
    return Model(f"{model.name}_sundman", tuple(model.states) + (tau,), model.controls, dyn,
                 dict(model.parameters), exprs, units,
                 (model.description + f" [Sundman: dt = {c} R^{k} ds, clock state {clock!r}]").strip(),
                 model.positions, time_state=clock, frame=model.frame)
