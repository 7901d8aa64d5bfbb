"""The solved phase seen segment by segment: its node values, the state and control
polynomials of each segment, and where values sit at their bounds."""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from ...result import PhaseTrajectory


_FUNCTIONS: dict = {}     # id(phase) -> (phase, free symbols, functions): lambdified once per run


def phase_functions(ph, free_syms):
    """The phase's dynamics ``f`` and path constraints ``g`` (None without any) as NumPy
    callables of (states..., controls..., t, free parameters...)."""
    f, g, _ = phase_functions_all(ph, free_syms)
    return f, g


def phase_functions_all(ph, free_syms):
    """``f``, ``g`` and the integrands ``q`` of every integral of the phase (None without any),
    lambdified once per phase and free-parameter list (the mesh iterations reuse them)."""
    key = id(ph)
    hit = _FUNCTIONS.get(key)
    if hit is not None and hit[0] is ph and hit[1] == tuple(free_syms):
        return hit[2]
    from ...symbolic.model import TIME

    args = list(ph.states) + list(ph.controls) + [TIME] + list(free_syms)
    f = sp.lambdify(args, list(ph.rhs()), "numpy", cse=True)
    g = sp.lambdify(args, [ph.substitute(c.expr) for c in ph.path], "numpy", cse=True) if ph.path else None
    q = (sp.lambdify(args, [ph.substitute(e) for e in ph.integrals.values()], "numpy", cse=True)
         if ph.integrals else None)
    if len(_FUNCTIONS) > 64:     # a long study builds many problems: keep the cache small
        _FUNCTIONS.clear()
    _FUNCTIONS[key] = (ph, tuple(free_syms), (f, g, q))
    return f, g, q


def solution_arrays(pb):
    """States (state nodes), controls (collocation nodes; a control that enters only through
    2 pi-periodic functions on one continuous branch, ``continuous_controls``), t0, tf."""
    from ...transcribe.solution import continuous_controls, node_values, phase_times

    X, U = node_values(pb)
    return (X, continuous_controls(pb, U), *phase_times(pb))


def _interpolant(nodes, values):
    """tau -> (m, ncols): the polynomial through ``values`` at ``nodes``, by the barycentric
    formula with its weights computed once (the integrators of the estimate call it at every
    step: lagrange_matrix, which recomputes them, was most of the mesh stage's time)."""
    from ...transcribe.nodes import barycentric_rows, barycentric_weights

    x = np.asarray(nodes, float)
    F = np.asarray(values, float)
    w = barycentric_weights(x)

    def ev(tau):
        p = np.atleast_1d(np.asarray(tau, float))
        if p.size == 1:
            # one point (the integrators' right-hand sides): the same formula without the
            # matrix, about a third of the time per call
            d = p[0] - x
            if not d.all():
                return F[np.flatnonzero(d == 0.0)[:1]]
            with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
                r = w / d
                out = r @ F / r.sum()
            if not np.isfinite(out).all():   # a point within ~1e-300 of a node: w / d overflowed
                return F[[int(np.argmin(np.abs(d)))]]
            return out[None, :]
        return barycentric_rows(x, w, p) @ F

    return ev


def seg_polys(lay, k, X, U):
    """Callables tau -> state (m, nx) and tau -> control (m, nu) of segment k."""
    sc = lay.mesh.scheme(k)
    Xs, Uc = X[lay.support[k]], U[lay.colloc[k]]
    xs = _interpolant(sc.support, Xs)
    if len(sc.colloc) == 1:
        def us(tau):
            return np.repeat(Uc, len(np.atleast_1d(tau)), axis=0)
    else:
        us = _interpolant(sc.colloc, Uc)
    return xs, us


def activity(values, lo, hi, tol, span: float | None = None):
    """-1 at the lower bound, +1 at the upper bound, 0 inside (per value): within ``tol`` x
    (1 + |bound|) of it, Ipopt's own resolution of a bound; with ``span`` (the quantity's
    range over the phase), not farther than 1e-3 of that span (at least ``tol``): a state about
    1e7 travelling 0.11 to x <= 1e7 + 1/9 was "at its bound" at 17 nodes up to 0.087 below it,
    where 2 are (unseen59 F5)."""
    def near(b: float) -> float:
        d = tol * (1 + abs(b))
        return d if span is None else min(d, max(1e-3 * span, tol))

    out = np.zeros(len(values), int)
    if math.isfinite(lo):
        out[values <= lo + near(lo)] = -1
    if math.isfinite(hi):
        out[values >= hi - near(hi)] = 1
    return out


def runs_of(flags) -> list[tuple[int, int]]:
    """(first, last) index of every run of consecutive true flags."""
    runs, k = [], 0
    while k < len(flags):
        if not flags[k]:
            k += 1
            continue
        qa = k
        while k + 1 < len(flags) and flags[k + 1]:
            k += 1
        runs.append((qa, k))
        k += 1
    return runs


def zigzag(u, step: float | None = None) -> bool:
    """Node-to-node chattering: the significant steps of u (above ``step``, default 1e-6 of
    1 + max |u|) alternate in sign at least twice."""
    d = np.diff(np.asarray(u, float))
    d = d[np.abs(d) > (1e-6 * (1.0 + np.max(np.abs(u))) if step is None else step)]
    return int(np.sum(np.sign(d[1:]) != np.sign(d[:-1]))) >= 2


def state_evaluator(lay, X, U):
    """s -> ``state_at(lay, X, U, s)`` with each segment's interpolant made once (the
    junction locators evaluate it on a grid of 201 points per junction)."""
    bps = lay.mesh.breakpoints
    cache: dict = {}

    def poly(k):
        xs = cache.get(k)
        if xs is None:
            xs = cache[k] = seg_polys(lay, k, X, U)[0]
        return xs

    def at(s):
        k = int(np.clip(np.searchsorted(bps, s, side="right") - 1, 0, lay.mesh.segments - 1))
        a, b = bps[k], bps[k + 1]
        return poly(k)(2.0 * (s - a) / (b - a) - 1.0)[0]

    def many(ss):
        """The states at the times ``ss`` (P,) -> (P, n): a locator's grid in one call per segment."""
        ss = np.asarray(ss, float)
        ks = np.clip(np.searchsorted(bps, ss, side="right") - 1, 0, lay.mesh.segments - 1)
        out = np.empty((len(ss), X.shape[1]))
        for k in np.unique(ks):
            sel = ks == k
            a, b = bps[k], bps[k + 1]
            out[sel] = poly(int(k))(2.0 * (ss[sel] - a) / (b - a) - 1.0)
        return out

    at.many = many
    return at


def state_at(lay, X, U, s):
    """State polynomial value at normalised time s (the segment holding s; the first or last
    segment's polynomial extrapolated outside [0, 1])."""
    bps = lay.mesh.breakpoints
    k = int(np.clip(np.searchsorted(bps, s, side="right") - 1, 0, lay.mesh.segments - 1))
    xs, _ = seg_polys(lay, k, X, U)
    a, b = bps[k], bps[k + 1]
    return xs(2.0 * (s - a) / (b - a) - 1.0)[0]


def control_polys(pb):
    """Per segment: s -> control polynomial of that segment (normalised time s)."""
    lay = pb.layout
    X, U, _, _ = solution_arrays(pb)
    out = []
    for k in range(lay.mesh.segments):
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        _, us = seg_polys(lay, k, X, U)
        out.append(lambda s, us=us, a=a, b=b: us(2.0 * (np.asarray(s) - a) / (b - a) - 1.0))
    return out


def dense_trajectory(pb, samples: int = 4) -> PhaseTrajectory:
    """States and controls sampled from each segment's polynomials (a warm start)."""
    ph, lay = pb.phase, pb.layout
    X, U, t0, tf = solution_arrays(pb)
    ulo = np.array([ph.bounds_of(c)[0] for c in ph.controls])
    uhi = np.array([ph.bounds_of(c)[1] for c in ph.controls])
    xlo = np.array([ph.bounds_of(s)[0] for s in ph.states])
    xhi = np.array([ph.bounds_of(s)[1] for s in ph.states])
    ts, xs_all, us_all = [], [], []
    for k in range(lay.mesh.segments):
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        xs, us = seg_polys(lay, k, X, U)
        n = lay.mesh.degrees[k] + samples
        # open interval inside the segment keeps np.interp's abscissae increasing
        tau = np.linspace(-1, 1, n + 2)[1:-1]
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


def close_mesh(a, b, tol: float) -> bool:
    """Same scheme and degrees, breakpoints within ``tol`` (normalised time)."""
    return (a.scheme_name == b.scheme_name and tuple(a.degrees) == tuple(b.degrees)
            and len(a.breakpoints) == len(b.breakpoints)
            and bool(np.all(np.abs(np.asarray(a.breakpoints) - np.asarray(b.breakpoints)) <= tol)))
