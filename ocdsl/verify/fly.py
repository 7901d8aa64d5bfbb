"""Fly another control from a solution's start: the objective and the constraints of the
trajectory it gives, measured as the verification measures the solution's own.

The certificate uses it to put a claimed optimum to the test with a control built from the
solution's costates (ocdsl/solve/certificate/flown_control.py): any feasible trajectory's objective bounds
the optimum, so one that does better than the claim by more than the tolerance refutes it.
"""
from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, field

import numpy as np

from . import _numbers, _PhaseRun, _points
from .checks import evaluate, path_scales, path_violations, relative_violation, sensitivity_scale, state_scale
from .functions import PhaseFunctions, controls_at
from .integrate import _stiff, integrate_pass
from .interpolate import bounds_of


class _Linear:
    """A control tabulated at increasing times, linear in between, held outside: the
    interface of the verification's interpolants (``at``, ``piece``, ``kinks``), with the
    one-time evaluation in plain Python (an integrator asks for it ~10^4 times)."""

    state_dependent = False

    def __init__(self, t, U):
        self.t, self.U = np.asarray(t, float), np.asarray(U, float)
        self._t, self._U = self.t.tolist(), self.U.tolist()

    def at(self, tt, X=None) -> np.ndarray:
        tt = np.asarray(tt, float)
        return np.column_stack([np.interp(tt, self.t, self.U[:, j]) for j in range(self.U.shape[1])]) \
            if self.U.shape[1] else np.zeros((len(tt), 0))

    def kinks(self, a: float, b: float) -> list[float]:
        return []       # the table's entries are kinks, but small ones; its jumps are the caller's cuts

    def piece(self, tt: float):
        ts, us, last = self._t, self._U, len(self._t) - 1

        def at(s: float) -> list[float]:
            k = bisect_right(ts, s) - 1
            if k < 0:
                return us[0]
            if k >= last:
                return us[last]
            w = (s - ts[k]) / (ts[k + 1] - ts[k])
            return [a + w * (b - a) for a, b in zip(us[k], us[k + 1])]

        return at


@dataclass(frozen=True)
class Flight:
    """What a control flown from the solution's x(t0) achieves."""

    objective: float            # the problem's objective (its own sense)
    violation: float            # the largest relative violation of a boundary condition, state bound or path constraint
    where: str                  # which one
    steps: int
    # per equality boundary condition (its index in problem.boundary): value minus target over
    # its sensitivity scale, signed (what a correction of the control must drive to zero)
    residuals: dict = field(default_factory=dict)


def flight_functions(problem, result) -> PhaseFunctions:
    """The single phase's compiled dynamics and integrands for ``fly_control``: built once by a
    caller that flies many controls (a corrected flight flies up to 40; building them each time
    was 0.9 s of seed 0's 2.3 s)."""
    (ph,) = problem.phases
    return PhaseFunctions(ph, _numbers(result.parameters), ph.integrals)


def fly_control(problem, result, t_table: np.ndarray, U_table: np.ndarray, cuts: np.ndarray,
                rtol: float = 1e-9, stretch: float = 1.0, funcs: PhaseFunctions | None = None) -> Flight:
    """Integrate the single phase of ``problem`` from the result's first row with the control
    tabulated at ``t_table`` (linear between entries, restarted at ``cuts``, where it jumps);
    the result's parameters are kept, and its final time unless ``stretch`` (a free final time
    moved: the phase and the table stretched by that factor about t0). Violations are relative as in the
    verification (boundary conditions by their sensitivity scale, state bounds by the state's
    range)."""
    (ph,) = problem.phases
    traj = result.phases[0]
    params = _numbers(result.parameters)
    names_x = [s.name for s in ph.states]
    t_rows = np.asarray(traj.time, float)
    X_rows = np.column_stack([np.asarray(traj.states[n], float) for n in names_x])
    keep = np.isfinite(t_rows) & np.isfinite(X_rows).all(axis=1)
    t_rows, X_rows = t_rows[keep], X_rows[keep]
    if stretch != 1.0:
        # a free final time moved: the phase (rows, table and cuts) stretched about t0
        t0 = t_rows[0]
        t_rows, t_table = t0 + stretch * (t_rows - t0), t0 + stretch * (np.asarray(t_table, float) - t0)
        cuts = t0 + stretch * (np.asarray(cuts, float) - t0)
    if funcs is None:
        funcs = flight_functions(problem, result)
    uf = _Linear(t_table, U_table)
    breaks = np.unique(np.concatenate([[t_rows[0], t_rows[-1]], np.asarray(cuts, float)]))
    breaks = breaks[(breaks >= t_rows[0]) & (breaks <= t_rows[-1])]
    grid = np.unique(np.concatenate([breaks, np.clip(t_table, t_rows[0], t_rows[-1])]))
    scale_x = state_scale(X_rows)
    nq = len(funcs.integral_symbols)
    start = np.concatenate([X_rows[0], np.zeros(nq)])
    scale_q = np.ones(nq)
    if nq:
        Q = np.abs(funcs.q(t_rows, X_rows, controls_at(uf, t_rows, X_rows)))
        scale_q = np.maximum(np.trapezoid(Q, t_rows, axis=0), 1e-12)
    scale = np.concatenate([scale_x, scale_q])
    rho = _stiff(funcs, uf, t_rows, X_rows, scale)
    flown = integrate_pass(funcs, uf, grid, breaks, lambda k, y_prev: start if k == 0 else y_prev,
                           rtol, scale, rho)
    end = flown.Y[-1]
    run = _PhaseRun(t_rows, X_rows, scale_x, scale_q, end, end, uf)
    point, scales = _points(problem, result, {ph.name: run}, params, "global")
    worst, where, residuals = 0.0, "", {}
    for i, c in enumerate(problem.boundary):
        value, sensitivity = evaluate(c.expr, point), sensitivity_scale(c.expr, point, scales)
        v = float(relative_violation(np.array([value]), c.lower, c.upper, 1.0)[0]) / sensitivity
        if c.is_equality:
            residuals[i] = (value - c.lower) / sensitivity
        if not v <= worst:
            worst, where = (v if math.isfinite(v) else math.inf), c.text or str(c.expr)
    lo_tf, hi_tf = ph.tf_bounds
    v = float(relative_violation(np.array([t_rows[-1]]), lo_tf, hi_tf, max(t_rows[-1] - t_rows[0], 1e-12))[0])
    if not v <= worst:
        worst, where = (v if math.isfinite(v) else math.inf), "bounds of the final time"
    for j, (lo, hi) in enumerate(bounds_of(ph, names_x, "states")):
        if math.isfinite(lo) or math.isfinite(hi):
            v = float(np.max(relative_violation(flown.Y[:, j], lo, hi, scale_x[j])))
            if not v <= worst:
                worst, where = (v if math.isfinite(v) else math.inf), f"bound of {names_x[j]}"
    if funcs.g is not None:
        # path constraints along the flight, scaled as the verification scales them
        X_fl = flown.Y[:, :len(names_x)]
        G = funcs.g(flown.t, X_fl, controls_at(uf, flown.t, X_fl))
        U_rows = controls_at(uf, t_rows, X_rows)
        ubounds = bounds_of(ph, [c.name for c in ph.controls], "controls")
        gscale = path_scales(funcs, t_rows, X_rows, U_rows, scale_x, ubounds, funcs.g(t_rows, X_rows, U_rows))
        err = path_violations(funcs, flown.t, X_fl, controls_at(uf, flown.t, X_fl), G, scale_x, ubounds, gscale)
        for k, c in enumerate(funcs.path):
            v = float(np.max(err[:, k]))
            if not v <= worst:
                worst, where = (v if math.isfinite(v) else math.inf), c.text or str(c.expr)
    return Flight(evaluate(problem.objective.expr, point), worst, where, flown.steps, residuals)
