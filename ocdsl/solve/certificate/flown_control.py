"""The control the minimum principle gives, flown (certificate check ``flown_control``).

The node checks and the verification can all pass on a solution whose control polynomials
cannot follow the optimum between the nodes: an LQ control that enters its bound inside an LGR
segment leaves every node stationary and the trajectory consistent, with J 9e-5 off (unseen14
F2). At every time the solution's own states and costates say which admissible control
minimises H; flown from x(t0), that control gives a trajectory whose objective, when it is
feasible, bounds the optimum. Better than the claim by more than the tolerance, it refutes the
claim; worse or infeasible, it proves nothing (costates off near a singular arc, a condition
missed), so the check then passes, unless the first-order prediction promised a gain above
the tolerance and the feasible flight lost more than it: then inconclusive (``_doubted``).
Conditions on the final state or an integral are met first by correcting the control
(corrected_flight.py). Applies to one phase with box-bounded controls
that enter H at most quadratically and no path constraint that binds (``_path_binds``).
"""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import sympy as sp

from ...result import Result
from ...symbolic.numbers import substitute_numbers
from ...symbolic.problem import Problem
from ...verify.objective_size import objective_size
from .. import pchip
from .conditions import _param_subs
from .corrected_flight import MAX_CONDITIONS, bang_jumps, corrected_flight, late_equalities, late_symbols
from .nodes import _hamiltonian_nodes, _Numeric

# points between consecutive rows at which the minimising control is tabulated (linear in
# between): the control's own interpolation error then costs J far below the tolerance
PER_INTERVAL = 7
# a flown trajectory is feasible when it misses no boundary condition or state bound by more
# than this share of the verification tolerance: missing a condition by d can gain about
# nu d in J, which must stay well below what the check calls a gain
FEASIBLE_SHARE = 1e-3
# the control is flown only when H's minimiser predicts a gain of at least this share of the
# limit (the prediction is first order; for a convex problem it bounds the real gain above)
PREDICTED_SHARE = 0.1
# ... and with final conditions, where every flight is a Newton iteration of several at rtol
# 1e-11, at least the limit itself: the corrected flight gains alpha x the prediction to first
# order, so less cannot refute (post stage before: seed 0 1.6 s, Goddard 0.5 s, for nothing)
PREDICTED_SHARE_CORRECTED = 1.0
# a path constraint this far (relative) from its bounds at every row counts as inactive
PATH_AWAY = 1e-3
# the flight integrates at rtol 1e-9: a gain below this share of 1 + |J| may be its own error
FLIGHT_RESOLUTION = 1e-7
# integrator steps all of one check's flights may take: a corrected control can fly the model out
# of its domain (the moon lander's mass towards zero), where a stiff integrator at rtol 1e-11
# went on for minutes (unseen18: mesh_moon_landing did not end); a flight past it counts as
# failed. Counted in steps, not seconds, so that a loaded machine cuts the same flights as a
# quiet one (a wall-clock budget cut a fixed mesh's flights under load: its check said "not
# compared", the bisection was skipped, `optimal` with J 3e-4 off)
FLIGHT_STEPS_MIN = 6_000       # about 0.7 s of flights here
FLIGHT_STEPS_MAX = 80_000      # about 10 s (Goddard's corrected flights took 10 s after a 0.08 s solve)
FLIGHT_SHARE_STEPS = 1_600     # ... and each flight after the first at most 20 times the first, or this
# the wall clock only as a guard against a flight that hangs inside one step: what it cuts
# judges nothing (``inconclusive``), as it depends on the machine's load
FLIGHT_WALL_S = 60.0


def flight_budget(iterations: int | None, variables: int | None) -> int:
    """The flights' step budget for a run whose last solve took ``iterations`` Ipopt iterations
    on ``variables`` NLP variables: about twice that solve's time in flights (an iteration costs
    about 0.6 ms + 2.5 us per variable here, a step 0.12 ms), at least FLIGHT_STEPS_MIN, at
    most FLIGHT_STEPS_MAX; a deterministic stand-in for the solve's seconds."""
    work = int(iterations or 0) * (10.0 + 0.05 * int(variables or 0))
    return int(min(FLIGHT_STEPS_MAX, max(FLIGHT_STEPS_MIN, work)))


def _quadratic_in_controls(model, params, lagrange) -> bool:
    """Whether f and L are polynomials of degree at most 2 in the controls (H's minimiser over
    a box is then found exactly, coordinate by coordinate)."""
    subs = _param_subs(model, params)
    controls = set(model.controls)
    exprs = list(substitute_numbers(model.rhs(), subs)) + [substitute_numbers(model.expand(sp.sympify(lagrange)), subs)]
    for e in exprs:
        for u in model.controls:
            d = sp.diff(e, u)
            if d.free_symbols & controls and any(sp.diff(d, v).free_symbols & controls for v in model.controls):
                return False
    return True


def _gradient(G0, R, U, U0):
    """dH/du at controls ``U`` from its value ``G0`` at ``U0`` and H's (constant) Hessian ``R``."""
    return G0 + np.einsum("pjk,pk->pj", R, U - U0)


def _minimising_controls(num: _Numeric, t, X, Lam, bounds):
    """argmin over the box of H(t, x, lambda, u) at every point, with dH/du there; None when H
    has no minimiser on it (unbounded control, H not convex in it). H is quadratic in u: its
    gradient at a base point and its (constant) Hessian, by one unit step per control, give
    it exactly; coordinate descent then finds the box minimiser."""
    m = len(bounds)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    U0 = np.clip(np.zeros((len(t), m)), lo, hi)
    _, G0, _, _ = _hamiltonian_nodes(num, t, X, U0, Lam)
    R = np.empty((len(t), m, m))
    for j in range(m):
        U1 = U0.copy()
        U1[:, j] += 1.0
        R[:, :, j] = _hamiltonian_nodes(num, t, X, U1, Lam)[1] - G0
    U = U0.copy()
    for _ in range(1 if m == 1 else 10 * m):
        for j in range(m):
            G = _gradient(G0, R, U, U0)
            g, r, u = G[:, j], R[:, j, j], U[:, j]
            with np.errstate(divide="ignore", invalid="ignore"):
                newton = u - g / r
                d_lo, d_hi = lo[j] - u, hi[j] - u
                # not convex in u_j: the better bound (a linear H: the sign of dH/du)
                h_lo, h_hi = g * d_lo + 0.5 * r * d_lo**2, g * d_hi + 0.5 * r * d_hi**2
                ends = np.where(h_lo < h_hi, lo[j], np.where(h_hi < h_lo, hi[j], u))
            U[:, j] = np.clip(np.where(r > 1e-12 * (np.abs(g) + 1.0), newton, ends), lo[j], hi[j])
    if not np.all(np.isfinite(U)):
        return None
    return U, _gradient(G0, R, U, U0), _corners(t, U, G0, R, U0, lo, hi)


def _corners(t, U, G0, R, U0, lo, hi) -> list[tuple[float, int, float]]:
    """(time, control, bound) where a control reaches or leaves a bound between grid points: the zero of dH/du
    evaluated at that bound (it pushes against the bound on the arc that holds it and pulls
    away on the interior arc), linear between the two points."""
    out = []
    for j in range(U.shape[1]):
        for bound in (lo[j], hi[j]):
            if not math.isfinite(bound):
                continue
            on = np.isclose(U[:, j], bound, rtol=0, atol=1e-12 * max(1.0, abs(bound)))
            # a jump from one bound to the other is a switch (``_tabulate``), not a corner
            for i in np.flatnonzero((on[1:] != on[:-1]) & ~bang_jumps(U, j, lo[j], hi[j])):
                Ub = U[i:i + 2].copy()
                Ub[:, j] = bound
                g = _gradient(G0[i:i + 2], R[i:i + 2], Ub, U0[i:i + 2])[:, j]
                w = g[0] / (g[0] - g[1]) if g[0] != g[1] and g[0] * g[1] <= 0 else 0.5
                if 0 < i < len(t) - 2:      # a bound held up to an end is no corner
                    out.append((float(t[i] + w * (t[i + 1] - t[i])), j, float(bound)))
    return sorted(out)


def _tabulate(t, U, G, bounds, corners):
    """The minimising control as a table for linear interpolation, with each jump from one
    bound to the other (a bang switch) placed where the switching function's linear
    interpolant vanishes, as two entries a hair apart, and an entry on the bound at each corner;
    and the jumps' times (cuts)."""
    apart = 1e-8 * (t[-1] - t[0])
    corners = [c for c in corners if np.min(np.abs(t - c[0])) > apart]     # not on a grid point
    if corners:
        at = np.array([c for c, _, _ in corners])
        extra_U = np.column_stack([np.interp(at, t, U[:, j]) for j in range(U.shape[1])])
        extra_G = np.column_stack([np.interp(at, t, G[:, j]) for j in range(G.shape[1])])
        for k, (_, j, bound) in enumerate(corners):
            extra_U[k, j] = bound
        order = np.argsort(np.concatenate([t, at]), kind="stable")
        t, U, G = np.concatenate([t, at])[order], np.vstack([U, extra_U])[order], np.vstack([G, extra_G])[order]
    jumps = []
    for j, (lo, hi) in enumerate(bounds):
        if not (math.isfinite(lo) and math.isfinite(hi)):
            continue
        for i in np.flatnonzero(bang_jumps(U, j, lo, hi)):
            g0, g1 = G[i, j], G[i + 1, j]
            w = g0 / (g0 - g1) if g0 != g1 and g0 * g1 < 0 else 0.5
            jumps.append((i, j, float(t[i] + w * (t[i + 1] - t[i]))))
    if not jumps:
        return t, U, np.zeros(0)
    eps = 1e-9 * (t[-1] - t[0])
    times, rows = list(t), list(U)
    for i, j, s in jumps:
        s = min(max(s, t[i] + eps), t[i + 1] - 2 * eps)
        w = (s - t[i]) / (t[i + 1] - t[i])
        for when, side in ((s, i), (s + eps, i + 1)):
            row = U[i] + w * (U[i + 1] - U[i])
            row[j] = U[side, j]
            times.append(when)
            rows.append(row)
    order = np.argsort(times, kind="stable")
    return np.asarray(times)[order], np.asarray(rows)[order], np.array(sorted(s for *_, s in jumps))


def _doubted(out: dict, predicted: float, limit: float, flight: str) -> dict:
    """Mark ``out`` inconclusive where H's minimiser predicts, to first order, a gain above
    the tolerance while its feasible flight comes out worse than the claim by more than the
    tolerance: prediction and flight contradict each other, so the check has not judged J (a
    fixed mesh is then bisected, a refinement refined again with that control's corners kept:
    run.py, mesh/flown.py). Before, it passed: x' = u with a corner inside an LGR segment,
    predicted gain 59 times the tolerance, the corrected flight 1.6e-4 worse: `optimal`,
    verified, certificate pass, J 3.0e-4 off (unseen23 FC2, FC3). A flight that reproduces
    the claim (a switch between nodes makes the prediction large: the double integrator's
    3.1e-5, its flight within 1e-9) judged it; an infeasible one proves nothing, as before."""
    if predicted > limit:
        out["inconclusive"] = (f"H's minimiser predicts a gain of {predicted:.1e} over the solution's control "
                               f"(the tolerance allows {limit:.1e}), but its flight {flight}: not judged")
    return out


def _path_binds(problem: Problem, result: Result, funcs) -> bool:
    """Whether a path constraint comes within ``PATH_AWAY`` (relative, scaled as the verification
    scales it) of a bound at a row of the solution. One that never does has a zero multiplier,
    so H's minimiser is the same without it, and the flight is checked against it
    (``fly_control``). Before, any path constraint turned the check off: an isoperimetric
    problem with a never-binding x + u <= 100 was `optimal`, verified, certificate pass with J
    3.2e-3 off (unseen23 FC1)."""
    from ...verify.checks import path_scales, relative_violation, state_scale
    from ...verify.interpolate import bounds_of

    (ph,), traj = problem.phases, result.phases[0]
    t = np.asarray(traj.time, float)
    X = np.column_stack([np.asarray(traj.states[s.name], float) for s in ph.states])
    U = np.column_stack([np.asarray(traj.controls[c.name], float) for c in ph.controls])
    rows = np.isfinite(t) & np.isfinite(X).all(axis=1) & np.isfinite(U).all(axis=1)
    if rows.sum() < 2 or funcs.g is None:
        return True
    t, X, U = t[rows], X[rows], U[rows]
    G = funcs.g(t, X, U)
    scale = path_scales(funcs, t, X, U, state_scale(X), bounds_of(ph, [c.name for c in ph.controls], "controls"), G)
    for k, c in enumerate(funcs.path):
        # distance to each finite bound over the scale: the violation of the bound moved inwards
        for lo, hi in ((c.lower + PATH_AWAY * scale[k], np.inf), (-np.inf, c.upper - PATH_AWAY * scale[k])):
            if np.isfinite(lo) or np.isfinite(hi):
                if np.any(relative_violation(G[:, k], lo, hi, scale[k]) > 0) or not np.all(np.isfinite(G[:, k])):
                    return True
    return False


def _state_bound_binds(ph, traj) -> bool:
    """Whether a state reaches its bound (within ``PATH_AWAY`` of its range) at a row: there
    the costates jump and H's minimiser along them can be far off the optimum's control
    (Bryson-Denham, x <= 1/9: predicted 2.8e-3, the flight 3.2e-2 worse, J exact), so a
    worse flight there says nothing about the claim."""
    for x in ph.states:
        lo, hi = ph.bounds_of(x)
        v = np.asarray(traj.states.get(x.name, []), float)
        v = v[np.isfinite(v)]
        if not len(v):
            continue
        margin = PATH_AWAY * max(float(np.ptp(v)), 1e-12)
        if (np.isfinite(lo) and np.any(v <= lo + margin)) or (np.isfinite(hi) and np.any(v >= hi - margin)):
            return True
    return False


def _guarded(out: dict, out_of_time: list) -> dict:
    """``out``, ``inconclusive`` where the wall-clock guard cut a flight (what it cuts depends
    on the machine's load)."""
    if out_of_time:
        out["inconclusive"] = f"its flights ran past the {FLIGHT_WALL_S:g} s guard: not judged"
    return out


def flown_control(problem: Problem, result: Result, lagrange, params: dict, tolerance: float,
                  mesh_tolerance: float | None = None, always_fly: bool = False,
                  budget_steps: int | None = None) -> dict[str, Any] | None:
    """The check's record (``params``: the phase's parameter values, as the certificate's): the
    claimed and the flown objective, the gain, the flown trajectory's worst violation; ``passed``
    False when it is feasible and better than the claim by more than ``tolerance`` x (1 + |J|). None where the check does not apply. With a
    ``mesh_tolerance`` (a ``mesh:`` run, which refines again on a gain above it, mesh/flown.py)
    the control is also flown for predicted gains near that tolerance; ``always_fly``: whatever
    gain it predicts (the flown J then bounds what other meshes' J can be, mesh/flown.py);
    ``budget_steps``: integrator steps for all its flights (default FLIGHT_STEPS_MAX). ``inconclusive``
    (a reason) where it predicts a gain above the tolerance that its flight does not realise
    (``_doubted``); ``judged`` False where no flight judged J (the correction onto the final
    conditions failed, or the flight missed them): the check passes, and a fixed mesh is
    bisected as where nothing was flown."""
    if len(problem.phases) != 1 or result.objective is None or not math.isfinite(float(result.objective)):
        return None
    from ...verify.fly import Flight, flight_functions, fly_control

    ph, traj = problem.phases[0], result.phases[0]
    if not ph.controls or not traj.costates:
        return None
    # the phase's compiled functions: the path constraints' now, the flights' later
    funcs = flight_functions(problem, result) if ph.path else None
    if ph.path and _path_binds(problem, result, funcs):
        return None
    model = ph.model
    if not _quadratic_in_controls(model, params, lagrange):
        return None
    if sp.sympify(lagrange) == 0 and not problem.objective.expr.free_symbols & late_symbols(problem) \
            and ph.tf is not None:
        return None     # J of a fixed t_f and parameters alone: no flight changes it
    t = np.asarray(traj.time, float)
    X = np.column_stack([np.asarray(traj.states[s.name], float) for s in model.states])
    Lam = np.column_stack([np.asarray(traj.costates.get(s.name, np.full(len(t), np.nan)), float)
                           for s in model.states])
    rows = np.isfinite(t) & np.isfinite(X).all(axis=1) & np.isfinite(Lam).all(axis=1)
    if rows.sum() < 2:
        return None
    bounds = [tuple(float(b) for b in ph.control_bounds.get(c, (-math.inf, math.inf))) for c in ph.controls]
    frac = np.arange(PER_INTERVAL + 1) / (PER_INTERVAL + 1)
    t_rows = np.unique(t[np.isfinite(t)])
    tt = np.append((t_rows[:-1, None] + np.diff(t_rows)[:, None] * frac[None, :]).ravel(), t_rows[-1])
    Xi = pchip.interpolate(t[rows], X[rows], tt)
    Li = pchip.interpolate(t[rows], Lam[rows], tt)
    num = _Numeric(model, params, lagrange)
    found = _minimising_controls(num, tt, Xi, Li, bounds)
    if found is None:
        return None
    U_min, G_min, corners = found
    corner_times = [c for c, _, _ in corners]
    claimed = float(result.objective)
    size = objective_size(claimed, result.extra.get("objective_scale"), result.extra.get("objective_constant", 0.0))
    limit = tolerance * size
    # what H's minimiser gains over the solution's own control, to first order (for a convex
    # problem an upper bound of J - J*): far below the limit, the flight cannot refute the claim
    from ...verify.interpolate import control_interpolant, declared_interpolation

    own = control_interpolant(traj, [c.name for c in ph.controls], bounds, declared_interpolation(traj, result.method))
    gap = _hamiltonian_nodes(num, tt, Xi, own.at(tt), Li)[0] - _hamiltonian_nodes(num, tt, Xi, U_min, Li)[0]
    predicted = float(np.sum(0.5 * (gap[1:] + gap[:-1]) * np.diff(tt)))
    late = late_equalities(problem)
    # a mesh run flies for gains near its own tolerance too (to refine again, mesh/flown.py),
    # with final conditions as well: those flights are Newton iterations of several flights at
    # rtol 1e-11 (the hang glider's post stage took 5.5 s against a 0.3 s solve before the
    # flights' budget, ``flight_budget``), but left out, a corner inside a segment of x' = u
    # with x(tf) fixed passed a mesh tolerance of 1e-7 with J 3.1e-6 off (unseen23 FC4:
    # predicted gain 3.8e-6 against the 1e-5 a flight then needed)
    wanted = limit if mesh_tolerance is None else \
        min(limit, max(mesh_tolerance, FLIGHT_RESOLUTION) * size)
    share = PREDICTED_SHARE_CORRECTED if late else PREDICTED_SHARE
    if not always_fly and predicted < share * wanted:
        # judged nothing: the prediction rests on the NLP's own costates, which carry the
        # mesh's error (unseen53 F1: x' = u, min int u^2/2 + t x, LG 3 x 2: predicted 2.1e-7,
        # J 8.6e-6 above J*, lambda(tf) 9.3e-3 for 0), so a fixed mesh is bisected
        return {"claimed": claimed, "predicted_gain": predicted, "limit": limit, "corners": corner_times, "passed": True,
                "judged": False,
                "note": (f"H's minimiser gains {predicted:.1e} over the solution's control to first order "
                         if predicted > 0 else "H's minimiser predicts no gain over the solution's control ")
                        + f"(with the mesh's own costates), below the {share * wanted:.1e} a flight would need: not flown"}
    t_tab, U_tab, cuts = _tabulate(tt, U_min, G_min, bounds, corners)
    from ...verify.integrate import IntegrationFailure, step_budget, time_budget

    # J to 1e-3 of the tolerance is all the comparison needs (the verification's own flight
    # integrates at 1e-10); a correction onto final conditions needs them met to below that
    rtol = min(1e-11 if late else 1e-9, 1e-4 * tolerance)
    steps_left = [FLIGHT_STEPS_MAX if budget_steps is None else int(budget_steps)]
    deadline = time.monotonic() + FLIGHT_WALL_S
    funcs = funcs or flight_functions(problem, result)
    first: list[int] = []        # the first flight's steps: a flight 20 times as long has left the domain
    out_of_time: list[bool] = []

    def fly(t_fly, U, cuts_fly, stretch=1.0):
        allowed = steps_left[0]
        if first:
            allowed = min(allowed, max(FLIGHT_SHARE_STEPS, 20 * first[0]))
        if allowed <= 0:
            return Flight(math.nan, math.inf, "the flights' step budget", 0)
        with step_budget(allowed) as used:
            try:
                with time_budget(deadline - time.monotonic()):
                    flight = fly_control(problem, result, t_fly, U, cuts_fly, stretch=stretch, rtol=rtol,
                                         funcs=funcs)
            except IntegrationFailure as exc:
                if time.monotonic() >= deadline:
                    out_of_time.append(True)
                flight = Flight(math.nan, math.inf, f"the flight ({exc})", 0)
        steps_left[0] -= used.used
        if not first:
            first.append(used.used)
        return flight

    def gain_of(flight) -> float:
        return (claimed - flight.objective) * (1.0 if problem.objective.sense == "minimize" else -1.0)

    corrected = None
    if late:
        # conditions on the final state or an integral: the control is first moved back onto them
        corrected = corrected_flight(
            fly, t_tab, own.at(t_tab), U_tab, cuts, bounds, late, 0.5 * FEASIBLE_SHARE * tolerance,
            lambda f: f.violation <= FEASIBLE_SHARE * tolerance and gain_of(f) > limit, gain_of,
            free_final_time=ph.tf is None)
        if corrected is None:
            texts = "; ".join(problem.boundary[i].text or str(problem.boundary[i].expr) for i in late)
            out = {"claimed": claimed, "predicted_gain": predicted, "limit": limit, "corners": corner_times,
                   "passed": True, "judged": False, "note": f"H's minimiser could not be corrected to meet {texts}"
                                           + (f" (more than {MAX_CONDITIONS} conditions are not tried)"
                                              if len(late) > MAX_CONDITIONS else "") + ": not compared"}
            # in a refinement the second pass with H's minimiser's corners kept is the test
            # (mesh/flown.py): an LGR 2 x 4 area problem, predicted gain 12.6 x the tolerance,
            # the correction failing, was `optimal` 3.8e-4 off (unseen25); a fixed mesh is
            # bisected (``judged``: seed 4's unrestricted run was `optimal` on a J that moves
            # 1.7e-5 when bisected, seed 0's 8.7e-5)
            if mesh_tolerance is not None:
                _doubted(out, predicted, limit, "could not be corrected onto the final conditions")
            return _guarded(out, out_of_time)
        flight, switches = corrected.flight, corrected.switches
    else:
        flight, switches = fly(t_tab, U_tab, cuts), cuts
    gain = gain_of(flight)
    feasible = flight.violation <= FEASIBLE_SHARE * tolerance
    out = {"claimed": claimed, "flown": flight.objective, "gain": gain, "predicted_gain": predicted, "limit": limit,
           "violation": flight.violation, "feasible": bool(feasible), "corners": corner_times,
           "switches": [float(c) for c in switches],
           "passed": not (feasible and gain > limit)}
    if corrected is not None:
        out["corrected"] = {"share": corrected.share, "flights": corrected.flights, "stretch": corrected.stretch,
                            "conditions": [problem.boundary[i].text or str(problem.boundary[i].expr) for i in late]}
    if not feasible:
        out["judged"] = False
        out["note"] = (f"the flown control misses {flight.where} by {flight.violation:.1e} (relative): "
                       "its objective bounds nothing")
        _guarded(out, out_of_time)
    elif out["passed"] and gain < -limit and not _state_bound_binds(ph, traj):
        _doubted(out, predicted, limit, f"gives J = {flight.objective:.10g}, worse than the claim by {-gain:.1e}")
    elif not out["passed"]:
        t0, tf = float(tt[0]), float(tt[-1])
        features = sorted(corner_times + out["switches"])
        shown = ", ".join(f"{c:.6g}" for c in features[:6])
        scaled = ", ".join(f"{(c - t0) / (tf - t0):.6g}" for c in features[:6])
        what = ("reaches or leaves a bound" if not out["switches"] else
                "switches between bounds" if not corner_times else "reaches, leaves or switches between bounds")
        corrected_to = ("" if corrected is None else
                        f" ({corrected.share:g} of the step from the solution's control to it, corrected to meet "
                        f"{'; '.join(out['corrected']['conditions'])}"
                        + (f", over a final time {t0 + corrected.stretch * (tf - t0):.10g}" if corrected.stretch != 1.0 else "")
                        + ")")
        out["reason"] = (f"the control that minimises H along the solution's own states and costates, flown "
                         f"from x(t0){corrected_to}, gives J = {flight.objective:.10g}, better than the claimed {claimed:.10g} "
                         f"by {gain:.1e} (the tolerance allows {limit:.1e}): the solution is not optimal; its "
                         "control cannot follow the optimum between nodes"
                         + (f". That control {what} at t = {shown} (phase time {scaled} "
                            "of [0, 1]): breakpoints there (`segments: [0, ..., 1]`) let the mesh follow it"
                            if features else ": more segments, or `mesh:`"))
    return out
