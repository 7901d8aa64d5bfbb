"""A phase's functions as NumPy callables, vectorised over points: the dynamics ``f``, its
state Jacobian, the integrands of the phase's integrals and its path constraints, with the
constants and the free parameters' solved values substituted."""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np
import sympy as sp

from ..hermite import hermite_basis
from ..symbolic.model import TIME
from ..symbolic.numbers import substitute_numbers   # exp(885 - r/H) kept whole
from ..symbolic.numeric import family                # printed once, then from the disk cache
from ..symbolic.problem import Phase


class UnresolvedSymbols(ValueError):
    """An expression still holds symbols that neither the phase nor the result gives a value."""


def _vectorised(fn, exprs: list[sp.Expr], owner):
    def evaluate(t, X, U) -> np.ndarray:
        """(P,), (P, n), (P, m) -> (P, len(exprs))"""
        P = len(t)
        out = fn(t, *X.T, *U.T, *owner.free_values)
        arr = np.empty((P, len(exprs)))
        for i, entry in enumerate(out):
            arr[:, i] = entry      # a constant entry (a number) fills its column
        return arr

    return evaluate


class PhaseFunctions:
    """``f``, ``df/dx``, integrands and path constraints of one phase at fixed parameters.

    ``values`` maps parameter names (constants given at run time, free parameters' solved
    values) to numbers; the phase's own constants are substituted first. Parameters named in
    ``free`` stay arguments of the generated code, valued by ``bind`` (mesh refinement: the
    free parameters change from mesh to mesh, the code, cached on disk, does not)."""

    def __init__(self, phase: Phase, values: Mapping[str, float], integrals: Mapping[sp.Symbol, sp.Expr],
                 free: tuple[str, ...] = ()):
        self.phase = phase
        self.states, self.controls = list(phase.states), list(phase.controls)
        self.n, self.m = len(self.states), len(self.controls)
        subs = {k: sp.Float(v) for k, v in phase.constants.items()}
        by_name = {str(k): k for k in phase.model.parameters}
        own = {s.name for s in (*phase.states, *phase.controls)}
        self.free = tuple(free)
        self.free_values: tuple = ()
        for name, v in values.items():
            if name in own or name in self.free:  # another phase's constant of that name, not this phase's variable
                continue
            key = by_name.get(name, sp.Symbol(name, real=True))
            subs.setdefault(key, sp.Float(float(v)))
        self._subs = subs
        f = [substitute_numbers(e, subs) for e in phase.rhs()]
        self.integral_symbols = list(integrals)
        self.integrands = [str(e) for e in integrals.values()]   # as written, for messages
        q = [substitute_numbers(phase.substitute(e), subs) for e in integrals.values()]
        self.path = list(phase.path)
        g = [substitute_numbers(phase.substitute(c.expr), subs) for c in self.path]
        self.path_exprs = g          # for the controls' projection (verify/admissible.py)
        present = {str(x): x for e in f + q + g for x in e.free_symbols}
        free_syms = [present.get(name, by_name.get(name, sp.Symbol(name, real=True))) for name in self.free]
        allowed = set(self.states) | set(self.controls) | {TIME} | set(free_syms)
        left = set().union(*(e.free_symbols for e in f + q + g)) - allowed if (f or q or g) else set()
        if left:
            raise UnresolvedSymbols(f"phase {phase.name!r}: no value for {sorted(s.name for s in left)}")
        args = [TIME, *self.states, *self.controls, *free_syms]
        # ``point``: one point at a time (what an adaptive integrator asks for), plain floats
        # through ``math``, ~50x cheaper per call than the array path at one point
        fns = family(args, ("verify", f, q, g),
                     lambda: {"f": (f, "numpy"), "q": (q, "numpy"), "g": (g, "numpy"), "point": (f + q, "math")})
        self.f = _vectorised(fns["f"], f, self)
        self.q = _vectorised(fns["q"], q, self) if q else None
        self.g = _vectorised(fns["g"], g, self) if g else None
        self.time_dependent = any(TIME in e.free_symbols for e in f + q)
        self._point = fns["point"]

    def bind(self, values: Mapping[str, float]) -> "PhaseFunctions":
        """Values of the ``free`` parameters for the calls that follow."""
        self.free_values = tuple(float(values[name]) for name in self.free)
        return self

    def augmented_point(self, t: float, y, u) -> np.ndarray:
        """Right-hand side of ``[x; integrals]`` at one point (NaN where undefined)."""
        try:
            return np.array(self._point(t, *y.tolist()[:self.n], *u, *self.free_values), float)
        except (ValueError, OverflowError, ZeroDivisionError):
            return np.full(len(y), np.nan)

    def augmented_pair(self, t: float, y, u) -> np.ndarray:
        """The right-hand side of two stacked ``[x; integrals]`` (``y`` of length 2 (n + n_q))
        under one control ``u``: the global and the local pass of one piece in one call."""
        w = len(y) // 2
        v = y.tolist()
        p = self.free_values
        try:
            return np.array(self._point(t, *v[:self.n], *u, *p) + self._point(t, *v[w:w + self.n], *u, *p), float)
        except (ValueError, OverflowError, ZeroDivisionError):
            return np.full(len(y), np.nan)

    def fx(self, t, X, U, scale) -> np.ndarray:
        """df/dx at the points (P, n, n), by forward differences (for the stiffness estimate
        only: cheaper than a symbolic Jacobian of a large model) of step 1e-7 x the state's
        size at the point, at least its median size over the points (its scale where that is
        0): a step of 1e-7 x its range over a trajectory that diverged to 7e26 at its end made
        x' = x^3 + u look stiff (5e39) at x = 1.2."""
        f0 = self.f(t, X, U)
        J = np.empty((len(t), self.n, self.n))
        typical = np.median(np.abs(X), axis=0) if len(X) else np.zeros(self.n)
        for j in range(self.n):
            size = np.maximum(np.abs(X[:, j]), typical[j])
            h = 1e-7 * np.where(size > 0, size, scale[j])
            Xp = X.copy()
            Xp[:, j] += h
            J[:, :, j] = (self.f(t, Xp, U) - f0) / h[:, None]
        return J

    def augmented(self, t, Y, U) -> np.ndarray:
        """Right-hand side of ``[x; integrals]`` (P, n + n_q)."""
        X = Y[:, :self.n]
        parts = [self.f(t, X, U)]
        if self.q is not None:
            parts.append(self.q(t, X, U))
        return np.concatenate(parts, axis=1)


def controls_at(uf, tt, X) -> np.ndarray:
    """The control ``uf`` at the times ``tt`` with the states ``X`` there: a control projected
    onto its path constraints (verify/admissible.py) depends on them, an interpolant alone not."""
    return uf.at(tt, X) if getattr(uf, "state_dependent", False) else uf.at(tt)


# at most this many interpolated points in all: a larger phase gets them on every k-th interval
MAX_BETWEEN = 200_000


def between_points(funcs: PhaseFunctions, uf, grid: np.ndarray, X: np.ndarray, per: int):
    """``per`` points inside every interval of ``grid`` with states from the cubic Hermite
    interpolant of ``X`` and its rates ``f`` (error about h^4 max|x^(4)|/384, far below the
    verification's tolerance at the dense grid's spacing): what a check at the grid alone
    cannot see, e.g. a path crossing an obstacle smaller than the spacing. No interval
    straddles a control jump: the grid holds every breakpoint."""
    if per <= 0 or len(grid) < 2:
        return np.zeros(0), np.zeros((0, X.shape[1]))
    h = np.diff(grid)
    keep = np.flatnonzero(h > 0)
    if len(keep) * per > MAX_BETWEEN:
        keep = keep[:: int(math.ceil(len(keep) * per / MAX_BETWEEN))]
    # the rates at each interval's ends with the controls from inside it: at a breakpoint the
    # control jumps, and the other side's rate bends the interpolant (0.008 past v <= 0.5)
    start, end, hk = grid[keep], grid[keep + 1], h[keep][:, None]
    Fa = funcs.f(start, X[keep], controls_at(uf, start + 1e-7 * hk[:, 0], X[keep]))
    Fb = funcs.f(end, X[keep + 1], controls_at(uf, end - 1e-7 * hk[:, 0], X[keep + 1]))
    s = np.arange(1, per + 1) / (per + 1)
    basis = hermite_basis(s)
    terms = [X[keep], hk * Fa, X[keep + 1], hk * Fb]
    Xs = sum(w[None, :, None] * v[:, None, :] for w, v in zip(basis, terms))
    ts = start[:, None] + hk * s[None, :]
    return ts.ravel(), Xs.reshape(-1, X.shape[1])
