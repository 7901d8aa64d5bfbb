"""Clamped B-spline bases on [a, b] (pure NumPy).

A spline of degree ``p`` with ``n`` control points ``c`` is ``y(x) = sum_i B_i(x) c_i``.
The clamped (open-uniform) knot vector repeats each end ``p + 1`` times and spaces the
``n - p - 1`` interior knots uniformly, so that ``y(a) = c_0``, ``y(b) = c_{n-1}`` and the
curve is ``C^{p-1}`` at every interior knot. In the seed's terms (eq. (22),
``P = l (k - s) + s`` with order ``k = p + 1`` and smoothness ``s = k - 1``), ``l`` pieces
give ``n = l + p`` control points: 10 pieces of degree 5 give the paper's 15.

:func:`basis_matrix` returns the ``(len(x), n)`` matrix of the ``d``-th derivatives of
the basis functions (Cox-de Boor recursion; derivatives by the standard difference
formula applied to lower-degree bases). Checked against :class:`scipy.interpolate.BSpline`.
"""
from __future__ import annotations

import functools

import numpy as np

__all__ = ["clamped_knots", "basis_matrix", "n_pieces", "greville"]


def clamped_knots(degree: int, n_ctrl: int, a: float = 0.0, b: float = 1.0) -> np.ndarray:
    """Clamped uniform knot vector of length ``n_ctrl + degree + 1``."""
    if degree < 0:
        raise ValueError(f"degree must be >= 0, got {degree}")
    if n_ctrl < degree + 1:
        raise ValueError(f"need at least degree + 1 = {degree + 1} control points, got {n_ctrl}")
    if not b > a:
        raise ValueError(f"need a < b, got [{a}, {b}]")
    inner = np.linspace(a, b, n_ctrl - degree + 1)
    return np.concatenate([np.full(degree, a), inner, np.full(degree, b)])


def n_pieces(degree: int, n_ctrl: int) -> int:
    """Number of polynomial pieces (knot spans of positive length)."""
    return n_ctrl - degree


def greville(degree: int, n_ctrl: int, a: float = 0.0, b: float = 1.0) -> np.ndarray:
    """Greville abscissae (knot averages): where control points 'sit'; good for a
    least-squares-free initial guess y(greville_i) ~ c_i."""
    t = clamped_knots(degree, n_ctrl, a, b)
    if degree == 0:
        return 0.5 * (t[:-1] + t[1:])
    return np.array([t[i + 1:i + degree + 1].mean() for i in range(n_ctrl)])


def _basis(t: np.ndarray, degree: int, x: np.ndarray) -> np.ndarray:
    """Values of all ``len(t) - degree - 1`` basis functions of ``degree`` at ``x``
    (the recursion runs over all spans at once: a flat build evaluates thousands of single
    points, where a Python loop over the spans cost 4 ms per point at 165 control points)."""
    n_spans = len(t) - 1
    lo, hi = t[:-1], t[1:]
    nonempty = hi > lo
    # degree 0: indicator of [t_i, t_{i+1}); the last non-empty span is closed at b
    last = int(np.flatnonzero(nonempty).max())
    upper = x[:, None] < hi[None, :]
    upper[:, last] = x <= hi[last]
    B = ((x[:, None] >= lo[None, :]) & upper & nonempty[None, :]).astype(float)
    for k in range(1, degree + 1):
        i = np.arange(n_spans - k)
        d1 = t[i + k] - t[i]
        d2 = t[i + k + 1] - t[i + 1]
        # a zero-length support contributes nothing (0/0 is avoided, not masked afterwards)
        left = (x[:, None] - t[i]) / np.where(d1 > 0, d1, 1.0) * B[:, :-1] * (d1 > 0)
        right = (t[i + k + 1] - x[:, None]) / np.where(d2 > 0, d2, 1.0) * B[:, 1:] * (d2 > 0)
        B = left + right
    return B


@functools.lru_cache(maxsize=64)
def _derivative_operator(degree: int, n_ctrl: int, deriv: int, a: float, b: float) -> np.ndarray:
    """Maps the degree-``(degree - deriv)`` basis values to the ``deriv``-th derivatives of
    the ``n_ctrl`` degree-``degree`` basis functions (the same for every point: made once)."""
    t = clamped_knots(degree, n_ctrl, a, b)
    # d^k/dx^k of the degree-p basis = lower-degree basis times a difference operator:
    # B'_{i,p} = p (B_{i,p-1}/(t_{i+p}-t_i) - B_{i+1,p-1}/(t_{i+p+1}-t_{i+1}))
    coeff = np.eye(n_ctrl)                       # rows: control points, columns: bases
    for q in range(degree, degree - deriv, -1):
        n_q = coeff.shape[1]
        new = np.zeros((n_ctrl, n_q + 1))
        for i in range(n_q):
            d1 = t[i + q] - t[i]
            d2 = t[i + q + 1] - t[i + 1]
            if d1 > 0:
                new[:, i] += q * coeff[:, i] / d1
            if d2 > 0:
                new[:, i + 1] -= q * coeff[:, i] / d2
        coeff = new
    operator = coeff.T
    operator.flags.writeable = False       # cached: shared by every caller
    return operator


def basis_matrix(degree: int, n_ctrl: int, x, deriv: int = 0,
                 a: float = 0.0, b: float = 1.0) -> np.ndarray:
    """``M[j, i] = d^deriv B_i / dx^deriv (x_j)`` for the clamped basis on [a, b].

    ``x`` outside [a, b] raises ValueError. Derivatives above ``degree`` are zero.
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    if np.any(x < a - 1e-12 * (b - a)) or np.any(x > b + 1e-12 * (b - a)):
        raise ValueError(f"points outside [{a}, {b}]")
    x = np.clip(x, a, b)
    t = clamped_knots(degree, n_ctrl, a, b)
    if deriv < 0:
        raise ValueError("deriv must be >= 0")
    if deriv > degree:
        return np.zeros((len(x), n_ctrl))
    return _basis(t, degree - deriv, x) @ _derivative_operator(degree, n_ctrl, deriv, float(a), float(b))
