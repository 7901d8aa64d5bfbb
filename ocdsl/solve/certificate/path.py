"""State-constrained arcs and path constraints with their multipliers, for the certificate."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import sympy as sp

from ocdsl.symbolic.model import Model

from .sides import _f
from .tolerances import Tolerances

def _state_arcs(model: Model, t, X, state_bounds, run: int = 2) -> list[str]:
    """``name <= bound`` of each state at one of its bounds at ``run`` or more nodes in a row,
    with the longest such run's node count and times (a few nodes may be a touch point the
    mesh resolves as a short arc: the nodes, not a guess of which, are said)."""
    held = []
    for j, st in enumerate(model.states):
        lo, hi = ((state_bounds or {}).get(st.name) or (None, None))[:2]
        for b, op in ((hi, "<="), (lo, ">=")):
            if b is None or not math.isfinite(b):
                continue
            at = np.abs(X[:, j] - b) <= 1e-6 * max(1.0, abs(b))
            longest = cur = 0
            end = -1
            for i, a in enumerate(at):
                cur = cur + 1 if a else 0
                if cur > longest:
                    longest, end = cur, i
            if longest >= run:
                held.append(f"{st.name} {op} {b:g} at {longest} consecutive nodes, "
                            f"t = {t[end - longest + 1]:.6g} to {t[end]:.6g}")
    return held


def _state_touches(model: Model, t, X, state_bounds, path, G, gu) -> list[str]:
    """State bounds, and path constraints free of the controls (dg/du = 0 at every node), at
    their bound at some node inside the phase (the ends hold boundary conditions): where such a
    constraint touches, the costates jump by its multiplier's impulse, and H too when the
    constraint depends on time (unseen16: x + 4 (t - 1/2)^2 >= 0.8, J right to 7e-10, H 2.4 off
    at the touch point)."""
    out = []
    inner = slice(1, len(t) - 1)
    for j, st in enumerate(model.states):
        lo, hi = ((state_bounds or {}).get(st.name) or (None, None))[:2]
        for b, op in ((hi, "<="), (lo, ">=")):
            if b is not None and math.isfinite(b):
                at = np.flatnonzero(np.abs(X[inner, j] - b) <= 1e-6 * max(1.0, abs(b)))
                if len(at):
                    out.append(f"{st.name} {op} {b:g} at t = {t[1 + at[0]]:.6g}")
    for k, (_g, lo, hi, text) in enumerate(path or ()):
        if gu is not None and np.any(np.abs(gu[:, k, :]) > 0):
            continue
        gk = G[inner, k]
        for b in (lo, hi):
            if math.isfinite(b):
                at = np.flatnonzero(np.abs(gk - b) <= 1e-6 * max(1.0, abs(b)))
                if len(at):
                    out.append(f"`{text}` at t = {t[1 + at[0]]:.6g}")
    return out


def _path_item(c) -> tuple:
    g, lo, hi, *rest = c
    lo = -math.inf if lo is None else float(lo)
    hi = math.inf if hi is None else float(hi)
    if lo > hi:
        raise ValueError(f"certificate: bounds of path constraint {g} are reversed: {lo} > {hi}")
    return sp.sympify(g), lo, hi, (str(rest[0]) if rest else str(g))


def _path_sizes(G, path, gu=None, U=None) -> list[float]:
    """Each path constraint's size: its range over the phase, its bounds, and its control
    terms sum_j |dg/du_j u_j| (a constraint binding throughout, `u - p <= 0` at u = p = 1,
    has range 0 and bound 0: its size is its terms', 1, not 1e-12; unseen27 FA4 counted it
    active at no node)."""
    sizes = []
    for k, (_g, lo, hi, _text) in enumerate(path):
        terms = [float(np.max(np.abs(gu[:, k, :] * U).sum(axis=1)))] if gu is not None and len(G) else []
        sizes.append(max([float(np.ptp(G[:, k]))] + [abs(b) for b in (lo, hi) if math.isfinite(b)]
                         + terms + [1e-12]))
    return sizes


def _path_active(G, path, tol: Tolerances, sizes) -> np.ndarray:
    """(N, p): path constraint k within ``saturation`` of its size from a finite bound."""
    active = np.zeros(G.shape, bool)
    for k, ((_g, lo, hi, _text), size) in enumerate(zip(path, sizes)):
        gk = G[:, k]
        band = tol.saturation * size
        if math.isfinite(hi):
            active[:, k] |= gk >= hi - band
        if math.isfinite(lo):
            active[:, k] |= gk <= lo + band
    return active


def _held_fraction(side, gu, active) -> float:
    """The share of nodes where the active bounds and path constraints fix every control:
    their gradients in u (e_j for a control at its bound, dg_k/du for an active g_k) span R^m."""
    N, m = side.shape
    held = 0
    for n in range(N):
        rows = [np.eye(m)[j] for j in range(m) if side[n, j] != 0]
        rows += [gu[n, k] for k in range(active.shape[1]) if active[n, k]]
        if rows and np.linalg.matrix_rank(np.array(rows), tol=1e-9) == m:
            held += 1
    return held / N if N else 0.0


def _path_check(num, path, t, X, U, Mu, scale, tol: Tolerances) -> dict[str, Any]:
    """Complementarity and sign conditions of the path multipliers (see the module doc)."""
    G = num.g_nodes(t, X, U)                             # (N, p)
    sizes = _path_sizes(G, path, num.gu_nodes(t, X, U), U)
    actives = _path_active(G, path, tol, sizes)
    per = []
    comp_abs = comp_rel = wrong_rel = 0.0
    ok_scale = scale > 0
    # a node holds its share of the phase: mu is a density, and on a segment 3e-7 long (a
    # touch point at t0 that LGR holds no node of, bisected again and again) mu reached 1e6
    # and mu (g - b) 0.1 at Ipopt's slack while its integral was 3e-8 (unseen56 F1)
    spacing = np.gradient(t) if len(t) > 1 else np.ones(len(t))
    share = np.minimum(1.0, spacing / max(float(np.mean(spacing)), 1e-300))
    for k, ((g, lo, hi, text), size) in enumerate(zip(path, sizes)):
        mu, gk = Mu[:, k], G[:, k]
        finite = [b for b in (lo, hi) if math.isfinite(b)]
        # the bound the multiplier's sign points to (an equality: its value)
        b = np.where(mu > 0, hi, lo) if lo != hi else np.full(len(mu), lo)
        wrong = ~np.isfinite(b) & (mu != 0)
        comp = np.where(np.isfinite(b), np.abs(mu * (gk - np.where(np.isfinite(b), b, 0.0))), 0.0) * share
        active = actives[:, k]
        wrong_mag = np.abs(mu[wrong]) * size
        ca = float(comp.max()) if len(comp) else 0.0
        cr = ca / scale if ok_scale else (0.0 if ca == 0 else math.inf)
        wa = float(wrong_mag.max()) if wrong.any() else 0.0
        wr = wa / scale if ok_scale else (0.0 if wa == 0 else math.inf)
        kind = ("equality" if lo == hi else "range" if len(finite) == 2
                else "upper" if math.isfinite(hi) else "lower" if math.isfinite(lo) else "free")
        per.append({"index": k, "text": text, "kind": kind, "lower": _f(lo), "upper": _f(hi),
                    "active_nodes": int(active.sum()),
                    "wrong_sign_nodes": int(np.sum(np.abs(mu[wrong]) * size > tol.stationarity * scale)),
                    "max_wrong_sign_relative": _f(wr), "complementarity": ca,
                    "complementarity_relative": _f(cr), "mu_min": float(mu.min()),
                    "mu_max": float(mu.max())})
        comp_abs, comp_rel, wrong_rel = max(comp_abs, ca), max(comp_rel, cr), max(wrong_rel, wr)
    return {"complementarity": comp_abs, "complementarity_relative": _f(comp_rel),
            "max_wrong_sign_relative": _f(wrong_rel), "scale": scale, "per_constraint": per,
            "passed": bool(comp_rel <= tol.complementarity and wrong_rel <= tol.stationarity)}
