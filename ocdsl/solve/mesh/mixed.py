"""Entry and exit of the arcs on which a mixed control-state path constraint is active
(normalised time), located from the unconstrained arc next to them."""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from .segments import control_polys, phase_functions, runs_of, solution_arrays, state_evaluator

# a collocation point is on the constraint within this (relative to 1 + |bound|): looser than
# the estimate's activity test, because the NLP meets a constraint whose multiplier is small
# (next to the junction, where it falls to 0) only to its own tolerance (Rayleigh: g = -5e-5
# with multiplier 1e-3 one node before the exit)
ON = 1e-4
AWAY = 1e-3   # a segment clearly off the constraint somewhere (relative, as ON)


def _mixed(ph) -> list[int]:
    """Indices of the phase's inequality path constraints that contain a control."""
    controls = set(ph.controls)
    out = []
    for q, c in enumerate(ph.path):
        if c.is_equality:
            continue
        if sp.sympify(ph.substitute(c.expr)).free_symbols & controls:
            out.append(q)
    return out


def locate_mixed_junctions(pb, params: dict) -> list[float]:
    """Junctions of mixed path constraints c(x, u, t) <= bound (or >= bound).

    A constrained arc is a run of segments on which the constraint is active (within ``ON``)
    at every collocation point; for it and the nearest segment on either side that is off the
    constraint at its interior points (the ends may touch it) and clearly so somewhere, the
    junction is the zero nearest the arc of
        psi(s) = c(x(s), u_U(s), t(s)) - bound,
    u_U the unconstrained segment's control polynomial extrapolated over the gap and x(s) the
    state polynomials. Where the Hamiltonian is strictly convex in u the control is continuous
    at the junction (and meets the constraint there) but kinked: the collocated solution
    smears the kink over the segment that holds it, while the unconstrained arc's polynomial,
    smooth up to the junction, meets the constraint where the arc ends. Measured on
    configs/mesh_rayleigh_mixed.yaml (exit of u + x1/6 <= 0 near t = 1.2700): the polynomial
    corner locator (``locate._corner``) found none on the refined meshes, and the segments
    around the breakpoint 7e-5 (normalised) before the exit were refined to degree 11 without
    meeting the tolerance.
    """
    from .roots import brentq

    ph, lay = pb.phase, pb.layout
    idx = _mixed(ph)
    if not idx:
        return []
    free_syms = sorted(params, key=str)
    pvals = [params[s] for s in free_syms]
    _, g = phase_functions(ph, free_syms)
    X, U, t0, tf = solution_arrays(pb)
    x_at = state_evaluator(lay, X, U)
    mesh = lay.mesh
    bps = np.asarray(mesh.breakpoints, float)
    K = mesh.segments
    polys = control_polys(pb)
    tc = t0 + (tf - t0) * lay.s_colloc
    gv = np.array([np.asarray(g(*X[lay.colloc_state[k][i]], *U[lay.colloc[k][i]], tc[lay.colloc[k][i]], *pvals),
                               float).reshape(-1)
                   for k in range(K) for i in range(len(lay.colloc[k]))])
    seg_rows, r = [], 0
    for k in range(K):
        n = len(lay.colloc[k])
        seg_rows.append(np.arange(r, r + n))
        r += n
    out = []
    for q in idx:
        c = ph.path[q]
        for bound, sign in ((c.upper, 1.0), (c.lower, -1.0)):
            if not math.isfinite(bound):
                continue
            scale = 1.0 + abs(bound)
            # distance to the bound, >= 0 where the constraint is met
            dist = [sign * (bound - gv[rows, q]) / scale for rows in seg_rows]
            full = [bool(np.all(d <= ON)) for d in dist]
            free = [bool(np.all(d[1:-1] > ON)) and float(np.max(d)) > AWAY if len(d) > 2
                    else bool(np.all(d > ON)) for d in dist]
            for qa, qb in runs_of(full):
                for side, edge, other in (("entry", qa, next((p for p in range(qa - 1, -1, -1) if free[p]), None)),
                                          ("exit", qb, next((p for p in range(qb + 1, K) if free[p]), None))):
                    if other is None:
                        continue
                    b = float(bps[edge] if side == "entry" else bps[edge + 1])
                    if side == "entry":
                        lo_s, hi_s = 0.5 * (bps[other] + bps[other + 1]), 0.5 * (bps[edge] + bps[edge + 1])
                    else:
                        lo_s, hi_s = 0.5 * (bps[edge] + bps[edge + 1]), 0.5 * (bps[other] + bps[other + 1])

                    def psi(s, other=other, q=q, bound=bound):
                        x = x_at(s)
                        u = polys[other](np.array([s]))[0]
                        return float(np.asarray(g(*x, *u, t0 + (tf - t0) * s, *pvals), float).reshape(-1)[q]
                                     - bound)

                    grid = np.linspace(lo_s, hi_s, 201)
                    with np.errstate(all="ignore"):     # the grid in one call (it brackets the roots)
                        xg, ug = x_at.many(grid), polys[other](grid)
                        vals = np.broadcast_to(np.asarray(g(*xg.T, *ug.T, t0 + (tf - t0) * grid, *pvals)[q],
                                                          float), grid.shape) - bound
                    roots = [brentq(psi, grid[n], grid[n + 1], xtol=1e-15)
                             for n in range(len(grid) - 1)
                             if np.isfinite(vals[n]) and np.isfinite(vals[n + 1]) and vals[n] * vals[n + 1] < 0]
                    roots += [float(grid[n]) for n in range(len(grid)) if vals[n] == 0.0]
                    if roots:
                        out.append(float(min(roots, key=lambda x: abs(x - b))))
    return sorted(set(out))
