"""Per-segment error estimate of a solved phase (see the package docstring)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .segments import activity, phase_functions_all, seg_polys, solution_arrays, zigzag


@dataclass
class SegmentError:
    phase: str
    segment: int
    t_start: float
    t_end: float
    degree: int
    error: float                 # max(relative state discrepancy, violation, integral error)
    discrepancy: float
    violation: float
    state: str                   # state (or integral) with the largest discrepancy
    nonsmooth: bool
    switches: list[tuple[float, float]] = field(default_factory=list)   # brackets in s
    smoothed: bool = False       # the error is the one with the smoothed control (see estimate_errors)
    integral: float = 0.0        # largest relative error of an integral's quadrature (see estimate_errors)
    # the segment flown from its own start: the state at its end and each integral's increment
    # (``segment_ends``: the terminal conditions judged piece by piece)
    x_end: np.ndarray | None = None
    q_increment: np.ndarray | None = None
    control_switch: bool = False  # a control's activity changes in ``switches`` (not only states' or paths')
    # a state bound or a path constraint starts or stops binding (``binding_nodes``) between
    # two collocation nodes inside the segment (neither at its ends): a junction no
    # breakpoint holds, which the estimate does not see where the states integrate the
    # controls exactly (x' = u: unseen27 FC2, an obstacle's exit 0.045 inside a segment, J
    # 1.65e-4 high with every error below 1e-8)
    inner_junctions: list[tuple[float, float]] = field(default_factory=list)   # their brackets in s

    @property
    def inner_junction(self) -> bool:
        return bool(self.inner_junctions)


# a state bound or an inequality path constraint binds at a collocation node where its
# multiplier is above this share of the largest one of the phase (``binding_nodes``)
BINDING_SHARE = 1e-6


def binding_nodes(pb) -> np.ndarray | None:
    """(collocation nodes, constraints) booleans: where each state bound and inequality path
    constraint binds, by its multiplier (not by the distance to its bound: a state leaving
    its bound tangentially, Bryson-Denham's x <= l, stays within any distance of it for a
    while after the junction). None when the solve left no multipliers."""
    m = pb.block.model()
    dual = m.component("dual")
    zl, zu = m.component("ipopt_zL_out"), m.component("ipopt_zU_out")
    if dual is None or zl is None or zu is None or not len(dual):
        return None
    lay, ph, b = pb.layout, pb.phase, pb.block
    C = lay.n_colloc
    cols = []
    state_of = np.empty(C, int)
    for k in range(lay.mesh.segments):
        state_of[lay.colloc[k]] = lay.colloc_state[k]
    for j, s in enumerate(ph.states):
        lo, hi = ph.bounds_of(s)
        if math.isfinite(lo) or math.isfinite(hi):
            cols.append([abs(float(zl.get(b.X[n, j], 0.0) or 0.0)) + abs(float(zu.get(b.X[n, j], 0.0) or 0.0))
                         for n in state_of])
    npath = len(ph.path)
    if npath and hasattr(b, "path"):
        for q, c in enumerate(ph.path):
            if not c.is_equality:
                cols.append([abs(float(dual.get(b.path[cn * npath + q], 0.0) or 0.0)) for cn in range(C)])
    if not cols:
        return np.zeros((C, 0), bool)
    mu = np.array(cols, float).T
    return mu > BINDING_SHARE * max(float(np.max(mu)), 1e-300)


def flight_rtol(tolerance: float) -> float:
    """The integrator tolerance of the estimate's and the terminal check's flights for a mesh
    tolerance: four orders below what they measure, within [1e-12, 1e-10]. At 1e-12 for
    every tolerance these flights were a third of a mesh run (hang glider, tolerance 1e-6:
    DOP853's steps grow as rtol^(-1/8))."""
    return min(1e-10, max(1e-12, 1e-4 * tolerance))


_FLIGHTS: dict = {}      # id(phase) -> (phase, free parameter names, PhaseFunctions): one per run


def flight_functions(pb, params: dict, X, U, t0: float, tf: float):
    """What every flight of the estimate and of the terminal check integrates: the phase's
    dynamics and integrands at one point (the verification's ``PhaseFunctions``, plain
    floats through ``math``, its code cached on disk; the free parameters bound as
    arguments, so the mesh iterations share it), and the collocated controls clipped to
    their bounds, each segment's as straight-line Python (``SegmentPolynomials``). About a
    tenth of the cost per right-hand side of a lambdified NumPy function and a barycentric
    control at one point, which were most of the mesh stage. ``X, U, t0, tf``: the phase's
    ``solution_arrays``."""
    from ...verify.functions import PhaseFunctions
    from ...verify.interpolate import SegmentPolynomials

    ph, lay = pb.phase, pb.layout
    free = tuple(sorted(str(s) for s in params))
    hit = _FLIGHTS.get(id(ph))
    if hit is None or hit[0] is not ph or hit[1] != free:
        if len(_FLIGHTS) > 64:     # a long study builds many problems: keep the cache small
            _FLIGHTS.clear()
        hit = _FLIGHTS[id(ph)] = (ph, free, PhaseFunctions(ph, {}, ph.integrals, free=free))
    funcs = hit[2].bind({str(s): v for s, v in params.items()})
    mesh = lay.mesh
    span = [t0 + (tf - t0) * lay.s_colloc[lay.colloc[k]] for k in range(mesh.segments)]
    uf = SegmentPolynomials.of_segments(t0 + (tf - t0) * np.asarray(mesh.breakpoints, float), span,
                                        [U[lay.colloc[k]] for k in range(mesh.segments)],
                                        [ph.bounds_of(c) for c in ph.controls])
    return funcs, uf


def _fly(funcs, uf, ta: float, tb: float, y0, t_eval, rtol: float, atol):
    """DOP853 over one segment with its clipped control, stepping to the control's kinks."""
    from ...verify.integrate import dop853_split

    u_of = uf.piece(0.5 * (ta + tb))
    return dop853_split(lambda tt, y: funcs.augmented_point(tt, y, u_of(tt)), ta, tb, y0, t_eval, rtol, atol,
                        uf.kinks(ta, tb))


BATCH_MIN = 8     # segments from which the estimate's flights run side by side


def _fly_segments(funcs, uf, ta, tb, starts, taus, rtol: float, atol) -> list:
    """Every segment k flown from ``starts[k]`` over [ta[k], tb[k]]: its states and integrals
    at the points ``taus[k]`` (in [-1, 1]) as (w, len), None where the flight failed. The
    segments whose clipped control has no kink run side by side (``dop853.solve_ensemble``:
    each its own steps and error norm, the right-hand side of all in one vectorised call;
    one by one, DOP853's stepping in Python cost as much as the right-hand side); the rest,
    and all of them below BATCH_MIN, one by one, stepping to their kinks."""
    from ...verify import dop853
    from ...verify.integrate import FIRST_STEP_SHARE

    K = len(ta)
    h = tb - ta
    out: list = [None] * K
    batch = [k for k in range(K) if h[k] > 0 and not uf.kinks(ta[k], tb[k])]
    if len(batch) < BATCH_MIN:
        batch = []
    if batch:
        sel = np.array(batch)
        pos_k = {k: np.clip((np.asarray(taus[k], float) + 1.0) / 2.0, 0.0, 1.0) for k in batch}
        positions = np.unique(np.concatenate(list(pos_k.values())))
        a, hb = ta[sel], h[sel]
        inside = np.nextafter(tb[sel], -np.inf)    # each segment keeps its own control up to its end

        def rhs(idx, sv, Y):
            tt = np.minimum(a[idx] + sv * hb[idx], inside[idx])
            return funcs.augmented(tt, Y, uf.at(tt)) * hb[idx, None]

        with np.errstate(all="ignore"):
            sol = dop853.solve_ensemble(rhs, starts[sel], positions, rtol, atol, max_first_step=FIRST_STEP_SHARE)
        if sol.success:
            for j, k in enumerate(batch):
                y = sol.y[np.searchsorted(positions, pos_k[k]), j].T
                out[k] = y if np.all(np.isfinite(y)) else None
        else:
            batch = []
    for k in set(range(K)) - set(batch):
        if not h[k] > 0:
            continue
        t_eval = np.clip(ta[k] + (np.asarray(taus[k], float) + 1.0) * h[k] / 2.0, ta[k], tb[k])
        sol = _fly(funcs, uf, ta[k], tb[k], starts[k], t_eval, rtol, atol)
        if sol.success and sol.y.shape[1] == len(t_eval):
            out[k] = sol.y
    return out


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
    from ...verify import dop853

    from ...transcribe.nodes import legendre_gauss_lobatto

    ph, lay = pb.phase, pb.layout
    free_syms = sorted(params, key=str)
    pvals = [params[s] for s in free_syms]
    f, g, _ = phase_functions_all(ph, free_syms)
    X, U, t0, tf = solution_arrays(pb)
    nx, nu = X.shape[1], U.shape[1]
    scale = 1.0 + np.max(np.abs(X), axis=0)
    quad_k = segment_quadratures(pb, params)          # (K, nq): the NLP's quadrature per segment
    nq = quad_k.shape[1]
    # an integral's error against its own size, as J's (verify/objective_size.py): |I| plus its
    # pieces' size up to 1. Against 1 + |I| an integral of 1e-8 was estimated absolutely: a
    # coarsened mesh 12 % off in it was "within" 1e-8 (unseen34's corner problem, cost x 1e-8)
    scale_q = (np.max(np.abs(np.cumsum(quad_k, axis=0)), axis=0)
               + np.maximum(np.minimum(1.0, np.sum(np.abs(quad_k), axis=0)), 1e-12)) if nq else np.zeros(0)
    names_q = [f"integral({e})" for e in ph.integrals.values()]
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    xlo = np.array([ph.bounds_of(s)[0] for s in ph.states])
    xhi = np.array([ph.bounds_of(s)[1] for s in ph.states])
    mesh = lay.mesh
    funcs, uf = flight_functions(pb, params, X, U, t0, tf)
    # only where the states integrate the controls exactly (no state in any right-hand side):
    # elsewhere the estimate sees a junction inside a segment in the states' error
    binding = binding_nodes(pb) if not (set(ph.states) & set().union(
        *(sp.sympify(e).free_symbols for e in ph.rhs()))) else None
    K = mesh.segments
    bps = np.asarray(mesh.breakpoints, float)
    ta_all, tb_all = t0 + (tf - t0) * bps[:-1], t0 + (tf - t0) * bps[1:]
    taus = [np.asarray(legendre_gauss_lobatto(mesh.scheme(k).degree + extra_points)[0]) for k in range(K)]
    polys = [seg_polys(lay, k, X, U) for k in range(K)]
    x_polys = [polys[k][0](taus[k]) for k in range(K)]
    # the integrals ride along from 0: their increment over the segment against the NLP's
    # quadrature of it (a control that zigzags between the nodes can make the quadrature of
    # sqrt(1 + u^2) or |u| far from its integral: hanging chain, L1 costs)
    flights = _fly_segments(funcs, uf, ta_all, tb_all,
                            np.array([np.concatenate([x_polys[k][0], np.zeros(nq)]) for k in range(K)]),
                            taus, rtol, rtol * np.concatenate([scale, scale_q]))
    out = []
    for k in range(K):
        sc = mesh.scheme(k)
        ta, tb = ta_all[k], tb_all[k]
        xs, us = polys[k]
        h = tb - ta
        tau_f = taus[k]
        t_f = np.clip(ta + (tau_f + 1.0) * h / 2.0, min(ta, tb), max(ta, tb))
        x_poly = x_polys[k]
        x_start = x_poly[0]
        q_err = np.zeros(nq)
        q_inc = np.array(quad_k[k], float) if nq else np.zeros(0)
        if h > 0:
            y = flights[k]
            x_int = y[:nx].T if y is not None else np.full_like(x_poly, np.nan)
            if nq:
                q_inc = y[nx:, -1] if y is not None else np.full(nq, np.nan)
                q_err = np.abs(q_inc - quad_k[k]) / scale_q if y is not None else np.full(nq, np.inf)
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
        inside = all(not activity(U[near, j], ulo[j], uhi[j], 1e-6).any() or zigzag(U[near, j])
                     for j in range(nu))
        if smooth_above is not None and disc > smooth_above and h > 0 and nu and inside:
            usm = _smoothed_control(lay, k, U, ulo, uhi, t0, tf)
            sol2 = dop853.solve(lambda t, x: np.asarray(f(*x, *usm(t), t, *pvals), float).reshape(-1),
                                (ta, tb), x_start, t_f, rtol, rtol * scale)
            if sol2.success and sol2.y.shape[1] == len(t_f):
                rel2 = np.abs(sol2.y.T - x_poly) / scale
                if np.isfinite(rel2).all() and float(np.max(rel2)) < disc:
                    x_int, rel, disc, smoothed = sol2.y.T, rel2, float(np.max(rel2)), True
        # a flight that left the numbers names the first state it lost (unseen56 F2: "state )")
        which = (ph.states[int(np.nanargmax(np.nanmax(rel, axis=0)))].name if np.isfinite(rel).any() else
                 f"{ph.states[int(np.flatnonzero(~np.isfinite(rel).all(axis=0))[0])].name} (not finite)"
                 if rel.size and not np.isfinite(rel).all() else "")
        integral_err = float(np.max(q_err)) if nq else 0.0
        if nq and not (integral_err <= disc):
            which = names_q[int(np.argmax(np.where(np.isfinite(q_err), q_err, np.inf)))]
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
            act.append(activity(Uc[:, j], ulo[j], uhi[j], active_tol))
        for j in range(nx):
            if math.isfinite(xlo[j]) or math.isfinite(xhi[j]):
                act.append(activity(Xc[:, j], xlo[j], xhi[j], active_tol, span=float(np.ptp(X[:, j]))))
        if g is not None:
            tc = t0 + (tf - t0) * s_nodes
            gv = np.array([np.asarray(g(*Xc[i], *Uc[i], tc[i], *pvals), float).reshape(-1)
                           for i in range(len(tc))])
            for q, c in enumerate(ph.path):
                if not c.is_equality:
                    act.append(activity(gv[:, q], c.lower, c.upper, active_tol))
        # the start of the segment: the previous segment's last collocation point
        prev_s = None
        if k > 0:
            prev_node = lay.colloc[k - 1][-1]
            prev_s = lay.s_colloc[prev_node]
        switches = []
        control_switch = False
        inner = []
        sa, sb = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        edge = 1e-12 * max(sb - sa, 1e-300)
        for pattern_idx, pattern in enumerate(act):
            for i in range(1, len(pattern)):
                if pattern[i] != pattern[i - 1]:
                    switches.append((float(s_nodes[i - 1]), float(s_nodes[i])))
                    control_switch = control_switch or pattern_idx < nu
        for pattern in binding[sc_nodes].T if binding is not None else ():
            for i in range(1, len(pattern)):
                if pattern[i] != pattern[i - 1] and s_nodes[i - 1] > sa + edge and s_nodes[i] < sb - edge:
                    inner.append((float(s_nodes[i - 1]), float(s_nodes[i])))
        switches = sorted(set(switches))
        err = max(disc, viol, integral_err)
        out.append(SegmentError(ph.name, k, ta, tb, sc.degree, err, disc, viol, which,
                                bool(switches), switches, smoothed, integral_err,
                                np.array(x_int[-1], float), q_inc, control_switch, sorted(set(inner))))
    return out


def segment_quadratures(pb, params: dict) -> np.ndarray:
    """(segments, integrals): each segment's share of every integral of the phase as the NLP
    computes it, sum_i w_i h/2 L(x_i, u_i, t_i) over its collocation points."""
    ph, lay = pb.phase, pb.layout
    mesh = lay.mesh
    if not ph.integrals:
        return np.zeros((mesh.segments, 0))
    free_syms = sorted(params, key=str)
    pvals = [params[s] for s in free_syms]
    _, _, qf = phase_functions_all(ph, free_syms)
    X, U, t0, tf = solution_arrays(pb)
    out = np.zeros((mesh.segments, len(ph.integrals)))
    for k in range(mesh.segments):
        w = np.asarray(mesh.scheme(k).weights, float)
        h = (tf - t0) * (mesh.breakpoints[k + 1] - mesh.breakpoints[k])
        cn, sn = lay.colloc[k], lay.colloc_state[k]
        tk = t0 + (tf - t0) * lay.s_colloc[cn]
        vals = np.array([np.asarray(qf(*X[sn[i]], *U[cn[i]], tk[i], *pvals), float).reshape(-1)
                         for i in range(len(cn))])
        out[k] = w @ vals * h / 2.0
    return out


@dataclass
class PhaseEnd:
    """A phase flown from its initial state with the collocated (clipped) controls, segment
    after segment: its states and integrals at t0 and tf, and their scales."""

    t0: float
    tf: float
    x0: np.ndarray
    x_end: np.ndarray
    q_end: np.ndarray
    x_scale: np.ndarray
    q_scale: np.ndarray
    u0: np.ndarray
    u_end: np.ndarray


def phase_end(pb, params: dict, rtol: float = 1e-12, start=None) -> PhaseEnd:
    """The phase re-integrated from x(t0) over all its segments (see ``PhaseEnd``): what the
    terminal conditions and the integrals really are at the returned t_f. ``start``: another
    initial state (``flight_amplification``)."""
    from ...verify.checks import state_scale

    ph, lay = pb.phase, pb.layout
    mesh = lay.mesh
    X, U, t0, tf = solution_arrays(pb)
    funcs, uf = flight_functions(pb, params, X, U, t0, tf)
    nx = X.shape[1]
    nq = len(ph.integrals)
    quad_k = segment_quadratures(pb, params)
    x_scale = state_scale(X)
    q_scale = np.maximum(np.sum(np.abs(quad_k), axis=0), 1e-12) if nq else np.zeros(0)
    y = np.concatenate([X[0] if start is None else np.asarray(start, float), np.zeros(nq)])
    atol = rtol * np.concatenate([1.0 + np.max(np.abs(X), axis=0), 1.0 + q_scale])
    u0 = u_end = np.zeros(len(ph.controls))
    for k in range(mesh.segments):
        ta, tb = t0 + (tf - t0) * mesh.breakpoints[k], t0 + (tf - t0) * mesh.breakpoints[k + 1]
        h = tb - ta
        if k == 0:
            u0 = np.array(uf.piece(0.5 * (ta + tb))(ta), float)
        if k == mesh.segments - 1:
            u_end = np.array(uf.piece(0.5 * (ta + tb))(tb), float)
        if not h > 0:
            continue
        sol = _fly(funcs, uf, ta, tb, y, np.array([tb]), rtol, atol)
        if not sol.success or sol.y.shape[1] != 1:
            y = np.full_like(y, np.nan)
            break
        y = sol.y[:, -1]
    return PhaseEnd(t0, tf, X[0], y[:nx], y[nx:], x_scale, q_scale, u0, u_end)


def segment_ends(pb, params: dict, errors: list[SegmentError]) -> PhaseEnd:
    """The phase's ends judged piece by piece (multiple shooting): the state at t_f is the
    last segment's flown from that segment's own collocated start, each integral the sum of the
    segments' increments, each flown from its start (``estimate_errors`` integrates them).
    For dynamics whose flight from x(t0) amplifies (``flight_amplification``): a change of
    the state grows over one segment only, not over the phase (Betts' alp rider, e^40 over
    t_f = 20; at most e^(2 h) over a segment of width h)."""
    from ...verify.checks import state_scale

    ph = pb.phase
    X, U, t0, tf = solution_arrays(pb)
    nq = len(ph.integrals)
    quad_k = segment_quadratures(pb, params)
    last = errors[-1] if errors else None
    x_end = last.x_end if last is not None and last.x_end is not None else X[-1]
    q_end = (np.sum([e.q_increment for e in errors], axis=0) if nq and errors else np.zeros(nq))
    q_scale = np.maximum(np.sum(np.abs(quad_k), axis=0), 1e-12) if nq else np.zeros(0)
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    lay = pb.layout
    _, us0 = seg_polys(lay, 0, X, U)
    _, us1 = seg_polys(lay, lay.mesh.segments - 1, X, U)
    return PhaseEnd(t0, tf, X[0], np.asarray(x_end, float), np.asarray(q_end, float), state_scale(X), q_scale,
                    np.clip(us0(-1.0)[0], ulo, uhi), np.clip(us1(1.0)[0], ulo, uhi))


def flight_amplification(pb, params: dict, end: PhaseEnd, rel: float = 1e-6) -> float:
    """How much the open-loop flight of ``phase_end`` amplifies a change of its initial state:
    max_j |dx_j(tf)| / x_scale_j over max_j |dx_j(t0)| / x_scale_j for the start moved by
    ``rel`` of every state's scale (one direction: a lower bound of the amplification).
    Inf when the moved flight fails. Betts' alp rider (a block with eigenvalue +2 over
    t_f = 20) amplifies by about e^40: flown from x(t0), its terminal conditions were missed by
    1e8-1e14 on meshes whose J was 7e-7 from the published value."""
    d = rel * end.x_scale
    moved = phase_end(pb, params, start=end.x0 + d)
    dx = np.abs(moved.x_end - end.x_end) / end.x_scale
    if not np.all(np.isfinite(dx)):
        return math.inf
    return float(np.max(dx) / rel)
