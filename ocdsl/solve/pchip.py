"""The integral of the monotone piecewise cubic (PCHIP, Fritsch and Carlson) through data.

The certificate integrates dH/dt over the nodes with it. Written out in NumPy because
importing ``scipy.interpolate`` for it took 0.15-0.25 s of a 1.7 s run (it pulls in
``scipy.sparse``, ``scipy.optimize`` and ``scipy.special``); the slopes are the ones
``scipy.interpolate.PchipInterpolator`` uses (tests/test_pchip.py compares the two).
"""
from __future__ import annotations

import numpy as np

from ..hermite import hermite_basis


def slopes(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """PCHIP's node derivatives: zero at a local extremum or a flat interval, else the
    weighted harmonic mean of the neighbouring secants; one-sided three-point formulas at
    the ends, limited to keep the shape."""
    h = np.diff(t)
    m = np.diff(y) / h
    if len(t) == 2:
        return np.array([m[0], m[0]])
    d = np.zeros(len(t))
    w1 = 2.0 * h[1:] + h[:-1]
    w2 = h[1:] + 2.0 * h[:-1]
    a, b = m[:-1], m[1:]
    flat = (np.sign(a) != np.sign(b)) | (a == 0.0) | (b == 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inner = (w1 + w2) / (w1 / a + w2 / b)
    d[1:-1] = np.where(flat, 0.0, inner)
    d[0] = _end_slope(h[0], h[1], m[0], m[1])
    d[-1] = _end_slope(h[-1], h[-2], m[-1], m[-2])
    return d


def _end_slope(h0: float, h1: float, m0: float, m1: float) -> float:
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    if np.sign(d) != np.sign(m0):
        return 0.0
    if np.sign(m0) != np.sign(m1) and abs(d) > 3.0 * abs(m0):
        return 3.0 * m0
    return float(d)


def integral_to_end(t, y) -> np.ndarray:
    """``int_{t_k}^{t_N} y`` at every node ``t_k`` of increasing ``t`` (one-dimensional
    ``y``): on each interval the cubic Hermite integral h (y0 + y1) / 2 + h^2 (d0 - d1) / 12,
    exact for the interpolant."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    if len(t) < 3:      # PCHIP through two points is the line: the trapezoid is exact
        seg = 0.5 * (y[1:] + y[:-1]) * np.diff(t)
    else:
        h = np.diff(t)
        d = slopes(t, y)
        seg = 0.5 * h * (y[:-1] + y[1:]) + h * h * (d[:-1] - d[1:]) / 12.0
    return np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])


def segment_integral_to_end(t, y, breakpoints) -> np.ndarray | None:
    """``int_{t_k}^{t_N} y`` at every node with, on each segment between ``breakpoints``, the
    polynomial through that segment's nodes (the collocation's own interpolant: spectrally
    accurate on smooth data where PCHIP is second order at extrema), or None when a segment
    holds fewer than two nodes or a node lies outside the breakpoints. A node on a
    breakpoint is fitted by both segments."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    b = np.asarray(breakpoints, float)
    if len(b) < 2 or len(t) < 2:
        return None
    span = b[-1] - b[0]
    eps = 1e-9 * max(abs(span), 1e-300)
    if t[0] < b[0] - eps or t[-1] > b[-1] + eps:
        return None
    whole = np.zeros(len(b) - 1)              # each segment's integral
    to_seg_end = np.full(len(t), np.nan)      # from a node to its segment's end
    owner = np.clip(np.searchsorted(b, t - eps, side="right") - 1, 0, len(b) - 2)
    for k in range(len(b) - 1):
        inside = (t >= b[k] - eps) & (t <= b[k + 1] + eps)
        if int(inside.sum()) < 2:
            return None
        half = 0.5 * (b[k + 1] - b[k])
        x = (t[inside] - b[k]) / half - 1.0
        coef = np.polynomial.legendre.legfit(x, y[inside], int(inside.sum()) - 1)
        prim = np.polynomial.legendre.legint(coef)
        end = np.polynomial.legendre.legval(1.0, prim)
        whole[k] = half * (end - np.polynomial.legendre.legval(-1.0, prim))
        mine = owner == k
        to_seg_end[mine] = half * (end - np.polynomial.legendre.legval((t[mine] - b[k]) / half - 1.0, prim))
    later = np.concatenate([np.cumsum(whole[::-1])[::-1][1:], [0.0]])   # segments after k
    return to_seg_end + later[owner]


def interpolate(t, Y, tt) -> np.ndarray:
    """The PCHIP interpolant through the rows ``(t, Y)`` (Y (N, k)) at ``tt`` (P,) -> (P, k),
    held at the end values outside [t[0], t[-1]]."""
    t, Y, tt = np.asarray(t, float), np.asarray(Y, float), np.clip(np.asarray(tt, float), t[0], t[-1])
    if len(t) < 2:
        return np.repeat(Y[:1], len(tt), axis=0)
    D = np.column_stack([slopes(t, Y[:, j]) for j in range(Y.shape[1])])
    k = np.clip(np.searchsorted(t, tt, side="right") - 1, 0, len(t) - 2)
    h = (t[k + 1] - t[k])[:, None]
    h00, h10, h01, h11 = hermite_basis((tt - t[k])[:, None] / h)
    return h00 * Y[k] + h10 * h * D[k] + h01 * Y[k + 1] + h11 * h * D[k + 1]
