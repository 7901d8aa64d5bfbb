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
      segment next to) a segment boundary. Used when the switch cannot be located:
    - Located switches and corners (``locate_features``): a bound-to-bound switch from the
      quadrature of the collocated control (``locate_switches``), a corner from the crossing
      of the neighbouring smooth segments' control polynomials (``_corner``), another jump
      from the same quadrature with those polynomials in place of the bounds (``_jump``).
      Each one farther than ``corner_tolerance`` from a breakpoint becomes one: the nearest
      breakpoint is moved onto it when within ``snap`` of the segment width, else the segment
      is split there; the mesh is not converged while one is off its breakpoint.
    - Ends of state-constrained arcs (``locate_junctions``, our method): from the boundary
      control u_b (the bounded state differentiated along the dynamics until a control
      appears, ``_boundary_controls``), the zero of u_U - u_b with u_U the control polynomial
      of the nearest unconstrained segment (first-order constraints with a control jump: the
      zero of that segment's state polynomial minus the bound); repeated on the same mesh
      shape, a secant step on the map breakpoint -> estimate.
    - On an arc mesh (every interior breakpoint on a located feature), breakpoints are moved
      onto their re-located features and the segments next to them kept (``_arc_mesh_moves``).
    - At most ``growth`` times the segments per refinement (largest errors first); a split
      over the remaining budget is cut down to it (``_within_budget``), never dropped.
    - Never the same mesh twice while the tolerance is unmet: if the rules leave a phase's
      mesh unchanged, its worst segment gets degree + 1 (up to ``max_degree``) or is bisected
      (``_forced_refinement``); when that is impossible ``MeshStalled`` ends the run with
      ``mesh_not_converged`` and the reason in the message.
    - Coarsening (``coarsen``), once a mesh meets the tolerance: Liu, Hager & Rao (2015)
      reduce degrees and merge segments where the error is far below tolerance; here
      consecutive segments are merged and every segment gets the smallest degree for which
      one Legendre polynomial fits the solution's states over it within
      ``coarsen_margin * tolerance``. The coarse mesh is solved and estimated like any other
      (refined again if it misses); the smallest mesh that met the tolerance is returned.
      A second candidate is the arc mesh: one segment per arc between located features, a
      state-constrained arc fitted on its boundary-control trajectory (``_arc_mesh``).
    - Controls at phase junctions (``junction_control: limit``, the default;
      ``limit_junction_controls``): a control collocated at a phase's end point where another
      phase joins (LGR: tau = +1, LGR-start: tau = -1, LGL: both), and for LGL both controls at
      a breakpoint on a located switch/corner, are constrained to the one-sided limit of their
      segment's interior control polynomial. The continuous problem leaves the control at that
      instant free (measure zero); the NLP weights it by its quadrature weight and, left free,
      set it to the other bound so that the control polynomial overshoots its bound between
      the nodes (two-phase double integrator: estimate stuck at 2.8e-6 after 8 iterations).
    - Optional regularisation (``regularise`` > 0): w * int (du/ds)^2 ds over the arcs where
      the control chattered (``chattering_segments``, ``regularise``); the reported objective
      leaves the term out. It changes the problem (measured bias in docs/mesh-refinement.md).

Warm start (``warm_start``): with ``multipliers`` (default) the new mesh starts from the
previous mesh's polynomials and from its multipliers mapped through the costate, the path and
bound multiplier densities and by name (``solve/warm_start.py``), solved by cyipopt directly
(``ipopt.solve(..., multipliers=...)``; Pyomo's cyipopt solver passes no ``lagrange``/``zl``/
``zu``); with ``primal`` only the states and controls, sampled from the polynomials and
interpolated onto the new mesh (``transcribe.guess``).
"""
from __future__ import annotations

import math
import sys
import time
import warnings
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
    smoothed: bool = False       # the error is the one with the smoothed control (see estimate_errors)


def _phase_functions(ph, free_syms):
    args = list(ph.states) + list(ph.controls) + [sp.Symbol("t", real=True)] + list(free_syms)
    from ..symbolic.model import TIME

    args[len(ph.states) + len(ph.controls)] = TIME
    f = sp.lambdify(args, list(ph.rhs()), "numpy")
    g = sp.lambdify(args, [c.expr for c in ph.path], "numpy") if ph.path else None
    return f, g


def _solution_arrays(pb):
    from ..transcribe.solution import node_values, phase_times

    return (*node_values(pb), *phase_times(pb))


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


def _zigzag(u, step: float | None = None) -> bool:
    """Node-to-node chattering: the significant steps of u (above ``step``, default 1e-6 of
    1 + max |u|) alternate in sign at least twice."""
    d = np.diff(np.asarray(u, float))
    d = d[np.abs(d) > (1e-6 * (1.0 + np.max(np.abs(u))) if step is None else step)]
    return int(np.sum(np.sign(d[1:]) != np.sign(d[:-1]))) >= 2


def _smoothed_control(lay, k, U, ulo, uhi, t0, tf):
    """t -> control: least-squares quadratic in time through the collocated controls of
    segment k and its two neighbours (weighted by the quadrature weights), clipped to the
    bounds."""
    segs = range(max(0, k - 1), min(lay.mesh.segments, k + 2))
    nodes = np.concatenate([lay.colloc[q] for q in segs])
    # weighted by the quadrature weights: the dynamics feel the control through them
    w = np.concatenate([np.asarray(lay.mesh.scheme(q).weights) * (lay.mesh.breakpoints[q + 1] - lay.mesh.breakpoints[q])
                        for q in segs])
    ts = t0 + (tf - t0) * lay.s_colloc[nodes]
    deg = min(2, len(nodes) - 1)
    mid, half = 0.5 * (ts.min() + ts.max()), 0.5 * (ts.max() - ts.min()) or 1.0
    coef = [np.polyfit((ts - mid) / half, U[nodes, j], deg, w=np.sqrt(w)) for j in range(U.shape[1])]
    return lambda t: np.clip([np.polyval(c, (t - mid) / half) for c in coef], ulo, uhi)


def estimate_errors(pb, params: dict, *, active_tol: float = 1e-6, extra_points: int = 6,
                    rtol: float = 1e-12, smooth_above: float | None = None) -> list[SegmentError]:
    """Per-segment error of one solved phase (see the module docstring).

    ``smooth_above``: where the error with the collocated control is above it, the dynamics
    are integrated again with the smoothed control (``_smoothed_control``) and the smaller
    of the two errors is kept (``SegmentError.smoothed``). Both controls are admissible, so
    either way the collocated state is that close to a trajectory of the system; the
    smoothing keeps node-to-node chattering of a weakly determined control (singular arcs)
    from being taken for a state error and split forever."""
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
        t_f = np.clip(ta + (tau_f + 1.0) * h / 2.0, min(ta, tb), max(ta, tb))
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
        smoothed = False
        # only where every control is strictly inside its bounds at the segment's nodes and the
        # neighbours' (a boundary arc), or zigzags from node to node (a singular arc's
        # chattering): a single jump to or from a bound is a switch, not smoothed away
        near = np.concatenate([lay.colloc[q] for q in range(max(0, k - 1), min(mesh.segments, k + 2))])
        inside = all(not _activity(U[near, j], ulo[j], uhi[j], 1e-6).any() or _zigzag(U[near, j])
                     for j in range(nu))
        if smooth_above is not None and disc > smooth_above and h > 0 and nu and inside:
            usm = _smoothed_control(lay, k, U, ulo, uhi, t0, tf)
            sol2 = solve_ivp(lambda t, x: np.asarray(f(*x, *usm(t), t, *pvals), float).reshape(-1),
                             (ta, tb), x_start, method="DOP853", t_eval=t_f, rtol=rtol, atol=rtol * scale)
            if sol2.success and sol2.y.shape[1] == len(t_f):
                rel2 = np.abs(sol2.y.T - x_poly) / scale
                if np.isfinite(rel2).all() and float(np.max(rel2)) < disc:
                    x_int, rel, disc, smoothed = sol2.y.T, rel2, float(np.max(rel2)), True
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
                                bool(switches), switches, smoothed))
    return out


# ---------------------------------------------------------------------------------------
# located nonsmooth points: bang-bang switches (switching function) and control corners
# ---------------------------------------------------------------------------------------

def locate_switches(tr, pb, params: dict, active_tol: float) -> list[float]:
    """Bang-bang switches of one phase in normalised time, located from the collocated control.

    For a control with two finite bounds, a switch is a run of collocation points at one
    bound followed (after only interior values) by a run at the other bound. The window is
    the union of the segments that hold the interior values (or, for a clean jump inside one
    segment, that segment); if the jump falls between two segments with no interior value,
    the switch is that breakpoint. Inside the window the switch time t_s is the one for which
    the bang-bang control delivers the same quadrature of the control as the collocated one
    (Gauss-Radau weights of each segment):
        sum_i w_i u_i h_k / 2 = u_A (t_s - a) + u_B (b - t_s).
    The next solve on a mesh with a breakpoint at t_s shows interior control values near it
    again only as far as t_s is still off, so the estimate tightens every iteration (to about
    active_tol times the segment width). The costate-based switching function H_u was tried
    and not used: the LGR costate estimate is biased near a switch (minimum-time double
    integrator, 2 x 3 mesh: zero of H_u at t = 1.0327 for the exact switch t = 1).
    """
    ph, lay = pb.phase, pb.layout
    mesh = lay.mesh
    _, U, _, _ = _solution_arrays(pb)
    seg = lay.colloc_segment
    out = []
    for j, c in enumerate(ph.controls):
        lo, hi = ph.bounds_of(c)
        if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
            continue
        act = _activity(U[:, j], lo, hi, active_tol)
        at = [i for i in range(len(act)) if act[i] != 0]
        for p, q in zip(at, at[1:]):
            if act[p] == act[q] or act[p + 1:q].any():
                continue
            # a switch ends a run of two nodes at one bound and starts a run at the other
            # (single nodes at a bound are the chattering of a singular arc)
            if not (p >= 1 and act[p - 1] == act[p] and q + 1 < len(act) and act[q + 1] == act[q]):
                continue
            uA, uB = (lo, hi) if act[p] < 0 else (hi, lo)
            if q == p + 1 and seg[p] != seg[q]:
                out.append(float(mesh.breakpoints[seg[q]]))
                continue
            first = seg[p + 1] if q > p + 1 else seg[p]
            last = seg[q - 1] if q > p + 1 else seg[q]
            a, b = float(mesh.breakpoints[first]), float(mesh.breakpoints[last + 1])
            Q = 0.0
            for k in range(first, last + 1):
                sc = mesh.scheme(k)
                h = mesh.breakpoints[k + 1] - mesh.breakpoints[k]
                Q += float(np.dot(sc.weights, U[lay.colloc[k], j])) * h / 2
            ts = a + (Q - uB * (b - a)) / (uA - uB)
            out.append(float(min(max(ts, a), b)))
    return sorted(set(out))


def _smooth_neighbours(mesh, k, errors) -> tuple[int, int] | None:
    """The nearest smooth segments left and right of segment k, at least half its width
    (their control polynomials stand in for the control on either side of a feature)."""
    if k == 0 or k == mesh.segments - 1:
        return None
    width = np.diff(mesh.breakpoints)
    rough = {e.segment for e in errors if e.nonsmooth}
    ok = lambda q: q not in rough and width[q] >= 0.5 * width[k]  # noqa: E731
    lk = next((q for q in range(k - 1, -1, -1) if ok(q)), None)
    rk = next((q for q in range(k + 1, mesh.segments) if ok(q)), None)
    return None if lk is None or rk is None else (lk, rk)


def _corner(mesh, k, errors, controls, tol):
    """Where the control has a corner (continuous, kinked) near segment k, or None.

    The control polynomials of the nearest smooth segments on either side (not flagged
    nonsmooth, at least half as wide as segment k) are extrapolated over the gap between
    them; a sign change of their difference locates the corner (a state-constraint junction,
    where the control is continuous but its derivative jumps). The segments in the gap are
    not used: there the discrete solution smears the corner over the nodes next to
    whatever breakpoint is nearest. A jump (bang-bang) gives no crossing: None.
    """
    from scipy.optimize import brentq

    sides = _smooth_neighbours(mesh, k, errors) if controls is not None else None
    if sides is None:
        return None
    lk, rk = sides
    left, right = controls[lk], controls[rk]
    ga, gb = float(mesh.breakpoints[lk + 1]), float(mesh.breakpoints[rk])
    grid = np.linspace(ga, gb, 81)
    best = None
    for j in range(left(grid).shape[1]):
        d = lambda s: float(left(np.array([s]))[0, j] - right(np.array([s]))[0, j])  # noqa: E731
        vals = np.array([d(s) for s in grid])
        span = np.max(np.abs(left(grid)[:, j])) + np.max(np.abs(right(grid)[:, j])) + 1.0
        # no kink where the two polynomials stay together to 1e-3 of the control's size over
        # the gap (Goddard's coast arc: u at 0 up to solver noise of 1e-6 crossed itself)
        if np.max(np.abs(vals)) < 1e-3 * span:
            continue
        for i in range(len(grid) - 1):
            if vals[i] == 0.0 or vals[i] * vals[i + 1] < 0:
                c = brentq(d, grid[i], grid[i + 1], xtol=1e-14) if vals[i] != 0.0 else grid[i]
                # a jump of the two extrapolations is no corner: they must cross at an angle
                # small against the control's range over the gap
                if abs(vals[0]) + abs(vals[-1]) < 0.5 * span and ga < c < gb:
                    best = c if best is None else best
                break
    if best is None or min(best - ga, gb - best) < 1e-12:
        return None
    return best


def _jump(mesh, k, errors, controls, U, lay):
    """Where the control jumps near nonsmooth segment k (a bound-to-interior switch, such as
    the entry of a first-order state-constraint arc), or None.

    With u_L and u_R the control polynomials of the nearest smooth segments on either side
    (as in ``_corner``) and [g_a, g_b] the gap between them, t_s solves
        int_{g_a}^{t_s} u_L + int_{t_s}^{g_b} u_R = sum over the gap's segments of w_i u_i h/2,
    the quadrature of the collocated control (the same impulse as ``locate_switches``, with
    the neighbours' controls in place of the bounds), for the control with the largest jump.
    """
    from scipy.integrate import quad
    from scipy.optimize import brentq

    sides = _smooth_neighbours(mesh, k, errors) if controls is not None else None
    if sides is None:
        return None
    lk, rk = sides
    ga, gb = float(mesh.breakpoints[lk + 1]), float(mesh.breakpoints[rk])
    mid = np.array([0.5 * (ga + gb)])
    jumps = np.abs(controls[lk](mid)[0] - controls[rk](mid)[0])
    j = int(np.argmax(jumps))
    scale = 1.0 + np.max(np.abs(U[:, j]))
    if jumps[j] < 1e-6 * scale:
        return None
    Q = 0.0
    for q in range(lk + 1, rk):
        sc = mesh.scheme(q)
        Q += float(np.dot(sc.weights, U[lay.colloc[q], j])) * (mesh.breakpoints[q + 1] - mesh.breakpoints[q]) / 2
    uL = lambda s: float(controls[lk](np.array([s]))[0, j])  # noqa: E731
    uR = lambda s: float(controls[rk](np.array([s]))[0, j])  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # quad's round-off notes near the root
        total_R = quad(uR, ga, gb, epsabs=1e-14)[0]
        F = lambda ts: quad(lambda s: uL(s) - uR(s), ga, ts, epsabs=1e-14)[0] + total_R - Q  # noqa: E731
        fa, fb = F(ga), F(gb)
        if not fa * fb < 0:
            return None
        ts = brentq(F, ga, gb, xtol=1e-14)
    return ts if ga < ts < gb else None


def _boundary_controls(ph, free_syms, max_order: int = 3) -> dict:
    """Per bounded state j: (order, control index, callable (x..., t, p...) -> u), the control
    that keeps the state on its bound (``boundary control``): the state's time derivatives along
    the dynamics are taken until a control appears (the constraint's order q) and the q-th
    derivative = 0 is solved for that control (Bryson & Ho 1975, sec. 3.11). Bryson-Denham
    x <= l: x'' = u, q = 2, u_b = 0; Goddard v <= v_max: v' = 0, q = 1, u_b = (D + m/r^2)/T_max.
    States whose derivatives meet several controls at once, or none up to ``max_order``, or
    whose equation sympy cannot solve uniquely, are left out."""
    from ..symbolic.model import TIME

    f = list(ph.rhs())
    out = {}
    for j, s in enumerate(ph.states):
        lo, hi = ph.bounds_of(s)
        if not (math.isfinite(lo) or math.isfinite(hi)):
            continue
        c = s
        for q in range(1, max_order + 1):
            c = sum(sp.diff(c, x) * fx for x, fx in zip(ph.states, f)) + sp.diff(c, TIME)
            present = [i for i, u in enumerate(ph.controls) if c.has(u)]
            if not present:
                continue
            if len(present) > 1:
                break
            i = present[0]
            try:
                sol = sp.solve(sp.Eq(c, 0), ph.controls[i], dict=False)
            except Exception:
                break
            if len(sol) == 1:
                args = list(ph.states) + [TIME] + list(free_syms)
                out[j] = (q, i, sp.lambdify(args, sol[0], "numpy"))
            break
    return out


def _state_at(lay, X, U, s):
    """State polynomial value at normalised time s (the segment holding s; the first or last
    segment's polynomial extrapolated outside [0, 1])."""
    bps = lay.mesh.breakpoints
    k = int(np.clip(np.searchsorted(bps, s, side="right") - 1, 0, lay.mesh.segments - 1))
    xs, _ = _seg_polys(lay, k, X, U)
    a, b = bps[k], bps[k + 1]
    return xs(2.0 * (s - a) / (b - a) - 1.0)[0]


def locate_junctions(pb, params: dict, active_tol: float, memory: dict | None = None) -> list[float]:
    """Entry and exit times of state-constrained arcs (normalised time), located from the
    arc next to them (our method; see docs/mesh-refinement.md).

    A constrained arc is a run of segments on which a state is at its bound on every state
    node; for it and the nearest segment on either side on which that state is at its bound
    on no node, the junction is the zero nearest the arc of
        phi(s) = u_U(s) - u_b(x(s), t(s)),
    u_U the unconstrained segment's control polynomial (extrapolated over the gap), u_b the
    boundary control (``_boundary_controls``) along the state polynomials: at a junction of a
    constraint of order >= 2 the control is continuous and equals u_b. For a first-order
    constraint (Goddard's v <= v_max) the control may jump there (u_b to 0); when phi has no
    zero, the zero of x_U,j(s) - bound is used instead, x_U,j the unconstrained segment's state polynomial
    extrapolated (the state is continuous with a kink at the junction). Measured on
    Bryson-Denham, mesh (3, 1, 3) with breakpoints at 1/3 + d1 and 2/3 + d2: the exit is
    found to 6 d2^2 (the arc after it is the cubic fixed by x = l, v = 0 at its start), the
    entry only to 0.8 d1 (LGR collocates the entry breakpoint in the arc before it, which
    tilts that arc's control). So, on a mesh with the same segments and degrees as in an
    earlier iteration (``memory``), the estimate g(b) of a junction breakpoint b is treated as
    a fixed-point map and the breakpoint is moved to the secant root of g(b) - b instead
    (exact for a linear map; measured on configs/mesh_bryson_denham.yaml: the entry
    1.1e-5 -> 9.1e-6 by the plain estimate, then 3.6e-10 by one secant step).
    """
    from scipy.optimize import brentq

    ph, lay = pb.phase, pb.layout
    mesh = lay.mesh
    free_syms = sorted(params, key=str)
    pvals = [params[s] for s in free_syms]
    ubs = _boundary_controls(ph, free_syms)
    if not ubs:
        return []
    X, U, t0, tf = _solution_arrays(pb)
    bps = np.asarray(mesh.breakpoints)
    K = mesh.segments
    polys = _control_polys(pb)
    out = []
    for j, (order, i, ub) in ubs.items():
        lo, hi = ph.bounds_of(ph.states[j])
        act = [_activity(X[lay.support[k], j], lo, hi, active_tol) for k in range(K)]
        full = [bool(a.all()) and len(set(a.tolist())) == 1 for a in act]
        # off the bound inside (the ends may touch it: a junction), and clearly so somewhere:
        # a state that sits at its bound up to solver noise is no unconstrained arc
        away = 1e-6 * (1.0 + abs(hi if math.isfinite(hi) else lo))
        free = [not a[1:-1].any() and float(np.max(np.minimum(np.abs(X[lay.support[k], j] - lo),
                                                              np.abs(X[lay.support[k], j] - hi)))) > away
                for k, a in enumerate(act)]
        k = 0
        while k < K:
            if not full[k]:
                k += 1
                continue
            qa = k
            while k + 1 < K and full[k + 1]:
                k += 1
            qb = k
            k += 1
            for side, (edge, other) in (("entry", (qa, next((q for q in range(qa - 1, -1, -1) if free[q]), None))),
                                        ("exit", (qb, next((q for q in range(qb + 1, K) if free[q]), None)))):
                if other is None:
                    continue
                b = float(bps[edge] if side == "entry" else bps[edge + 1])
                lo_s = 0.5 * (bps[other] + bps[other + 1]) if side == "entry" else b
                hi_s = b if side == "entry" else 0.5 * (bps[other] + bps[other + 1])
                # up to the middle of the arc's first (last) segment on its side
                if side == "entry":
                    hi_s = 0.5 * (bps[edge] + bps[edge + 1])
                else:
                    lo_s = 0.5 * (bps[edge] + bps[edge + 1])

                bound = hi if act[edge][0] > 0 else lo
                xs_other = _seg_polys(lay, other, X, U)[0]
                a_o, b_o = bps[other], bps[other + 1]

                def phi(s, other=other, i=i, ub=ub):
                    x = _state_at(lay, X, U, s)
                    return float(polys[other](np.array([s]))[0, i]
                                 - ub(*x, t0 + (tf - t0) * s, *pvals))

                def psi(s, xs_other=xs_other, a_o=a_o, b_o=b_o, bound=bound, j=j):
                    # the state leaves (reaches) its bound with a kink where the control jumps;
                    # the other arc's state polynomial, extrapolated, crosses the bound there
                    return float(xs_other(2.0 * (s - a_o) / (b_o - a_o) - 1.0)[0, j] - bound)

                grid = np.linspace(lo_s, hi_s, 201)
                roots = []
                for fun in ((phi, psi) if order == 1 else (phi,)):
                    with np.errstate(all="ignore"):
                        vals = np.array([fun(s) for s in grid])
                    roots = [brentq(fun, grid[n], grid[n + 1], xtol=1e-15)
                             for n in range(len(grid) - 1)
                             if np.isfinite(vals[n]) and np.isfinite(vals[n + 1]) and vals[n] * vals[n + 1] < 0]
                    roots += [grid[n] for n in range(len(grid)) if vals[n] == 0.0]
                    if roots:
                        break
                if not roots:
                    continue
                g = min(roots, key=lambda r: abs(r - b))
                if memory is not None:
                    key = (side, j, edge, tuple(mesh.degrees))
                    prev = memory.get(key)
                    memory[key] = (b, g)
                    if prev is not None and abs(prev[0] - b) > 1e-15:
                        F0, F1 = prev[1] - prev[0], g - b
                        if F1 != F0:
                            cand = b - F1 * (b - prev[0]) / (F1 - F0)
                            rho = 1.0 + (F1 - F0) / (b - prev[0])   # slope of the map g
                            if -1.0 < rho < 0.95 and 0 < cand < 1:
                                g = cand
                gap = abs(b - (bps[other + 1] if side == "entry" else bps[other]))
                out.append((float(g), float(gap)))
    # two estimates of one junction (Goddard: v leaves v_max where m reaches m_min): the one
    # extrapolated over the shorter gap is kept
    kept: list[tuple[float, float]] = []
    for g, gap in sorted(out, key=lambda q: q[1]):
        if all(abs(g - h) > max(gap, hgap, 1e-12) for h, hgap in kept):
            kept.append((g, gap))
    return sorted(g for g, _ in kept)


def locate_features(tr, pb, errors, params, spec, controls, memory: dict | None = None) -> list[float]:
    """Located nonsmooth points of one phase (normalised time): bound-to-bound switches, the
    ends of state-constrained arcs (``locate_junctions``; ``memory`` carries its secant steps
    across iterations), then, in nonsmooth segments that hold none, corners (``_corner``) or
    other jumps (``_jump``)."""
    mesh = pb.layout.mesh
    U = _solution_arrays(pb)[1]
    # at a bound to 1e-6 (relative): the NLP's bound relaxation and stopping tolerance leave
    # a bang arc's control ~1e-8 inside its bound
    feats = locate_switches(tr, pb, params, max(1e-6, 0.1 * spec.tolerance))
    junctions = []
    try:
        junctions = locate_junctions(pb, params, max(1e-9, 0.1 * spec.tolerance), memory)
    except Exception:   # an aid only: the other locators and the estimate still work
        pass
    for f in junctions:
        if all(abs(f - g) > spec.corner_tolerance for g in feats):
            feats.append(f)
    bps = mesh.breakpoints
    for e in errors:
        if not e.nonsmooth:
            continue
        a, b = float(bps[e.segment]), float(bps[e.segment + 1])
        if any(a - spec.corner_tolerance <= f <= b + spec.corner_tolerance for f in feats):
            continue
        # a junction in a neighbouring segment already accounts for this one's active-set change
        lo_n, hi_n = float(bps[max(e.segment - 1, 0)]), float(bps[min(e.segment + 2, mesh.segments)])
        if any(lo_n <= f <= hi_n for f in junctions):
            continue
        c = _corner(mesh, e.segment, errors, controls, spec.tolerance)
        if c is None:
            c = _jump(mesh, e.segment, errors, controls, U, pb.layout)
        # a point outside the flagged segment is not the change it holds (measured on Goddard:
        # the coast arc's flagged segments, where u sits at 0 up to solver noise, gave the
        # burn's end 0.1 away)
        if c is not None and not (a - spec.corner_tolerance <= c <= b + spec.corner_tolerance):
            c = None
        if c is not None and all(abs(c - f) > spec.corner_tolerance for f in feats):
            feats.append(c)
    return sorted(feats)


def misplaced(mesh, features, spec) -> list[float]:
    """Located features farther than corner_tolerance (normalised time) from every breakpoint."""
    bps = np.asarray(mesh.breakpoints)
    return [f for f in features if np.min(np.abs(bps - f)) > spec.corner_tolerance]


# kept for callers of the previous interface
def corners_to_place(mesh, errors, spec, controls) -> list[float]:
    out = []
    for e in errors:
        if not e.nonsmooth:
            continue
        c = _corner(mesh, e.segment, errors, controls, spec.tolerance)
        a, b = float(mesh.breakpoints[e.segment]), float(mesh.breakpoints[e.segment + 1])
        if c is not None and min(c - a, b - c) > spec.corner_tolerance:
            out.append(c)
    return out


# ---------------------------------------------------------------------------------------
# refinement
# ---------------------------------------------------------------------------------------

def _place(segs: list[list], f: float, snap: float, keep: list[float], tol: float) -> None:
    """Put a breakpoint on f in the segment list [[a, b, N], ...] (in place).

    A breakpoint within ``snap`` of the segment's width from f is moved onto f (no sliver
    segment is left next to the feature) unless it is 0, 1 or holds another feature (within
    ``tol`` of one in ``keep``); otherwise the segment is split at f.
    """
    k = next((q for q, (a, b, _) in enumerate(segs) if a <= f <= b), None)
    if k is None:
        return
    a, b, N = segs[k]
    if min(abs(f - a), abs(b - f)) <= tol:
        return
    held = lambda x: any(abs(x - g) <= tol for g in keep if g != f)  # noqa: E731
    w = b - a
    if f - a <= snap * w and k > 0 and not held(a):
        segs[k - 1][1] = f
        segs[k][0] = f
        return
    if b - f <= snap * w and k < len(segs) - 1 and not held(b):
        segs[k][1] = f
        segs[k + 1][0] = f
        return
    segs[k:k + 1] = [[a, f, N], [f, b, N]]


def _arc_mesh_moves(mesh, errors, spec, features, todo) -> dict[int, float]:
    """On an arc mesh (every interior breakpoint within corner_tolerance of a located feature,
    as ``coarsen`` builds it): breakpoint index -> feature, for the breakpoints that are not
    exactly on their feature and have a segment above tolerance next to them. ``refine`` moves
    them onto the features and leaves those segments as they are: on such a stiff mesh the
    error next to a junction is that of the junction's position (Bryson-Denham (3, 1, 3):
    0.18 d for a junction off by d), which a higher degree would only paper over."""
    bps = np.asarray(mesh.breakpoints)
    inner = bps[1:-1]
    feats = [f for f in features if f not in todo]
    if not len(inner) or not feats or not all(min(abs(b - f) for f in feats) <= spec.corner_tolerance
                                               for b in inner):
        return {}
    moves = {}
    for f in feats:
        q = 1 + int(np.argmin(np.abs(inner - f)))
        if (abs(bps[q] - f) > 1e-14 and bps[q - 1] < f < bps[q + 1]
                and max(errors[q - 1].error, errors[q].error) > spec.tolerance):
            moves[q] = float(f)
    return moves


def refine(mesh, errors: list[SegmentError], spec, controls=None, features=None) -> Any:
    """The next mesh of one phase (see the module docstring).

    ``features``: located switches and corners (normalised time); each one not already on a
    breakpoint becomes one (moving a close breakpoint, or splitting), and the segment that
    held it is otherwise left to the next iteration's estimate. ``controls`` (per segment,
    s -> control polynomial) is used to locate corners when ``features`` is not given.
    """
    from ..transcribe.mesh import Mesh

    tol, nmin, nmax = spec.tolerance, spec.min_degree, spec.max_degree
    pieces = spec.bracket_pieces
    if features is None:
        features = corners_to_place(mesh, errors, spec, controls)
    todo = misplaced(mesh, features, spec)
    moves = _arc_mesh_moves(mesh, errors, spec, features, todo)
    still = {k for q in moves for k in (q - 1, q)}
    proposals: list[list[list]] = []
    for e in errors:
        k = e.segment
        a, b = float(mesh.breakpoints[k]), float(mesh.breakpoints[k + 1])
        N = mesh.degrees[k]
        holds = [f for f in todo if a < f < b]
        if not (e.error > tol) or holds or k in still:
            proposals.append([[a, b, N]])
            continue
        if e.nonsmooth and not e.smoothed:
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
                edges = [a, *merged, b]
                proposals.append([[x, y, nmin] for x, y in zip(edges, edges[1:])])
                continue
        # smooth (or a switch that cannot be bracketed more finely): p, then h
        ratio = e.error / tol if math.isfinite(e.error) else 1e6
        P = max(1, math.ceil(math.log(ratio) / math.log(max(N, 2))))
        if N + P <= nmax:
            proposals.append([[a, b, N + P]])
        else:
            B = max(math.ceil((N + P) / nmin), 2)
            edges = [a + (b - a) * q / B for q in range(B + 1)]
            proposals.append([[x, y, nmin] for x, y in zip(edges, edges[1:])])
    # at most growth x the segments: the largest errors are split first; a split that does not
    # fit the remaining budget is cut down to it (``_within_budget``), and a segment that gets
    # no new segment at all waits. (It used to be left as it was even when it came first:
    # Bryson-Denham with LG on 2 x 3 touches x <= l at two Gauss points of each segment, so
    # each segment's brackets asked for 5 cuts against a budget of 4 and the 2 x 3 mesh was
    # solved again until max_iterations.)
    budget = max(1, int(spec.growth * mesh.segments) - mesh.segments)
    for k in sorted(range(len(errors)), key=lambda q: -errors[q].error):
        extra = len(proposals[k]) - 1
        if extra <= 0:
            continue
        if extra > budget:
            proposals[k] = _within_budget(proposals[k], budget, mesh.degrees[k])
            extra = len(proposals[k]) - 1
        budget -= extra
    segs = [sg for prop in proposals for sg in prop]
    for q, f in moves.items():   # the segments next to a moved breakpoint were kept: edges exact
        b = float(mesh.breakpoints[q])
        for sg in segs:
            sg[0] = f if sg[0] == b else sg[0]
            sg[1] = f if sg[1] == b else sg[1]
    for f in todo:
        _place(segs, f, spec.snap, features, spec.corner_tolerance)
    segs = [sg for sg in segs if sg[1] > sg[0]]
    bps = [0.0] + [sg[1] for sg in segs]
    bps[-1] = 1.0
    new = Mesh(mesh.scheme_name, np.array(bps), tuple(int(sg[2]) for sg in segs))
    if same_mesh(new, mesh) and (todo or any(e.error > tol for e in errors)):
        # never the same mesh again while the tolerance is unmet: the worst segment is
        # refined regardless of the rules above, or the refinement stops (MeshStalled)
        new = _forced_refinement(mesh, errors, spec, todo)
    return new


class MeshStalled(RuntimeError):
    """``refine`` cannot produce a mesh different from the current one although the
    tolerance is unmet; ``solve_adaptive`` ends with ``mesh_not_converged`` and this message."""


def same_mesh(a, b) -> bool:
    return (a.scheme_name == b.scheme_name and tuple(a.degrees) == tuple(b.degrees)
            and np.array_equal(np.asarray(a.breakpoints), np.asarray(b.breakpoints)))


def _within_budget(prop: list[list], budget: int, degree: int) -> list[list]:
    """A segment's proposal [[a, b, N], ...] cut down to at most ``budget`` new segments:
    ``budget`` of its interior edges, evenly spread over them (a bracketed switch keeps edges on
    either side of it), each piece with the proposal's largest degree; with no budget left,
    the segment unchanged (it waits for the next iteration)."""
    a, b = prop[0][0], prop[-1][1]
    if budget <= 0:
        return [[a, b, degree]]
    inner = [sg[1] for sg in prop[:-1]]
    pick = sorted({inner[min(len(inner) - 1, round((q + 1) * (len(inner) + 1) / (budget + 1)) - 1)]
                   for q in range(budget)})
    N = max(sg[2] for sg in prop)
    edges = [a, *pick, b]
    return [[x, y, N] for x, y in zip(edges, edges[1:])]


def _forced_refinement(mesh, errors, spec, todo):
    """The mesh with its worst segment (largest error) refined: degree raised by one up to
    max_degree, else bisected. Raises MeshStalled when neither is possible."""
    from ..transcribe.mesh import Mesh

    bps = np.asarray(mesh.breakpoints, float)
    worst = max(errors, key=lambda e: e.error) if errors else None
    if worst is None or not (worst.error > spec.tolerance):
        raise MeshStalled(f"located switches/corners {todo} could not be put on breakpoints of mesh "
                          f"{mesh.describe()}")
    k = worst.segment
    degrees = list(mesh.degrees)
    if degrees[k] < spec.max_degree:
        degrees[k] += 1
        return Mesh(mesh.scheme_name, bps.copy(), tuple(degrees))
    a, b = bps[k], bps[k + 1]
    mid = 0.5 * (a + b)
    if not (a < mid < b) or b - a < 1e-12:
        raise MeshStalled(f"segment {k} (s in [{a:.6g}, {b:.6g}]) has error {worst.error:.3e} above "
                          f"tolerance {spec.tolerance:.1e} at max_degree {spec.max_degree} and is too "
                          "short to split")
    degrees[k:k + 1] = [spec.min_degree, spec.min_degree]
    return Mesh(mesh.scheme_name, np.concatenate([bps[:k + 1], [mid], bps[k + 1:]]), tuple(degrees))


# ---------------------------------------------------------------------------------------
# coarsening: merge segments and lower degrees where the error is far below tolerance
# ---------------------------------------------------------------------------------------

def _samples(pb, extra_points: int = 6):
    """Per segment: normalised times and the (clipped) state and control polynomial values on
    N + extra_points Lobatto points."""
    from ..transcribe.nodes import legendre_gauss_lobatto

    ph, lay = pb.phase, pb.layout
    X, U, _, _ = _solution_arrays(pb)
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    out = []
    for k in range(lay.mesh.segments):
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        tau = np.asarray(legendre_gauss_lobatto(lay.mesh.degrees[k] + extra_points)[0])
        xs, us = _seg_polys(lay, k, X, U)
        out.append((a + (tau + 1) * (b - a) / 2, xs(tau), np.clip(us(tau), ulo, uhi)))
    xscale = 1.0 + np.max(np.abs(X), axis=0)
    uscale = 1.0 + (np.max(np.abs(U), axis=0) if U.size else np.zeros(U.shape[1]))
    return out, xscale, uscale


def _fit_degree(samples, xscale, uscale, lowest: int, highest: int, limit: float,
                shift: int = 0) -> int | None:
    """Smallest degree n in [lowest, highest] whose Legendre least-squares fit of degree
    n - ``shift`` to the states (over the union of the samples) is within ``limit`` (relative,
    as the error estimate), or None. ``shift`` is the scheme degree minus the degree of its
    state polynomial: 0 for LG, LGR, LGR-start (n collocation points, n + 1 support points),
    1 for LGL (n points, state polynomial of degree n - 1: a degree-2 LGL segment holds a
    straight line; without the shift coarsening gave the two-phase double integrator LGL
    segments of degree 2 for its parabolas, missed the tolerance, refined, and coarsened to
    the same mesh again every other iteration). The controls are not fitted: on a constrained arc the collocated
    control wiggles at the 1e-5 level without moving the state (Bryson-Denham), and a jump
    or kink of the control shows in the state's fit; the next solve's estimate checks."""
    from numpy.polynomial import legendre as leg

    s = np.concatenate([q[0] for q in samples])
    Xs = np.vstack([q[1] for q in samples]) / xscale
    a, b = s.min(), s.max()
    z = 2 * (s - a) / (b - a) - 1
    for n in range(lowest, highest + 1):
        p = n - shift
        if p < 0:
            continue
        if len(z) <= p + 1:
            return None
        V = leg.legvander(z, p)
        res = Xs - V @ np.linalg.lstsq(V, Xs, rcond=None)[0]
        if np.max(np.abs(res), initial=0.0) > limit:
            continue
        return n
    return None


def coarsen(pb, errors, spec, features) -> Any:
    """A smaller mesh of one phase that should still meet the tolerance, or the same mesh.

    Liu, Hager & Rao (2015) reduce the mesh where the error is far below the tolerance; here
    (our variant) consecutive segments are merged, left to right, while one Legendre
    polynomial of degree <= max_degree fits the solution over the merged interval to within
    ``coarsen_margin * tolerance``, and every segment gets the smallest such degree (down to
    ``lowest_degree``). Breakpoints on located switches/corners are kept. The next solve
    checks the result with the error estimate.
    """
    from ..transcribe.mesh import Mesh

    mesh = pb.layout.mesh
    samples, xs, us = _samples(pb)
    limit = spec.coarsen_margin * spec.tolerance
    lowest = max(spec.lowest_degree, 2 if mesh.scheme_name == "LGL" else 1)
    shift = 1 if mesh.scheme_name == "LGL" else 0
    bps = np.asarray(mesh.breakpoints)
    keep = [any(abs(bps[k] - f) <= spec.corner_tolerance for f in features) for k in range(len(bps))]
    K = mesh.segments
    # each segment on its own: the smallest degree that fits (segments above tolerance keep theirs)
    own = []
    for k in range(K):
        n = (_fit_degree(samples[k:k + 1], xs, us, lowest, mesh.degrees[k], limit, shift)
             if errors[k].error <= spec.tolerance else None)
        own.append((n if n is not None else mesh.degrees[k], n is not None))
    groups = []
    i = 0
    while i < K:
        best = (i, i, own[i][0])
        j = i
        while (j + 1 < K and own[best[1] - 0][1] and own[j + 1][1] and not keep[j + 1]):
            m = _fit_degree(samples[i:j + 2], xs, us, lowest, spec.max_degree, limit, shift)
            # merged only when it has fewer nodes than the group and the segment kept apart
            if m is None or m >= best[2] + own[j + 1][0]:
                break
            j += 1
            best = (i, j, m)
        groups.append(best)
        i = best[1] + 1
    new_bps = [0.0] + [float(bps[g[1] + 1]) for g in groups]
    # a breakpoint within corner_tolerance of a located feature is put exactly on it
    for q in range(1, len(new_bps) - 1):
        near = [f for f in features if abs(f - new_bps[q]) <= spec.corner_tolerance]
        if near:
            f = min(near, key=lambda f: abs(f - new_bps[q]))
            if new_bps[q - 1] < f < new_bps[q + 1]:
                new_bps[q] = f
    merged = Mesh(mesh.scheme_name, np.array(new_bps), tuple(int(g[2]) for g in groups))
    arcs = _arc_mesh(pb, spec, features, samples, xs, us, limit, lowest)
    nx, nu = len(pb.phase.states), len(pb.phase.controls)
    if arcs is not None and _nlp_size(arcs, nx, nu) < _nlp_size(merged, nx, nu):
        return arcs
    return merged


def _boundary_arc(pb, a: float, b: float, pts, xscale, threshold: float):
    """States on the sample points ``pts`` (normalised time in [a, b]) of the trajectory that
    starts from the collocated state at a and follows a state bound's boundary control
    (``_boundary_controls``), when it stays within ``threshold`` (relative, as the error
    estimate) of the collocated states on the arc's nodes and within the control's bounds;
    else None. Phases with free parameters are not tried."""
    from scipy.integrate import solve_ivp

    ph, lay = pb.phase, pb.layout
    X, U, t0, tf = _solution_arrays(pb)
    f, _ = _phase_functions(ph, [])
    inside = (lay.s_state >= a) & (lay.s_state <= b)
    ta, tb = t0 + (tf - t0) * a, t0 + (tf - t0) * b
    ts = np.clip(t0 + (tf - t0) * np.concatenate([lay.s_state[inside], pts]), min(ta, tb), max(ta, tb))
    t_eval = np.unique(ts)
    nu = len(ph.controls)
    for _q, i, ub in _boundary_controls(ph, []).values():
        lo, hi = ph.bounds_of(ph.controls[i])

        def control(x, t, i=i, ub=ub):
            u = np.zeros(nu)
            u[i] = float(ub(*x, t))
            return u

        def rhs(t, x, control=control):
            return np.asarray(f(*x, *control(x, t), t), float).reshape(-1)

        x0 = _state_at(lay, X, U, a)
        try:
            with np.errstate(all="ignore"):
                sol = solve_ivp(rhs, (ta, tb), x0, method="DOP853", t_eval=t_eval,
                                rtol=1e-11, atol=1e-11 * xscale)
        except Exception:
            continue
        if not sol.success or sol.y.shape[1] != len(t_eval):
            continue
        y = sol.y.T[np.searchsorted(t_eval, ts)]
        n = int(inside.sum())
        us_ = np.array([control(y[l], ts[l])[i] for l in range(len(ts))])
        if (np.max(np.abs(y[:n] - X[inside]) / xscale, initial=0.0) <= threshold
                and np.all(us_ >= lo - 1e-9) and np.all(us_ <= hi + 1e-9)):
            return y[n:]
    return None


def _arc_mesh(pb, spec, features, samples, xs, us, limit, lowest):
    """The arc mesh, or None: one segment per arc between located features (switches,
    junctions), of the smallest degree whose polynomial fits the states over the arc within
    ``limit`` (as ``coarsen``), leaving out the segments next to the features, where the
    discrete solution smears the feature. A state-constrained arc is recognised by the
    trajectory of its boundary control (``_boundary_arc``, within sqrt(tolerance) of the
    collocated states, a loose test: the arc mesh is a trial that the next solve checks), and
    its degree is fitted to that trajectory rather than to the discrete solution, which
    wiggles there at the level of the junctions' position error (Bryson-Denham: x up to 6e-7
    below its bound between the corners with the corners 1e-5 off). None when an arc needs
    more than ``max_degree``. ``refine`` then moves the arc mesh's breakpoints onto the
    re-located features (``_arc_mesh_moves``)."""
    from ..transcribe.mesh import Mesh

    lay = pb.layout
    shift = 1 if lay.mesh.scheme_name == "LGL" else 0
    bps = np.asarray(lay.mesh.breakpoints)
    fs = []
    for f in sorted(features):
        if spec.corner_tolerance < f < 1 - spec.corner_tolerance and (not fs or f - fs[-1] > spec.corner_tolerance):
            fs.append(float(f))
    if not fs:
        return None
    near = set()
    for f in fs:
        q = int(np.argmin(np.abs(bps - f)))
        near |= {q - 1, q}
    edges = [0.0, *fs, 1.0]
    seg_of = np.concatenate([np.full(len(q[0]), k) for k, q in enumerate(samples)])
    s_all = np.concatenate([q[0] for q in samples])
    x_all = np.vstack([q[1] for q in samples])
    u_all = np.vstack([q[2] for q in samples])
    degrees = []
    for a, b in zip(edges, edges[1:]):
        m = (s_all >= a) & (s_all <= b)
        away = m & ~np.isin(seg_of, list(near))
        if away.sum() > 2:
            m = away
        n = _fit_degree([(s_all[m], x_all[m], u_all[m])], xs, us, lowest, spec.max_degree, limit, shift)
        if n is None or n > spec.min_degree:
            y = _boundary_arc(pb, a, b, s_all[m], xs, math.sqrt(spec.tolerance))
            if y is not None:
                nb = _fit_degree([(s_all[m], y, u_all[m])], xs, us, lowest, spec.max_degree, limit, shift)
                n = nb if nb is not None and (n is None or nb < n) else n
        if n is None:
            return None
        degrees.append(n)
    return Mesh(lay.mesh.scheme_name, np.array(edges), tuple(degrees))


def _nlp_size(mesh, nx: int, nu: int) -> int:
    """Unknowns of one phase on ``mesh`` (states on state nodes + controls), for comparisons."""
    from ..transcribe.mesh import Layout

    lay = Layout.of(mesh)
    return lay.n_state_nodes * nx + lay.n_colloc * nu


# ---------------------------------------------------------------------------------------
# optional regularisation of chattering (singular) arcs
# ---------------------------------------------------------------------------------------

def chattering_segments(pb) -> list[tuple[float, float]]:
    """Segments (normalised time) on which a control zigzags from node to node (``_zigzag`` on
    the segment's collocation points and the nearest one on either side): the discrete
    solution of a singular arc, where the control is weakly determined and the NLP chatters."""
    lay = pb.layout
    U = _solution_arrays(pb)[1]
    bps = lay.mesh.breakpoints
    # steps below 1e-3 of the control's range are solver noise (a bang arc 1e-8 inside its bound)
    span = []
    for j, c in enumerate(pb.phase.controls):
        lo, hi = pb.phase.bounds_of(c)
        span.append(1e-3 * ((hi - lo) if math.isfinite(hi - lo) else 1.0 + np.max(np.abs(U[:, j]))))
    out = []
    for k in range(lay.mesh.segments):
        nodes = list(lay.colloc[k])
        if k > 0:
            nodes = [lay.colloc[k - 1][-1]] + nodes
        if k + 1 < lay.mesh.segments:
            nodes = nodes + [lay.colloc[k + 1][0]]
        if len(nodes) >= 4 and any(_zigzag(U[nodes, j], span[j]) for j in range(U.shape[1])):
            out.append((float(bps[k]), float(bps[k + 1])))
    return out


def _merge_intervals(old: list, new: list) -> list:
    out = []
    for a, b in sorted([tuple(x) for x in old] + [tuple(x) for x in new]):
        if out and a <= out[-1][1] + 1e-12:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def regularise(tr, regions: dict, weight: float):
    """Add weight * sum over consecutive collocation points inside ``regions`` (per phase,
    normalised-time intervals) of (u_{i+1} - u_i)^2 / (s_{i+1} - s_i) -- a quadrature of
    weight * int (du/ds)^2 ds over the detected chattering arcs -- to the objective (with the
    sign that penalises it). Returns the Pyomo expression of the added term, or None.
    The solved objective is reported without it (``solve_adaptive``)."""
    import pyomo.core as pyo

    if not weight or not any(regions.values()):
        return None
    terms = []
    for pb in tr.phases:
        iv = regions.get(pb.phase.name) or []
        lay, b = pb.layout, pb.block
        sc = lay.s_colloc
        inside = [any(a <= x <= c for a, c in iv) for x in sc]
        nu = len(pb.phase.controls)
        for i in range(lay.n_colloc - 1):
            if inside[i] and inside[i + 1] and sc[i + 1] > sc[i]:
                for j in range(nu):
                    terms.append((b.U[i + 1, j] - b.U[i, j]) ** 2 / float(sc[i + 1] - sc[i]))
    if not terms:
        return None
    m = tr.model
    m.mesh_regularisation = pyo.Expression(expr=weight * sum(terms))
    sign = 1.0 if m.objective.sense == pyo.minimize else -1.0
    m.objective.expr = m.objective.expr + sign * m.mesh_regularisation
    return m.mesh_regularisation


def limit_junction_controls(tr, features: dict | None = None, tol: float = 0.0) -> int:
    """At every phase junction, constrain a control collocated at the phase's end point to the
    one-sided limit of its segment's interior control polynomial (``junction_control: limit``).

    Which points: tau = +1 of the last segment of a phase that another phase follows (LGR, LGL)
    and tau = -1 of the first segment of a phase that follows another (LGR-start, LGL); the
    phases are taken in their order in the problem. The constraint is u_end = sum_i l_i(+-1) u_i
    over the segment's other collocation points (Lagrange basis l_i through them); segments with
    no other collocation point are left free. Why (measured, docs/mesh-refinement.md "Two
    phases"): in the continuous problem the control at a phase junction acts on a single
    instant, where it generally jumps; in the NLP it acts through its quadrature weight w_N h/2,
    and on the two-phase double integrator (LGR) the NLP drives it to the other bound, so that
    the segment's control polynomial overshoots the bound between the nodes (1.2 on 2 x 3) and
    the collocated state goes faster than any admissible control allows (tf = 1.99918 < 2). The
    error estimate rightly sees that (1.7e-2), but it only falls with the width of the phase's
    end segment, so refinement does not reach 1e-8 in 8 iterations. With the end control tied
    to its interior limit, the discrete solution is the exact one.

    ``features`` (per phase, normalised times of located switches/corners, as
    ``locate_features`` returns them) with ``tol``: for LGL also at every interior breakpoint
    within ``tol`` of one, both controls there (tau = +1 of the segment before, tau = -1 of the
    segment after: two control values at one instant, each collocated) are tied to their own
    segment's interior limit. Measured on the single-phase double integrator (LGL, 2 x 3): the
    NLP puts u = 0 at both copies of the breakpoint t = 1 (u = (1, 1, 0 | 0, -1, -1)), the
    control polynomials overshoot to 1.12 between the nodes, and the estimate (3.0e-2, then
    falling only with the width of the two segments) never reached 1e-9. LGR and LGR-start
    collocate one control at such a breakpoint and converged there without it, so they are
    left as they were. Returns the number of constraints added."""
    import pyomo.core as pyo

    from ..transcribe.nodes import lagrange_matrix

    added = 0
    n_ph = len(tr.phases)
    for i, pb in enumerate(tr.phases):
        lay, b = pb.layout, pb.block
        nu = len(pb.phase.controls)
        ends = []
        if i < n_ph - 1:
            ends.append(("end", lay.mesh.segments - 1, 1.0))
        if i > 0:
            ends.append(("start", 0, -1.0))
        if lay.mesh.scheme_name == "LGL" and features:
            bps = np.asarray(lay.mesh.breakpoints)
            for q in range(1, len(bps) - 1):
                if any(abs(bps[q] - f) <= tol for f in features.get(pb.phase.name, [])):
                    ends.append((f"end_{q - 1}", q - 1, 1.0))
                    ends.append((f"start_{q}", q, -1.0))
        for which, k, tau in ends:
            col = np.asarray(lay.mesh.scheme(k).colloc, float)
            at = np.flatnonzero(np.abs(col - tau) < 1e-12)
            if not len(at) or len(col) < 2:
                continue
            others = [q for q in range(len(col)) if q != at[0]]
            coef = lagrange_matrix(col[others], np.array([tau]))[0]
            nodes = np.asarray(lay.colloc[k])
            cl = pyo.ConstraintList()
            b.add_component(f"mesh_junction_control_{which}", cl)
            for j in range(nu):
                cl.add(b.U[int(nodes[at[0]]), j]
                       == sum(float(c) * b.U[int(nodes[q]), j] for c, q in zip(coef, others)))
                added += 1
    return added


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
    import pyomo.core as pyo

    from ..run import _result
    from ..transcribe.guess import make_guess
    from ..transcribe.pseudospectral import build
    from . import ipopt
    from . import warm_start as ws

    ipopt.check_available()
    problem, spec = file.problem, file.method.mesh
    meshes = initial_meshes(file)
    previous: dict[str, PhaseTrajectory] = {}
    snapshot = None      # the previous mesh's solution, multipliers included (warm_start.py)
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
    stalled = ""         # why the refinement stopped before max_iterations without converging
    last = None
    converged = []       # iterations within tolerance with every located switch on a breakpoint
    coarsening = False   # the current mesh came from coarsening a converged one
    junction_memory: dict = {}   # per phase: the previous junction estimates (locate_junctions' secant)
    chatter: dict = {}   # per phase: the chattering arcs found so far (regularise)
    reg_weight = spec.regularise
    located: dict = {}   # per phase: the features located on the previous mesh (limit_junction_controls)
    for it in range(1, spec.max_iterations + 1):
        t_iter = time.perf_counter()
        with timer.measure("build"):
            guesses = {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=seed if it == 1 else None)
                       for ph in problem.phases}
            tr = build(problem, meshes, guesses)
            reg = regularise(tr, chatter, reg_weight) if spec.regularise else None
            if spec.junction_control == "limit":
                limit_junction_controls(tr, located, spec.corner_tolerance)
            ws.prepare(tr.model)
            mult = ws.apply(snapshot, tr) if snapshot is not None else None
        with timer.measure("solve"):
            bar = ipopt.Progress(progress, f"[mesh {it}]")
            info = ipopt.solve(tr.model, options, verbose=verbose, progress=bar, multipliers=mult,
                               transcription=tr)
        reg_value = None
        if reg is not None and info.objective is not None:
            # the objective of the problem itself: the regularisation term taken out
            reg_value = float(pyo.value(reg))
            info.objective += reg_value if tr.model.objective.sense == pyo.maximize else -reg_value
        with timer.measure("mesh"):
            params = {s: float(pyo.value(tr.scalars[s])) for s in problem.free_parameters}
            errors = {pb.phase.name: estimate_errors(pb, params, active_tol=max(1e-9, 0.1 * spec.tolerance),
                                                     smooth_above=spec.tolerance if spec.smooth_control else None)
                      if info.status in GOOD else []
                      for pb in tr.phases}
        allerr = [e for es in errors.values() for e in es]
        worst = max(allerr, key=lambda e: e.error) if allerr else None
        max_err = worst.error if worst else math.inf
        elapsed = time.perf_counter() - t_iter
        rec = {"iteration": it, "status": info.status, "objective": info.objective,
               "ipopt_iterations": info.iterations, "nlp": dict(info.nlp), "time_s": round(elapsed, 4),
               "warm_start": "multipliers" if mult is not None else ("primal" if it > 1 else "none"),
               "max_error": max_err,
               "where": ({"phase": worst.phase, "segment": worst.segment, "t": [worst.t_start, worst.t_end],
                          "state": worst.state} if worst else None),
               "meshes": {k: m.describe() for k, m in meshes.items()}}
        if reg is not None:
            rec["regularisation"] = {"weight": reg_weight, "value": reg_value,
                                     "arcs": {k: [list(x) for x in v] for k, v in chatter.items()}}
        if spec.regularise and info.status in GOOD:
            for pb in tr.phases:
                chatter[pb.phase.name] = _merge_intervals(chatter.get(pb.phase.name, []), chattering_segments(pb))
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
        with timer.measure("mesh"):
            features = {}
            for pb in tr.phases:
                try:
                    features[pb.phase.name] = locate_features(tr, pb, errors[pb.phase.name], params, spec,
                                                              _control_polys(pb),
                                                              memory=junction_memory.setdefault(pb.phase.name, {}))
                except Exception as exc:  # locating is an aid; the estimate still decides
                    _say(progress, f"mesh {it}: switch location failed in phase {pb.phase.name}: {exc}")
                    features[pb.phase.name] = []
        off = {k: misplaced(meshes[k], f, spec) for k, f in features.items()}
        located = features
        rec["features"] = features
        rec["features_off_breakpoints"] = off
        if max_err <= spec.tolerance and not any(off.values()):
            converged.append(last)
            rec["converged"] = True
            smaller = None
            if spec.coarsen and it < spec.max_iterations:
                with timer.measure("mesh"):
                    cand = {pb.phase.name: coarsen(pb, errors[pb.phase.name], spec, features[pb.phase.name])
                            for pb in tr.phases}
                size = lambda ms: sum(_nlp_size(ms[pb.phase.name], len(pb.phase.states),  # noqa: E731
                                                len(pb.phase.controls)) for pb in tr.phases)
                if size(cand) < size(meshes):
                    smaller = cand
            if smaller is None:
                break
            coarsening = True
            previous = {pb.phase.name: _dense_trajectory(pb) for pb in tr.phases}
            snapshot = ws.take(tr) if spec.warm_start == "multipliers" else None
            meshes = smaller
            continue
        if coarsening:
            # the coarsened mesh missed the tolerance: refine it like any other mesh (the
            # smallest converged mesh so far is kept for the end)
            rec["coarsening_rejected"] = True
            coarsening = False
        if it == spec.max_iterations:
            break
        previous = {pb.phase.name: _dense_trajectory(pb) for pb in tr.phases}
        snapshot = ws.take(tr) if spec.warm_start == "multipliers" else None
        try:
            new_meshes = {pb.phase.name: refine(meshes[pb.phase.name], errors[pb.phase.name], spec,
                                                features=features[pb.phase.name]) for pb in tr.phases}
        except MeshStalled as exc:
            stalled = f"mesh iteration {it}: refinement stalled: {exc}"
            rec["stalled"] = str(exc)
            break
        if all(same_mesh(new_meshes[k], meshes[k]) for k in meshes):
            # refine() changes every phase that misses the tolerance; this is a last guard
            stalled = (f"mesh iteration {it}: refinement returned the same mesh while the tolerance "
                       f"{spec.tolerance:.1e} is unmet (largest error {max_err:.3e})")
            rec["stalled"] = stalled
            break
        meshes = new_meshes
    if status is None:
        if converged:
            chosen = min(converged, key=lambda c: (c[3].nlp.get("variables", 0), c[0]))
            status = "optimal" if chosen[3].status == "optimal" else chosen[3].status
            message = (f"mesh converged: iteration {chosen[1]} of {len(history)} is the smallest mesh within "
                       f"tolerance {spec.tolerance:.1e} (largest estimated error {chosen[0]:.3e}, "
                       f"{chosen[3].nlp.get('variables', 0)} NLP variables)")
            rejected = [h["iteration"] for h in history if h.get("coarsening_rejected")]
            if rejected:
                message += f"; coarsened meshes that missed it: iteration(s) {rejected}"
        else:
            status = "mesh_not_converged"
            chosen = best
    else:
        chosen = last
    max_err, it_c, tr_c, info_c, meshes_c, errors_c = chosen
    if status == "mesh_not_converged":
        above = [e for es in errors_c.values() for e in es if e.error > spec.tolerance]
        worst = max(above, key=lambda e: e.error) if above else None
        off_c = history[it_c - 1].get("features_off_breakpoints", {})
        where = (f"in phase '{worst.phase}' segment {worst.segment} (t in [{worst.t_start:.6g}, "
                 f"{worst.t_end:.6g}], state {worst.state}); {len(above)} segment(s) above tolerance"
                 if worst else f"within tolerance but located switches/corners {off_c} are off the breakpoints")
        message = (f"mesh refinement did not reach the tolerance {spec.tolerance:.1e} in "
                   f"{len(history)} of {spec.max_iterations} iterations: best mesh (iteration {it_c}) has "
                   f"largest estimated error {max_err:.3e} {where}. "
                   + (f"Stopped early because {stalled}." if stalled else
                      "Raise max_iterations or max_degree, or loosen the tolerance."))
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
