"""A bracketed root of a scalar function: Brent's method (zeroin), in plain Python.

The mesh's switch, corner and junction locators each find roots to 1e-14-1e-15 on a
bracket; ``scipy.optimize.brentq`` did that, but importing ``scipy.optimize`` cost about
0.2 s of CPU of a mesh run (it loads scipy.sparse, linalg and special). Same contract as
SciPy's: a sign change on [a, b] is required (ValueError otherwise), the root is returned
to ``xtol + rtol |x|``, RuntimeError after ``maxiter`` steps (tests/test_roots.py compares
the two).
"""
from __future__ import annotations

import sys

EPS = sys.float_info.epsilon


def brentq(f, a: float, b: float, xtol: float = 2e-12, rtol: float = 4 * EPS,
           maxiter: int = 100) -> float:
    a, b = float(a), float(b)
    fa, fb = float(f(a)), float(f(b))
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if (fa > 0) == (fb > 0):
        raise ValueError("f(a) and f(b) must have different signs")
    c, fc = a, fa              # c brackets the root with b; a is the previous iterate
    d = e = b - a
    for _ in range(maxiter):
        if (fb > 0) == (fc > 0):
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):   # b is the best estimate so far
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 0.5 * (xtol + rtol * abs(b))
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:          # secant
                p, q = 2.0 * m * s, 1.0 - s
            else:               # inverse quadratic interpolation
                q, r = fa / fc, fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:               # the interpolation would leave the bracket or creep: bisect
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else (tol if m > 0 else -tol)
        fb = float(f(b))
    raise RuntimeError(f"no root to {xtol:g} in {maxiter} iterations")
