"""Interpolation tables as SymPy expressions: C2 cubic splines in 1-D, bicubic in 2-D.

Why an expression and not a black box: every back end (Pyomo/ASL, the NumPy NLP, the
verification's re-integration, the certificate's costates) takes SymPy expressions and
differentiates them. A cubic spline through n points is, exactly, a cubic polynomial plus
one truncated power ``r3(u - u_k) = max(u - u_k, 0)**3`` per interior knot (the spline is C2,
so neighbouring pieces differ only in their cubic term). ``r3`` is a SymPy function with
exact derivatives (``3 r2``, ``6 r1``) and a numeric form ``((z + |z|)/2)**3`` that floats,
NumPy arrays and Pyomo expressions all accept; the second derivative is continuous, which is
what Ipopt needs. A 2-D table is the tensor product of two such splines (bicubic).

The spline is the not-a-knot interpolant (SciPy's ``CubicSpline`` default) or the natural
one; beyond the table's ends the end pieces' cubics continue (a warning-free extrapolation:
keep the variables inside the table with bounds when that matters).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

BOUNDARY_CONDITIONS = ("not-a-knot", "natural")


class _Ramp(sp.Function):
    """``max(z, 0)**p`` for p = 1, 2, 3 (subclasses), with exact derivatives."""

    nargs = 1
    power = 1

    @classmethod
    def eval(cls, z):
        if z.is_number and z.is_extended_real:
            return sp.Max(z, 0) ** cls.power

    def _latex(self, printer):
        return r"\left(%s\right)_+^{%d}" % (printer._print(self.args[0]), self.power)


class r1(_Ramp):
    power = 1

    @staticmethod
    def _imp_(z):
        return (z + abs(z)) * 0.5

    def fdiff(self, argindex=1):
        return sp.Heaviside(self.args[0])


class r2(_Ramp):
    power = 2

    @staticmethod
    def _imp_(z):
        return ((z + abs(z)) * 0.5) ** 2

    def fdiff(self, argindex=1):
        return 2 * r1(self.args[0])


class r3(_Ramp):
    power = 3

    @staticmethod
    def _imp_(z):
        return ((z + abs(z)) * 0.5) ** 3

    def fdiff(self, argindex=1):
        return 3 * r2(self.args[0])


RAMPS = {"r1": r1, "r2": r2, "r3": r3}


@dataclass(frozen=True)
class _Axis:
    """One grid axis: the spline space in the normalised coordinate u in [0, 1] and the
    matrix taking data values to basis coefficients."""

    lo: float
    span: float
    knots: tuple[float, ...]          # interior knots (u) with a truncated power
    matrix: np.ndarray                # (4 + len(knots), n): values -> coefficients

    @classmethod
    def of(cls, grid, bc: str) -> "_Axis":
        from scipy.interpolate import CubicSpline

        x = np.asarray(grid, float)
        lo, span = float(x[0]), float(x[-1] - x[0])
        u = (x - lo) / span
        n = len(u)
        rows = []
        for m in range(n):           # the cardinal spline of each data point
            e = np.zeros(n)
            e[m] = 1.0
            if n == 2:
                c = np.array([[0.0], [0.0], [e[1] - e[0]], [e[0]]])
            else:
                c = CubicSpline(u, e, bc_type=bc if n > 3 or bc == "natural" else "not-a-knot").c
                if c.shape[0] < 4:   # SciPy gives a parabola for 3 points not-a-knot
                    c = np.vstack([np.zeros((4 - c.shape[0], c.shape[1])), c])
            a3, a2, a1, a0 = c[:, 0]                  # first piece, in (u - u_0) with u_0 = 0
            jumps = np.diff(c[0]) if c.shape[1] > 1 else np.zeros(0)
            rows.append(np.concatenate([[a0, a1, a2, a3], jumps]))
        matrix = np.array(rows).T
        knots = list(u[1:-1])
        keep = [True] * 4 + [bool(np.any(np.abs(matrix[4 + k]) > 1e-12 * np.abs(matrix).max()))
                             for k in range(len(knots))]
        matrix = matrix[np.array(keep)]
        knots = tuple(float(k) for k, kept in zip(knots, keep[4:]) if kept)
        return cls(lo, span, knots, matrix)

    def basis(self, arg: sp.Expr) -> list[sp.Expr]:
        u = (arg - sp.Float(self.lo)) / sp.Float(self.span)
        return [sp.Integer(1), u, u**2, u**3] + [r3(u - sp.Float(k)) for k in self.knots]


@dataclass(frozen=True)
class Table:
    """A named 1-D or 2-D interpolation table; ``table(*args)`` is its SymPy expression."""

    name: str
    axes: tuple[_Axis, ...]
    coefficients: np.ndarray          # 1-D: (p,), 2-D: (p, q)

    @classmethod
    def build(cls, name: str, grids: list, values, bc: str = "not-a-knot") -> "Table":
        """``grids``: one or two strictly increasing lists; ``values``: a list (1-D) or a
        list of rows, one per point of the first grid (2-D)."""
        if bc not in BOUNDARY_CONDITIONS:
            raise ValueError(f"unknown spline end condition '{bc}'; known: {', '.join(BOUNDARY_CONDITIONS)}")
        if len(grids) not in (1, 2):
            raise ValueError("a table has one or two arguments")
        v = np.asarray(values, float)
        shape = tuple(len(g) for g in grids)
        if v.shape != shape:
            raise ValueError(f"table '{name}': values have shape {list(v.shape)}, the grid needs "
                             f"{list(shape)}" + (" (one row per point of the first grid)" if len(shape) == 2 else ""))
        if not np.all(np.isfinite(v)):
            raise ValueError(f"table '{name}': values must be finite numbers")
        for i, g in enumerate(grids):
            g = np.asarray(g, float)
            if len(g) < 2 or not np.all(np.isfinite(g)) or np.any(np.diff(g) <= 0):
                raise ValueError(f"table '{name}': grid {i + 1} must hold at least two strictly "
                                 "increasing finite numbers")
        axes = tuple(_Axis.of(g, bc) for g in grids)
        coef = axes[0].matrix @ v if len(axes) == 1 else axes[0].matrix @ v @ axes[1].matrix.T
        return cls(name, axes, coef)

    @property
    def arity(self) -> int:
        return len(self.axes)

    def __call__(self, *args: sp.Expr) -> sp.Expr:
        if len(args) != self.arity:
            raise ValueError(f"table '{self.name}' takes {self.arity} argument"
                             f"{'s' * (self.arity > 1)}, got {len(args)}")
        phi = self.axes[0].basis(args[0])
        if self.arity == 1:
            return sp.Add(*[sp.Float(c) * f for c, f in zip(self.coefficients, phi) if c != 0])
        psi = self.axes[1].basis(args[1])
        terms = []
        for i, f in enumerate(phi):
            inner = sp.Add(*[sp.Float(c) * g for c, g in zip(self.coefficients[i], psi) if c != 0])
            if inner != 0:
                terms.append(f * inner)
        return sp.Add(*terms)

    def evaluate(self, *args) -> np.ndarray:
        """Numeric values at arrays of arguments (tests, plots)."""
        x = [np.asarray(a, float) for a in args]
        s = [sp.Symbol(f"a{i}", real=True) for i in range(self.arity)]
        return np.broadcast_to(sp.lambdify(s, self(*s), "numpy")(*x), np.broadcast(*x).shape).astype(float)
