"""The objective's own size at a solution: what "J changed by the tolerance" is measured against.

The checks that can refute an `optimal` (the certificate's flown control and end arcs, the
bisection of a fixed mesh, a switch pinned on a breakpoint) counted a change of J against
``tolerance x (1 + |J|)``: for J of order 1 or more that is relative, for a small J it is
absolute, and a J of 3e-3 (a slew in N m, a cost in other units) was "optimal, verified"
8e-4 from its optimum (unseen29). The size is now ``|J| + min(1, S)``, S the sum of the
objective's terms at the solution (``objective_scale``): unchanged where S >= 1, relative to
J's own terms below. A J that is 0 at the optimum keeps the size of its terms (a tracking
cost (x - r)^2 expands to x^2 - 2 r x + r^2, a state's end value its range), not 0.

A constant added to J (``Problem.objective_constant``) moves neither the optimum nor any mesh's
error, so J's own size is ``min(|J|, |J - C|)`` (``own_size``): a J of 1e8 + 0.07 is measured
against 0.07, and a J whose written terms cancel a constant (an expanded tracking cost) against
|J| as before, never against more.
"""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from ..symbolic.model import TIME
from ..symbolic.numbers import substitute_numbers
from ..symbolic.numeric import family
from .checks import evaluate, sensitivity_scale

EXPAND_LIMIT = 200       # operations above which an expression's terms are its top-level ones


def additive_terms(expr: sp.Expr) -> tuple:
    """The additive terms of ``expr``, expanded while it is small."""
    if sp.count_ops(expr) <= EXPAND_LIMIT:
        expr = sp.expand(expr)
    return sp.Add.make_args(expr)


def _trapezoid(t: np.ndarray, v: np.ndarray) -> float:
    ok = np.isfinite(t) & np.isfinite(v)
    return float(np.trapezoid(v[ok], t[ok])) if ok.sum() >= 2 else math.nan


def own_size(objective: float, constant: float = 0.0) -> float:
    """``min(|J|, |J - C|)``: J's size without its constant part, never more than |J|."""
    return min(abs(float(objective)), abs(float(objective) - constant))


def _integrals(ph, traj, params: dict) -> dict:
    """Per integral of the phase: (its value, the integral of its integrand's terms' absolute
    values), both by the trapezoid rule over the rows that hold controls."""
    subs = {k: sp.Float(v) for k, v in ph.constants.items()}
    free = [s for s in sorted({x for L in ph.integrals.values() for x in ph.substitute(L).free_symbols},
                              key=lambda s: s.name)
            if s not in set(ph.states) | set(ph.controls) | {TIME} and s not in subs]
    args = [TIME, *ph.states, *ph.controls, *free]
    exprs = []
    for L in ph.integrals.values():
        e = substitute_numbers(ph.substitute(L), subs)
        exprs += [e, sp.Add(*(sp.Abs(term) for term in additive_terms(e)))]
    fns = family(args, ("objective_size", exprs), lambda: {"v": (exprs, "numpy")})
    t = np.asarray(traj.time, float)
    cols = [t] + [np.asarray(traj.states[s.name], float) for s in ph.states] \
        + [np.asarray(traj.controls[c.name], float) for c in ph.controls] \
        + [np.full(len(t), float(params.get(s.name, math.nan))) for s in free]
    with np.errstate(all="ignore"):
        values = [np.broadcast_to(np.asarray(v, float), t.shape) for v in fns["v"](*cols)]
    return {s: (_trapezoid(t, values[2 * i]), _trapezoid(t, values[2 * i + 1]))
            for i, s in enumerate(ph.integrals)}


def objective_scale(problem, result) -> float:
    """S: the sum of the absolute values of the objective's terms at the solution, an
    integral's terms integrated over its phase (weighted by |dJ/dI|), a term in states' boundary
    values at least what it moves when they move by their ranges; NaN where it cannot be
    evaluated."""
    params = {k: float(v) for k, v in (result.parameters or {}).items()}
    point: dict = {sp.Symbol(k, real=True): v for k, v in params.items()}
    integral_terms: dict = {}
    try:
        trajectories = {ph.name: result.phase(ph.name) if len(result.phases) > 1 else result.phases[0]
                        for ph in problem.phases}
        for ph in problem.phases:
            traj = trajectories[ph.name]
            t = np.asarray(traj.time, float)
            point[ph.t0_symbol], point[ph.tf_symbol] = float(t[0]), float(t[-1])
            for s, (value, terms) in (_integrals(ph, traj, params) if ph.integrals else {}).items():
                point[s], integral_terms[s] = value, terms
        state_ranges: dict = {}
        for s, bv in problem.boundary_values.items():
            ph, traj = problem.phase(bv.phase), trajectories[bv.phase]
            column = np.asarray((traj.states if bv.var in ph.states else traj.controls)[bv.var.name], float)
            finite = column[np.isfinite(column)]
            point[s] = float(finite[0] if bv.which == "t0" else finite[-1]) if len(finite) else math.nan
            if bv.var in ph.states and len(finite):
                state_ranges[s] = float(np.ptp(finite))
        J = sp.sympify(problem.objective.expr)
        total = 0.0
        for term in additive_terms(J):
            if term.free_symbols & set(integral_terms):
                continue
            # a term in a state's end value is at least what it moves when the state moves by
            # its range: the end value is the start plus the rate's integral, and those are J's
            # terms as much as an integrand's are (Aly and Chan's x3(t_f), an integral written
            # as a state, is 0 at the optimum while x3 spans 0.25; against |x3(t_f)| alone every
            # mesh's J of 1e-10 "moved" by its whole size: unseen41 F1)
            total += max(abs(evaluate(term, point)), sensitivity_scale(term, point, state_ranges))
        for s, terms in integral_terms.items():
            total += abs(evaluate(sp.diff(J, s), point)) * terms
        return float(total)
    except Exception:  # noqa: BLE001  (a scale it cannot make leaves the checks as they were)
        return math.nan


def objective_size(objective: float | None, scale: float | None, constant: float = 0.0) -> float:
    """``own_size + min(1, S)``: 1 + |J| where the objective's terms are of order 1 or more (or
    S is unknown), J's own size below; ``constant``: J's constant part."""
    s = 1.0 if scale is None or not math.isfinite(scale) else min(1.0, max(float(scale), 1e-12))
    return own_size(objective or 0.0, constant) + s


# J's relative changes are measured against |J|, but not below this share of its terms' size:
# Ipopt's tolerance (1e-8) is this share of the verification's (1e-5), so a J that is a smaller
# share of its terms (0 at the optimum, Aly and Chan's 1e-10 of terms of 0.25) is zero to the
# NLP, and a change of it relative to itself is noise
RESOLVED_SHARE = 1e-3


def resolved_size(objective: float | None, scale: float | None, constant: float = 0.0) -> float:
    """``max(own_size, RESOLVED_SHARE x min(1, S))``: J's own size while the NLP resolves it."""
    s = 1.0 if scale is None or not math.isfinite(scale) else min(1.0, max(float(scale), 0.0))
    return max(own_size(objective or 0.0, constant), RESOLVED_SHARE * s, 1e-300)
