"""Adaptive mesh refinement for the pseudospectral back end (``method: {mesh: {...}}``).

Each mesh iteration solves the NLP on the current mesh (warm-started from the previous
iteration's solution), estimates the error of every segment, and refines the segments whose
error is above the tolerance, until every segment is within it or ``max_iterations`` is
reached.

Error estimate (does not trust the collocation equations)
    In segment k, the state interpolant X(t) of the collocated solution is compared with the
    state obtained by *integrating* the dynamics from X(t_{k-1}) with the collocated control
    (the segment's control interpolant, clipped to the control bounds so that it stays
    admissible), by an adaptive Dormand-Prince 8(5,3) integrator (SciPy's DOP853, tolerances
    far below the mesh tolerance), on a finer set of points in the segment (N_k + 6
    Legendre-Gauss-Lobatto points). The relative error is that of Patterson, Hager & Rao,
    "A ph mesh refinement method for optimal control", Optimal Control Appl. Methods 36 (2015)
    398-421, eq. (29)-(30):

        e_k = max_i max_l |Xhat_i(t_l) - X_i(t_l)| / (1 + max_j |X_i(t_j)|)

    where Liu, Hager & Rao, "Adaptive mesh refinement method for optimal control using
    nonsmoothness detection and mesh size reduction", J. Franklin Inst. 352 (2015) 4081-4106,
    also integrate the dynamics with the collocated control (their estimate uses an ODE
    integration of the dynamics instead of a higher-degree collocation). In addition, the
    violation of the state bounds and path constraints by the integrated trajectory on the
    same points, relative to 1 + |bound|, counts as error (a polynomial state may leave a
    bound between collocation points).

Refinement rule
    - Smooth segment (no change of active set inside it): raise the degree by
      P_k = ceil(log(e_k / tol) / log(N_k)) (Patterson, Hager & Rao 2015, eq. (32)); when
      N_k + P_k exceeds ``max_degree``, split the segment into
      B_k = max(ceil((N_k + P_k) / min_degree), 2) equal segments of degree ``min_degree``
      (their eq. (34)).
    - Nonsmooth segment (an active-set change inside it: a control leaving or reaching a
      bound, or a state bound / path constraint becoming active or inactive, between two
      consecutive collocation points -- the switches and constraint corners of the solution,
      in the spirit of Liu, Hager & Rao's nonsmoothness detection): split it at the two
      collocation points that bracket each change and cut the bracket into ``bracket_pieces``
      equal pieces, all of degree ``min_degree``. The segment that holds the switch thus
      shrinks by a factor of about 2 * bracket_pieces / N_k per iteration, and the
      segments on either side of it are smooth, so the switch ends up on (or within a tiny
      segment next to) a segment boundary.

Warm start: the states and controls of the previous mesh are sampled from each segment's
interpolating polynomials and interpolated onto the new mesh (``transcribe.guess``).
Multipliers are not carried over (see docs/mesh-refinement.md).
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..result import PhaseTrajectory, Result

GOOD = ("optimal", "acceptable")


# ---------------------------------------------------------------------------------------
# error estimate
# ---------------------------------------------------------------------------------------

@dataclass
class SegmentError:
    phase: str
    segment: int
    t_start: float
    t_end: float
    degree: int
    error: float                 # max(relative state discrepancy, relative violation)
    discrepancy: float
    violation: float
    state: str                   # state with the largest discrepancy
    nonsmooth: bool
    switches: list[tuple[float, float]] = field(default_factory=list)   # brackets in s


def _phase_functions(ph, free_syms):
    args = list(ph.states) + list(ph.controls) + [sp.Symbol("t", real=True)] + list(free_syms)
    from ..symbolic.model import TIME

    args[len(ph.states) + len(ph.controls)] = TIME
    f = sp.lambdify(args, list(ph.rhs()), "numpy")
    g = sp.lambdify(args, [c.expr for c in ph.path], "numpy") if ph.path else None
    return f, g


def _solution_arrays(pb):
    import pyomo.environ as pyo

    lay, b, ph = pb.layout, pb.block, pb.phase
    nx, nu = len(ph.states), len(ph.controls)
    X = np.array([[pyo.value(b.X[n, j]) for j in range(nx)] for n in range(lay.n_state_nodes)], float)
    U = np.array([[pyo.value(b.U[i, j]) for j in range(nu)] for i in range(lay.n_colloc)],
                 float).reshape(lay.n_colloc, nu)
    return X, U, float(pyo.value(b.t0)), float(pyo.value(b.tf))


def _seg_polys(lay, k, X, U):
    """Callables tau -> state (m, nx) and tau -> control (m, nu) of segment k."""
    from ..transcribe.nodes import lagrange_matrix

    sc = lay.mesh.scheme(k)
    Xs, Uc = X[lay.support[k]], U[lay.colloc[k]]

    def xs(tau):
        return lagrange_matrix(np.asarray(sc.support), np.atleast_1d(tau)) @ Xs

    def us(tau):
        tau = np.atleast_1d(tau)
        if len(sc.colloc) == 1:
            return np.repeat(Uc, len(tau), axis=0)
        return lagrange_matrix(np.asarray(sc.colloc), tau) @ Uc

    return xs, us


def _activity(values, lo, hi, tol):
    """-1 at the lower bound, +1 at the upper bound, 0 inside (per value)."""
    out = np.zeros(len(values), int)
    if math.isfinite(lo):
        out[values <= lo + tol * (1 + abs(lo))] = -1
    if math.isfinite(hi):
        out[values >= hi - tol * (1 + abs(hi))] = 1
    return out


def estimate_errors(pb, params: dict, *, active_tol: float = 1e-6, extra_points: int = 6,
                    rtol: float = 1e-12) -> list[SegmentError]:
    """Per-segment error of one solved phase (see the module docstring)."""
    from scipy.integrate import solve_ivp

    from ..transcribe.nodes import legendre_gauss_lobatto

    ph, lay = pb.phase, pb.layout
    free_syms = sorted(params, key=str)
    pvals = [params[s] for s in free_syms]
    f, g = _phase_functions(ph, free_syms)
    X, U, t0, tf = _solution_arrays(pb)
    nx, nu = X.shape[1], U.shape[1]
    scale = 1.0 + np.max(np.abs(X), axis=0)
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    xlo = np.array([ph.bounds_of(s)[0] for s in ph.states])
    xhi = np.array([ph.bounds_of(s)[1] for s in ph.states])
    mesh = lay.mesh
    out = []
    for k in range(mesh.segments):
        sc = mesh.scheme(k)
        a, b = mesh.breakpoints[k], mesh.breakpoints[k + 1]
        ta, tb = t0 + (tf - t0) * a, t0 + (tf - t0) * b
        xs, us = _seg_polys(lay, k, X, U)
        h = tb - ta

        def uclip(t):
            tau = 2.0 * (t - ta) / h - 1.0 if h > 0 else 0.0
            return np.clip(us(tau)[0], ulo, uhi)

        def rhs(t, x):
            return np.asarray(f(*x, *uclip(t), t, *pvals), float).reshape(-1)

        tau_f = np.asarray(legendre_gauss_lobatto(sc.degree + extra_points)[0])
        t_f = ta + (tau_f + 1.0) * h / 2.0
        x_poly = xs(tau_f)
        x_start = x_poly[0]
        if h > 0:
            sol = solve_ivp(rhs, (ta, tb), x_start, method="DOP853", t_eval=t_f, rtol=rtol,
                            atol=rtol * scale)
            x_int = sol.y.T if sol.success and sol.y.shape[1] == len(t_f) else np.full_like(x_poly, np.nan)
        else:
            x_int = x_poly
        rel = np.abs(x_int - x_poly) / scale
        disc = float(np.nanmax(rel)) if np.isfinite(rel).any() else math.inf
        if not np.isfinite(rel).all():
            disc = math.inf
        which = ph.states[int(np.nanargmax(np.nanmax(rel, axis=0)))].name if np.isfinite(rel).any() else ""
        # violations of state bounds and path constraints by the integrated trajectory
        viol = 0.0
        with np.errstate(invalid="ignore"):
            over = np.maximum(x_int - xhi, 0) / (1 + np.abs(np.where(np.isfinite(xhi), xhi, 0)))
            under = np.maximum(xlo - x_int, 0) / (1 + np.abs(np.where(np.isfinite(xlo), xlo, 0)))
        viol = max(viol, float(np.nanmax(over, initial=0)), float(np.nanmax(under, initial=0)))
        u_f = np.clip(us(tau_f), ulo, uhi)
        if g is not None:
            for l, tl in enumerate(t_f):
                gv = np.asarray(g(*x_int[l], *u_f[l], tl, *pvals), float).reshape(-1)
                for c, v in zip(ph.path, gv):
                    if math.isfinite(c.upper) and v > c.upper:
                        viol = max(viol, (v - c.upper) / (1 + abs(c.upper)))
                    if math.isfinite(c.lower) and v < c.lower:
                        viol = max(viol, (c.lower - v) / (1 + abs(c.lower)))
        # active-set changes between consecutive collocation points of the segment
        # (for k > 0 the previous segment's last collocation point is included, so that a
        # change between segments is seen by the segment that starts there)
        sc_nodes = np.asarray(lay.colloc[k])
        st_nodes = np.asarray(lay.colloc_state[k])
        if k > 0:
            sc_nodes = np.concatenate([[lay.colloc[k - 1][-1]], sc_nodes])
            st_nodes = np.concatenate([[lay.colloc_state[k - 1][-1]], st_nodes])
        s_nodes = lay.s_colloc[sc_nodes]
        act = []
        Uc = U[sc_nodes]
        Xc = X[st_nodes]
        for j in range(nu):
            act.append(_activity(Uc[:, j], ulo[j], uhi[j], active_tol))
        for j in range(nx):
            if math.isfinite(xlo[j]) or math.isfinite(xhi[j]):
                act.append(_activity(Xc[:, j], xlo[j], xhi[j], active_tol))
        if g is not None:
            tc = t0 + (tf - t0) * s_nodes
            gv = np.array([np.asarray(g(*Xc[i], *Uc[i], tc[i], *pvals), float).reshape(-1)
                           for i in range(len(tc))])
            for q, c in enumerate(ph.path):
                if not c.is_equality:
                    act.append(_activity(gv[:, q], c.lower, c.upper, active_tol))
        # the start of the segment: the previous segment's last collocation point
        prev_s = None
        if k > 0:
            prev_node = lay.colloc[k - 1][-1]
            prev_s = lay.s_colloc[prev_node]
        switches = []
        for pattern_idx, pattern in enumerate(act):
            for i in range(1, len(pattern)):
                if pattern[i] != pattern[i - 1]:
                    switches.append((float(s_nodes[i - 1]), float(s_nodes[i])))
        if not switches and len(s_nodes) and prev_s is not None and act:
            pass
        switches = sorted(set(switches))
        err = max(disc, viol)
        out.append(SegmentError(ph.name, k, ta, tb, sc.degree, err, disc, viol, which,
                                bool(switches), switches))
    return out


# ---------------------------------------------------------------------------------------
# refinement
# ---------------------------------------------------------------------------------------

def _corner(mesh, k, errors, controls, tol):
    """Where the control has a corner (continuous, kinked) inside segment k, or None.

    The control polynomials of the two neighbouring segments, when both are smooth and
    within tolerance-free of switches, are extrapolated into segment k; a sign change of
    their difference locates the corner (a state-constraint junction, where the control is
    continuous but its derivative jumps). A jump (bang-bang) gives no crossing: None.
    """
    from scipy.optimize import brentq

    if controls is None or k == 0 or k == mesh.segments - 1:
        return None
    a, b = float(mesh.breakpoints[k]), float(mesh.breakpoints[k + 1])
    width = np.diff(mesh.breakpoints)
    # extrapolating a polynomial far beyond its own segment amplifies its errors: on each
    # side take the nearest segment at least half as wide as segment k
    lk = next((q for q in range(k - 1, -1, -1) if width[q] >= 0.5 * (b - a)), None)
    rk = next((q for q in range(k + 1, mesh.segments) if width[q] >= 0.5 * (b - a)), None)
    if lk is None or rk is None:
        return None
    left, right = controls[lk], controls[rk]
    grid = np.linspace(a, b, 41)
    best = None
    for j in range(left(grid).shape[1]):
        d = lambda s: float(left(np.array([s]))[0, j] - right(np.array([s]))[0, j])  # noqa: E731
        vals = np.array([d(s) for s in grid])
        span = np.max(np.abs(left(grid)[:, j])) + np.max(np.abs(right(grid)[:, j])) + 1.0
        for i in range(len(grid) - 1):
            if vals[i] == 0.0 or vals[i] * vals[i + 1] < 0:
                c = brentq(d, grid[i], grid[i + 1], xtol=1e-14) if vals[i] != 0.0 else grid[i]
                # a jump of the two extrapolations is no corner: they must cross at an angle
                # small against the control's range over the segment
                if abs(vals[0]) + abs(vals[-1]) < 0.5 * span and a < c < b:
                    best = c if best is None else best
                break
    if best is None or min(best - a, b - best) < 1e-12:
        return None
    return best


def corners_to_place(mesh, errors, spec, controls) -> list[float]:
    """Located control corners (normalised time) farther than corner_tolerance from a breakpoint."""
    out = []
    for e in errors:
        if not e.nonsmooth:
            continue
        c = _corner(mesh, e.segment, errors, controls, spec.tolerance)
        a, b = float(mesh.breakpoints[e.segment]), float(mesh.breakpoints[e.segment + 1])
        if c is not None and min(c - a, b - c) > spec.corner_tolerance:
            out.append(c)
    return out


def refine(mesh, errors: list[SegmentError], spec, controls=None) -> Any:
    """The next mesh of one phase (see the module docstring).

    ``controls``: per segment, a callable s -> (len(s), nu) control polynomial of that
    segment (extrapolated outside it), used to place a breakpoint on control corners.
    """
    from ..transcribe.mesh import Mesh

    tol, nmin, nmax = spec.tolerance, spec.min_degree, spec.max_degree
    pieces = spec.bracket_pieces
    bps, degs = [0.0], []
    for e in errors:
        k = e.segment
        a, b = float(mesh.breakpoints[k]), float(mesh.breakpoints[k + 1])
        N = mesh.degrees[k]
        corner = _corner(mesh, k, errors, controls, tol) if e.nonsmooth else None
        if corner is not None and min(corner - a, b - corner) <= spec.corner_tolerance:
            corner = None
        if not (e.error > tol) and corner is None:
            bps.append(b)
            degs.append(N)
            continue
        if e.nonsmooth:
            if corner is not None:
                bps.extend([corner, b])
                degs.extend([nmin, nmin])
                continue
            cuts = set()
            for lo, hi in e.switches:
                for q in range(pieces + 1):
                    cuts.add(lo + (hi - lo) * q / pieces)
            width = b - a
            cuts = sorted(c for c in cuts if a + 1e-9 * width < c < b - 1e-9 * width)
            merged = []
            for c in cuts:   # drop slivers far below the bracket scale
                if not merged or c - merged[-1] > 1e-6 * width:
                    merged.append(c)
            if merged:
                for c in merged:
                    bps.append(c)
                    degs.append(nmin)
                bps.append(b)
                degs.append(nmin)
                continue
        # smooth (or a switch that cannot be bracketed more finely): p, then h
        ratio = e.error / tol if math.isfinite(e.error) else 1e6
        P = max(1, math.ceil(math.log(ratio) / math.log(max(N, 2))))
        if N + P <= nmax:
            bps.append(b)
            degs.append(N + P)
        else:
            B = max(math.ceil((N + P) / nmin), 2)
            for q in range(1, B + 1):
                bps.append(a + (b - a) * q / B)
                degs.append(nmin)
    bps[-1] = 1.0
    return Mesh(mesh.scheme_name, np.array(bps), tuple(degs))


# ---------------------------------------------------------------------------------------
# warm start
# ---------------------------------------------------------------------------------------

def _control_polys(pb):
    """Per segment: s -> control polynomial of that segment (normalised time s)."""
    lay = pb.layout
    X, U, _, _ = _solution_arrays(pb)
    out = []
    for k in range(lay.mesh.segments):
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        _, us = _seg_polys(lay, k, X, U)
        out.append(lambda s, us=us, a=a, b=b: us(2.0 * (np.asarray(s) - a) / (b - a) - 1.0))
    return out


def _dense_trajectory(pb, samples: int = 4) -> PhaseTrajectory:
    """States and controls sampled from each segment's polynomials (a warm start)."""
    ph, lay = pb.phase, pb.layout
    X, U, t0, tf = _solution_arrays(pb)
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    xlo = np.array([ph.bounds_of(s)[0] for s in ph.states])
    xhi = np.array([ph.bounds_of(s)[1] for s in ph.states])
    ts, xs_all, us_all = [], [], []
    for k in range(lay.mesh.segments):
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        xs, us = _seg_polys(lay, k, X, U)
        n = lay.mesh.degrees[k] + samples
        # open interval inside the segment keeps np.interp's abscissae increasing
        tau = np.linspace(-1, 1, n + 2)[1:-1] if k < lay.mesh.segments - 1 or True else None
        if k == 0:
            tau = np.concatenate([[-1.0], tau])
        if k == lay.mesh.segments - 1:
            tau = np.concatenate([tau, [1.0]])
        s = a + (tau + 1.0) * (b - a) / 2.0
        ts.append(t0 + (tf - t0) * s)
        xs_all.append(np.clip(xs(tau), xlo, xhi))
        us_all.append(np.clip(us(tau), ulo, uhi))
    t = np.concatenate(ts)
    Xd, Ud = np.vstack(xs_all), np.vstack(us_all)
    return PhaseTrajectory(ph.name, t, {s.name: Xd[:, j] for j, s in enumerate(ph.states)},
                           {c.name: Ud[:, j] for j, c in enumerate(ph.controls)})


# ---------------------------------------------------------------------------------------
# driver
# ---------------------------------------------------------------------------------------

def initial_meshes(file) -> dict:
    from ..transcribe.mesh import Mesh

    method, spec = file.method, file.method.mesh
    given = method.model_fields_set
    segments = method.segments if "segments" in given else spec.segments
    degree = method.degree if "degree" in given else spec.degree
    if isinstance(degree, int):
        degree = min(max(degree, spec.min_degree), spec.max_degree)
    return {ph.name: Mesh.uniform(method.transcription, segments, degree) for ph in file.problem.phases}


def _say(progress: bool, text: str) -> None:
    if progress:
        print(text, file=sys.stderr, flush=True)


def solve_adaptive(file, timer, *, seed=None, warm_start=None, verbose=False, progress=False) -> Result:
    """Solve with adaptive mesh refinement; returns a Result with the mesh history."""
    import pyomo.environ as pyo

    from ..run import _result
    from ..transcribe.guess import make_guess
    from ..transcribe.pseudospectral import build
    from . import ipopt

    ipopt.check_available()
    problem, spec = file.problem, file.method.mesh
    meshes = initial_meshes(file)
    previous: dict[str, PhaseTrajectory] = {}
    if warm_start is not None:
        previous = {p.name: p for p in Result.read(warm_start).phases}
    options = dict(file.spec.solver.options)
    # the NLP must be solved well below the mesh tolerance, or solver noise (Ipopt's
    # relaxation of the bounds, its stopping tolerance) is what the estimate measures
    options.setdefault("tol", min(1e-8, 1e-2 * spec.tolerance))
    options.setdefault("bound_relax_factor", min(1e-8, 1e-3 * spec.tolerance))
    history, tables = [], {k: [] for k in ("iteration", "phase", "segments", "min_degree", "max_degree", "nlp_variables",
                                          "nlp_constraints", "ipopt_iterations", "objective",
                                          "max_error", "max_error_segment", "max_error_t", "time_s")}
    best = None          # (max_error, iteration, tr, info, meshes, errors)
    status, message = None, ""
    last = None
    for it in range(1, spec.max_iterations + 1):
        t_iter = time.perf_counter()
        with timer.measure("build"):
            guesses = {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=seed if it == 1 else None)
                       for ph in problem.phases}
            tr = build(problem, meshes, guesses)
        with timer.measure("solve"):
            bar = ipopt.Progress(progress, f"[mesh {it}]")
            info = ipopt.solve(tr.model, options, verbose=verbose, progress=bar)
        with timer.measure("mesh"):
            params = {s: float(pyo.value(tr.scalars[s])) for s in problem.free_parameters}
            errors = {pb.phase.name: estimate_errors(pb, params, active_tol=max(1e-9, 0.1 * spec.tolerance))
                      if info.status in GOOD else []
                      for pb in tr.phases}
        allerr = [e for es in errors.values() for e in es]
        worst = max(allerr, key=lambda e: e.error) if allerr else None
        max_err = worst.error if worst else math.inf
        elapsed = time.perf_counter() - t_iter
        rec = {"iteration": it, "status": info.status, "objective": info.objective,
               "ipopt_iterations": info.iterations, "nlp": dict(info.nlp), "time_s": round(elapsed, 4),
               "max_error": max_err,
               "where": ({"phase": worst.phase, "segment": worst.segment, "t": [worst.t_start, worst.t_end],
                          "state": worst.state} if worst else None),
               "meshes": {k: m.describe() for k, m in meshes.items()}}
        history.append(rec)
        for ph in problem.phases:
            m = meshes[ph.name]
            es = errors[ph.name]
            w = max(es, key=lambda e: e.error) if es else None
            tables["iteration"].append(it)
            tables["phase"].append(problem.phases.index(ph))
            tables["segments"].append(m.segments)
            tables["min_degree"].append(min(m.degrees))
            tables["max_degree"].append(max(m.degrees))
            tables["nlp_variables"].append(info.nlp.get("variables", 0))
            tables["nlp_constraints"].append(info.nlp.get("constraints", 0))
            tables["ipopt_iterations"].append(info.iterations)
            tables["objective"].append(info.objective if info.objective is not None else math.nan)
            tables["max_error"].append(w.error if w else math.nan)
            tables["max_error_segment"].append(w.segment if w else -1)
            tables["max_error_t"].append(0.5 * (w.t_start + w.t_end) if w else math.nan)
            tables["time_s"].append(round(elapsed, 4))
        where = (f"{worst.phase}[{worst.segment}] t in [{worst.t_start:.6g}, {worst.t_end:.6g}] ({worst.state})"
                 if worst else "-")
        _say(progress, f"mesh {it:2d}: {sum(m.segments for m in meshes.values()):3d} segments, "
                       f"{info.nlp.get('variables', 0):5d} variables, Ipopt {info.status} in {info.iterations:4d} it, "
                       f"J = {info.objective if info.objective is not None else float('nan'):.10g}, "
                       f"max error {max_err:.2e} at {where}, {elapsed:.2f} s")
        last = (max_err, it, tr, info, dict(meshes), errors)
        if info.status not in GOOD:
            status = info.status
            message = (f"mesh iteration {it}: Ipopt ended with '{info.status}' ({info.message}); "
                       "mesh refinement stopped")
            break
        if best is None or max_err < best[0]:
            best = last
        corners = {pb.phase.name: corners_to_place(meshes[pb.phase.name], errors[pb.phase.name], spec,
                                                   _control_polys(pb)) for pb in tr.phases}
        rec["corners_to_place"] = corners
        if max_err <= spec.tolerance and not any(corners.values()):
            status = "optimal" if info.status == "optimal" else info.status
            message = (f"mesh converged in {it} iteration(s): largest estimated error {max_err:.3e} "
                       f"<= tolerance {spec.tolerance:.1e}")
            break
        if it == spec.max_iterations:
            status = "mesh_not_converged"
            break
        previous = {pb.phase.name: _dense_trajectory(pb) for pb in tr.phases}
        meshes = {pb.phase.name: refine(meshes[pb.phase.name], errors[pb.phase.name], spec,
                                        _control_polys(pb)) for pb in tr.phases}
    chosen = last if status != "mesh_not_converged" or best is None else best
    max_err, it_c, tr_c, info_c, meshes_c, errors_c = chosen
    if status == "mesh_not_converged":
        above = [e for es in errors_c.values() for e in es if e.error > spec.tolerance]
        worst = max(above, key=lambda e: e.error)
        message = (f"mesh refinement did not reach the tolerance {spec.tolerance:.1e} in "
                   f"{spec.max_iterations} iterations: best mesh (iteration {it_c}) has largest estimated "
                   f"error {max_err:.3e} in phase '{worst.phase}' segment {worst.segment} "
                   f"(t in [{worst.t_start:.6g}, {worst.t_end:.6g}], state {worst.state}); "
                   f"{len(above)} segment(s) above tolerance. Raise max_iterations or max_degree, "
                   "or loosen the tolerance.")
    with timer.measure("post"):
        result = _result(file, tr_c, info_c, timer, meshes_c)
    result.status = status
    result.message = message
    result.iterations = sum(h["ipopt_iterations"] for h in history)
    err_tab = {k: [] for k in ("phase", "segment", "t_start", "t_end", "degree", "error",
                               "discrepancy", "violation", "nonsmooth")}
    names = [ph.name for ph in problem.phases]
    for es in errors_c.values():
        for e in es:
            for key in err_tab:
                v = getattr(e, key)
                err_tab[key].append(names.index(v) if key == "phase" else float(v))
    result.extra["mesh_history"] = history
    result.extra["mesh"] = {"tolerance": spec.tolerance, "iterations": len(history), "chosen_iteration": it_c,
                            "converged": status == "optimal" or (status in GOOD and max_err <= spec.tolerance),
                            "max_error": max_err,
                            "error_map": {ph: [[e.t_start, e.t_end, e.error] for e in es]
                                          for ph, es in errors_c.items()}}
    result.tables["mesh_history"] = {k: np.asarray(v) for k, v in tables.items()}
    result.tables["mesh_error"] = {k: np.asarray(v) for k, v in err_tab.items()}
    result.wall_time_s = timer.breakdown()
    return result
