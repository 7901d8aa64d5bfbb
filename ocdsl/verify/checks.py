"""The verification's checks of one solution, each a row ``{name, phase, value, limit,
passed, where, detail}``; ``value`` is always relative (see :func:`state_scale` and
:func:`sensitivity_scale`) and ``limit`` the tolerance it is held to."""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np
import sympy as sp


# the NLP's resolution in its own units (ten times Ipopt's tol, ocdsl's default 1e-8; the
# certificate's Tolerances.resolution is this too): a state whose values all stay within it of zero is
# measured against it. With 1e-12 a state that is 0 at the optimum failed on the solver's
# slop: an unused axis (planar motion in a 3-D model, a single-axis slew of a full attitude
# model) left at 1e-16..2.4e-13 by a perturbed start was "1e-4..0.24 relative", while the
# single start, exactly 0, passed (unseen21 FA2b); with 1e-8 the verification's 1e-5 asked
# 1e-13 of it, the rounding of its rate's terms: x' = ux + 0.5 held at x = 0 by ux = -0.5
# missed by 1.5e-13 over 1.15 s, "1.5e-5", failed (unseen27 FA5)
RESOLUTION = 1e-7


def state_scale(X: np.ndarray) -> np.ndarray:
    """Per column: its range over the rows, at least 1e-3 of its largest magnitude (a nearly
    constant quantity is measured against its size) and the NLP's resolution (``RESOLUTION``)."""
    if X.size == 0:
        return np.ones(X.shape[1])
    rng = np.nanmax(X, axis=0) - np.nanmin(X, axis=0)
    size = np.nanmax(np.abs(X), axis=0)
    return np.maximum.reduce([rng, 1e-3 * size, np.full(X.shape[1], RESOLUTION)])


def row(name: str, phase: str | None, value: float, limit: float, where: str = "", detail: str = "",
        **more: Any) -> dict[str, Any]:
    value = float(value)
    passed = bool(math.isfinite(value) and value <= limit)
    out = {"name": name, "phase": phase, "value": value, "limit": float(limit), "passed": passed,
           "where": where, "detail": detail}
    out.update(more)
    return out


def relative_violation(values: np.ndarray, lo: float, hi: float, scale: np.ndarray | float) -> np.ndarray:
    """How far ``values`` lie outside [lo, hi], divided by ``scale``."""
    v = np.asarray(values, float)
    over = np.maximum(np.maximum(lo - v, v - hi), 0.0)
    over = np.where(np.isfinite(v), over, np.inf)
    return over / scale


def sensitivity_scale(expr: sp.Expr, point: Mapping[sp.Symbol, float],
                      scales: Mapping[sp.Symbol, float]) -> float:
    """``sum_s |d expr/d s| scale_s`` at ``point``: how much ``expr`` moves when each quantity
    it depends on moves by its own scale (a boundary condition ``x(tf) == 0`` is measured
    against x's range, ``integral(L) == c`` against the integral's size)."""
    if isinstance(expr, sp.Symbol):      # most boundary conditions: no SymPy arithmetic needed
        return float(scales[expr]) if expr in scales and float(scales[expr]) > 0 else 1e-12
    total = 0.0
    subs = {k: sp.Float(v) for k, v in point.items()}
    for s in expr.free_symbols:
        if s not in scales:
            continue
        try:
            d = abs(float(sp.diff(expr, s).xreplace(subs)))
        except (TypeError, ValueError):
            d = math.inf
        total += (d if math.isfinite(d) else 0.0) * scales[s]
    return total if total > 0 else 1e-12


def evaluate(expr: sp.Expr, point: Mapping[sp.Symbol, float]) -> float:
    if isinstance(expr, sp.Symbol):
        return float(point[expr]) if expr in point else math.nan
    try:
        v = complex(expr.xreplace({k: sp.Float(v) for k, v in point.items()}).evalf())
    except (TypeError, ValueError):
        return math.nan
    return v.real if abs(v.imag) <= 1e-12 * max(1.0, abs(v.real)) else math.nan


def worst(err: np.ndarray, names: list[str], t: np.ndarray) -> tuple[float, str]:
    """Largest entry of ``err`` (P, k) and where: ``name at t = ...``."""
    if err.size == 0:
        return 0.0, ""
    e = np.where(np.isfinite(err), err, np.inf)
    i, j = np.unravel_index(int(np.argmax(e)), e.shape)
    return float(e[i, j]), f"{names[j]} at t = {t[i]:.6g}"


# a spike or zigzag smaller than this share of a bounded control's range is noise, not a
# shape the NLP made (unseen39 F6: a coast thrust 2e-6 ... 2.8e-5 on [0, 1.227] "jumped")
IRREGULAR_RANGE_SHARE = 1e-3


def irregular_controls(t: np.ndarray, U: np.ndarray, names: list[str], transcription: str | None = None,
                       mesh: bool = False, spans: list[float] | None = None) -> list[str]:
    """Notes on controls that an NLP shapes node by node instead of resolving: an isolated
    spike (one node far from both neighbours, on the same side) or a zigzag (the differences
    alternating in sign over most rows). Either means the collocation scheme is exploited,
    and refining alone may not help, so the summary says what else to change (LG only to a
    file that does not use it already: unseen10 F3; `mesh:` only to a run without it: unseen17).
    ``spans``: each control's bound range (inf where unbounded)."""
    notes = []
    other = "" if transcription == "LG" else "`transcription: LG`, "
    advice = ("the NLP exploits the collocation scheme instead of resolving the solution (typical "
              "of an integral constraint or a singular arc); refining alone may not help: "
              f"try {other}a small penalty on the control"
              + ("" if mesh else ", or `mesh:` (it locates switches)"))
    for j, name in enumerate(names):
        keep = np.isfinite(U[:, j])
        u, tt = U[keep, j], t[keep]
        if len(u) < 6:
            continue
        size = max(float(np.ptp(u)), 1e-4 * max(1.0, float(np.max(np.abs(u)))))   # not noise on a constant
        span = spans[j] if spans is not None else math.inf
        floor = IRREGULAR_RANGE_SHARE * span if math.isfinite(span) else 0.0
        left, right = u[1:-1] - u[:-2], u[1:-1] - u[2:]
        spike = np.minimum(np.abs(left), np.abs(right))
        isolated = (np.sign(left) == np.sign(right)) & (spike > 10 * np.abs(u[2:] - u[:-2])) \
            & (spike > max(0.2 * size, floor))
        d = np.diff(u)
        big = np.abs(d) > max(1e-2 * size, floor)
        alternating = (np.sign(d[1:]) != np.sign(d[:-1])) & big[1:] & big[:-1]
        if alternating.mean() > 0.5:
            notes.append(f"{name} zigzags from node to node ({alternating.mean():.0%} of the steps "
                         f"alternate): {advice}")
        elif isolated.any():
            i = int(np.argmax(np.where(isolated, spike, -np.inf)))
            notes.append(f"{name} jumps at a single node (t = {tt[i + 1]:.6g}): {advice}")
    return notes


END_JUMP_SHARE = 0.25   # an end control this share of its spread off its segment's extrapolation "jumps"


def end_jump(x_end: float, x_others: np.ndarray, u_end: np.ndarray, u_others: np.ndarray,
             size: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per control: whether the value ``u_end`` at a segment's end node ``x_end`` departs by
    more than END_JUMP_SHARE of ``size`` from what the segment's other nodes extrapolate to,
    while those nodes are smooth among themselves (the nearest one predicted by the rest to a
    tenth of that; else the segment holds a switch and its end value may be right); and the
    extrapolated values."""
    from ..transcribe.nodes import lagrange_matrix

    x_others, u_others = np.asarray(x_others, float), np.asarray(u_others, float)
    limit = lagrange_matrix(x_others, np.array([x_end]))[0] @ u_others
    near = int(np.argmin(np.abs(x_others - x_end)))
    rest = np.arange(len(x_others)) != near
    smooth = (lagrange_matrix(x_others[rest], x_others[near:near + 1])[0] @ u_others[rest]) if rest.sum() >= 2 \
        else u_others[rest][0]
    share = END_JUMP_SHARE * np.asarray(size, float)
    return (np.abs(u_end - limit) > share) & (np.abs(smooth - u_others[near]) <= 0.1 * share), limit


def end_control_jumps(t: np.ndarray, U: np.ndarray, names: list[str], breakpoints, mesh: bool = False) -> list[str]:
    """Notes on a control collocated at a phase end (LGR: t_f; LGR-start: t0; LGL: both)
    that jumps there (``end_jump``): a value at one instant that the end conditions do not
    price (a free final state's costate vanishes at t_f), which the NLP sets arbitrarily and
    which bends that segment's states (unseen29: psi(t_f) = 3.71 after 0.927 at every other
    node, the verification's dynamics 3 % off, J right to 1e-10)."""
    bps = np.asarray(breakpoints or [], float)
    if len(bps) < 2 or len(t) < 3:
        return []
    notes = []
    span = max(float(bps[-1] - bps[0]), 1e-300)
    size = np.maximum(np.ptp(U, axis=0), 1e-9)
    for end, at, (a, b) in (("t_f", bps[-1], (bps[-2], bps[-1])), ("t0", bps[0], (bps[0], bps[1]))):
        seg = (t >= a - 1e-12 * span) & (t <= b + 1e-12 * span)
        here = seg & (np.abs(t - at) <= 1e-12 * span)
        others = seg & ~here
        if not here.any() or others.sum() < 2:
            continue
        value = U[np.flatnonzero(here)[0]]
        jumps, limit = end_jump(at, t[others], value, U[others], size)
        notes += [f"{name} at {end} = {at:.6g} is {value[j]:.6g} where its segment's other nodes extrapolate "
                  f"to {limit[j]:.6g}: a value at one end instant that the end conditions do not price (e.g. "
                  "free final states, whose costates vanish there), set by the NLP at will; it bends that "
                  "segment's states" + ("" if mesh else ". `mesh:` ties it to its segment's polynomial")
                  for j, name in enumerate(names) if jumps[j]]
    return notes


def _first_order_size(fn, t, X, U, scale_x, ubounds) -> np.ndarray:
    """Per row and output of ``fn(t, X, U)``: ``sum_j |d fn/dz_j| scale_j`` over the states
    and controls (finite differences), a control's scale its bounds' range, else its
    ``state_scale``."""
    g0 = fn(t, X, U)
    sens = np.zeros(g0.shape)
    for j in range(X.shape[1]):
        h = 1e-6 * scale_x[j]
        Xp = X.copy()
        Xp[:, j] += h
        sens += np.abs(fn(t, Xp, U) - g0) / h * scale_x[j]
    for j, (lo, hi) in enumerate(ubounds):
        # without bounds, the control's scale as a state's (``state_scale``): a control held
        # at one value (u = p = 1 at two LG nodes, 1e-10 apart) is measured against its
        # size, not its spread (a 1e-6 floor made 4e-11 a violation of 3.8e-5; unseen27 FA4)
        su = hi - lo if math.isfinite(hi - lo) and hi > lo else max(float(state_scale(U[:, [j]])[0]), 1e-6)
        h = 1e-6 * su
        Up = U.copy()
        Up[:, j] += h
        sens += np.abs(fn(t, X, Up) - g0) / h * su
    return sens


def integral_scales(funcs, t, X, U, scale_x, ubounds) -> np.ndarray:
    """Per integral: the larger of the integral of |integrand| and of the integrand's
    first-order size (``_first_order_size``). An integrand that vanishes along the solution
    (x' = u x, minimise integral((1 - u) x), u = 1) is measured against what moving its
    arguments by their scales would change, not against 0: the solver's J -1.6e-9 (u 9e-10 over
    its bound, Ipopt's bound relaxation) against the flight's 0 failed the objective check by
    1.57e+03 (unseen23 FA1)."""
    Q = funcs.q(t, X, U)
    sens = _first_order_size(funcs.q, t, X, U, scale_x, ubounds)
    return np.maximum.reduce([np.trapezoid(np.abs(Q), t, axis=0), np.trapezoid(np.nan_to_num(sens), t, axis=0),
                              np.full(Q.shape[1], 1e-12)])


# a point's own first-order size, floored at this share of the constraint's size over the path
LOCAL_SCALE_FLOOR = 1e-3


def path_violations(funcs, t, X, U, G, scale_x, ubounds, gscale) -> np.ndarray:
    """(P, K) relative violations of the path constraints at the points (t, X, U), whose
    values are G: each point's excess over its own first-order size (how much g moves there
    when the states and controls move by their scales), that size floored at
    LOCAL_SCALE_FLOOR x the constraint's size over the path (``path_scales``, ``gscale``).
    Over the path's size alone, a keep-out `x**2 + y**2 >= R**2` with R = 10 on a 4 km
    crossing measured a point at its centre (g short by R^2 = 100) against 1.6e7, the size
    of g far from the zone: 6e-6, "verified" (unseen29). There g's own size is 0, and the
    floor makes the same point 6e-3."""
    local = np.nan_to_num(_first_order_size(funcs.g, t, X, U, scale_x, ubounds), nan=0.0, posinf=np.inf)
    scale = np.maximum(local, LOCAL_SCALE_FLOOR * np.asarray(gscale, float)[None, :])
    return np.column_stack([relative_violation(G[:, k], c.lower, c.upper, scale[:, k])
                            for k, c in enumerate(funcs.path)]) if len(funcs.path) else np.zeros((len(t), 0))


def path_scales(funcs, t, X, U, scale_x, ubounds, G) -> np.ndarray:
    """Per path constraint: the larger of its range on the grid and its first-order size
    ``sum_j |dg/dz_j| scale_j`` over the states and controls (finite differences at the rows)."""
    sens = _first_order_size(funcs.g, t, X, U, scale_x, ubounds)
    return np.maximum.reduce([np.nanmax(sens, axis=0), np.ptp(G, axis=0), np.full(G.shape[1], 1e-12)])
