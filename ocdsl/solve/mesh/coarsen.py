"""Coarsening: a smaller mesh where the error is far below tolerance (merged segments,
lower degrees, or one segment per arc between located features)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .boundary import boundary_controls
from .segments import phase_functions, seg_polys, solution_arrays, state_at


def _samples(pb, extra_points: int = 6):
    """Per segment: normalised times and the (clipped) state and control polynomial values on
    N + extra_points Lobatto points."""
    from ...transcribe.nodes import legendre_gauss_lobatto

    ph, lay = pb.phase, pb.layout
    X, U, _, _ = solution_arrays(pb)
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    out = []
    for k in range(lay.mesh.segments):
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        tau = np.asarray(legendre_gauss_lobatto(lay.mesh.degrees[k] + extra_points)[0])
        xs, us = seg_polys(lay, k, X, U)
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


def coarsen(pb, errors, spec, features, budget=None) -> Any:
    """A smaller mesh of one phase that should still meet the tolerance, or the same mesh.

    Liu, Hager & Rao (2015) reduce the mesh where the error is far below the tolerance; here
    (our variant) consecutive segments are merged, left to right, while one Legendre
    polynomial of degree <= max_degree fits the solution over the merged interval to within
    ``coarsen_margin * tolerance``, and every segment gets the smallest such degree (down to
    ``lowest_degree``). Breakpoints on located switches/corners are kept. The next solve
    checks the result with the error estimate.
    """
    from ...transcribe.mesh import Mesh

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
    arcs = _arc_mesh(pb, spec, features, samples, xs, us, limit, lowest, budget)
    nx, nu = len(pb.phase.states), len(pb.phase.controls)
    if arcs is not None and nlp_size(arcs, nx, nu) < nlp_size(merged, nx, nu):
        return arcs
    return merged


# right-hand-side evaluations a boundary-arc flight may take (DOP853: about 12 per step). A
# bound that is not active on the arc can make its boundary control drive the flight where the
# integrator creeps (COPS hang glider: the boundary controls of x's and vx's bounds, never
# active, followed over the thermal: one call ran for minutes, the mesh iteration with it);
# such a flight is no boundary arc. The boundary arcs of configs/mesh_*.yaml took 32
# (Bryson-Denham) to 515 (Goddard's v <= 0.1).
MAX_EVALUATIONS = 5_000


class _TooLong(Exception):
    pass


def _boundary_arc(pb, a: float, b: float, pts, xscale, threshold: float, budget=None):
    """States on the sample points ``pts`` (normalised time in [a, b]) of the trajectory that
    starts from the collocated state at a and follows a state bound's boundary control
    (``boundary_controls``), when it stays within ``threshold`` (relative, as the error
    estimate) of the collocated states on the arc's nodes and within the control's bounds;
    else None. Phases with free parameters are not tried."""
    from ...verify import dop853

    ph, lay = pb.phase, pb.layout
    X, U, t0, tf = solution_arrays(pb)
    f, _ = phase_functions(ph, [])
    inside = (lay.s_state >= a) & (lay.s_state <= b)
    ta, tb = t0 + (tf - t0) * a, t0 + (tf - t0) * b
    ts = np.clip(t0 + (tf - t0) * np.concatenate([lay.s_state[inside], pts]), min(ta, tb), max(ta, tb))
    t_eval = np.unique(ts)
    nu = len(ph.controls)
    scale = np.broadcast_to(np.asarray(xscale, float), (X.shape[1],))
    for j, (_q, i, ub) in boundary_controls(ph, [], budget=budget).items():
        # a boundary arc holds its state on the bound at every node: a bound the arc's nodes
        # are off is not followed (its boundary control may drive the flight anywhere: the
        # hang glider's never-active x >= 0 and vx >= 0 took 2 s of its first converged mesh)
        if not any(math.isfinite(b) and np.all(np.abs(X[inside, j] - b) <= threshold * scale[j])
                   for b in ph.bounds_of(ph.states[j])[:2]):
            continue
        lo, hi = ph.bounds_of(ph.controls[i])

        def control(x, t, i=i, ub=ub):
            u = np.zeros(nu)
            u[i] = float(ub(*x, t))
            return u

        calls = [0]

        def rhs(t, x, control=control, calls=calls):
            calls[0] += 1
            if calls[0] > MAX_EVALUATIONS:
                raise _TooLong
            return np.asarray(f(*x, *control(x, t), t), float).reshape(-1)

        x0 = state_at(lay, X, U, a)
        try:
            with np.errstate(all="ignore"):
                sol = dop853.solve(rhs, (ta, tb), x0, t_eval, 1e-11, 1e-11 * xscale)
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


def _arc_mesh(pb, spec, features, samples, xs, us, limit, lowest, budget=None):
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
    from ...transcribe.mesh import Mesh

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
            y = _boundary_arc(pb, a, b, s_all[m], xs, math.sqrt(spec.tolerance), budget)
            if y is not None:
                nb = _fit_degree([(s_all[m], y, u_all[m])], xs, us, lowest, spec.max_degree, limit, shift)
                n = nb if nb is not None and (n is None or nb < n) else n
        if n is None:
            return None
        degrees.append(n)
    return Mesh(lay.mesh.scheme_name, np.array(edges), tuple(degrees))


def nlp_size(mesh, nx: int, nu: int) -> int:
    """Unknowns of one phase on ``mesh`` (states on state nodes + controls), for comparisons."""
    from ...transcribe.mesh import Layout

    lay = Layout.of(mesh)
    return lay.n_state_nodes * nx + lay.n_colloc * nu
