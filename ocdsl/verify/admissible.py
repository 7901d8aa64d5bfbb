"""Controls between rows projected onto the set their path constraints allow.

A path constraint affine in one control and free of the others, ``lower <= a(t, x) u_j +
b(t, x) <= upper`` (``u <= 1 - x``, ``2 u + x t >= 0``), bounds that control pointwise given
the state, as a box bound does without it. The NLP meets it at its nodes only; between them
the interpolant of the control overshoots at a corner inside a segment (the control leaving
its bound: 2.35e-5 past ``u <= 1.37 - x`` on 320 LGR segments whose J is right to 3e-7),
exactly as it overshoots a box bound, which the interpolation clips. So the verification
flies the interpolant projected onto the interval these constraints and the box leave at
the flown state at that time: a feedback law ``u(t, x)``. What it then checks is that this
feasible control reproduces the rows: a solution that really needs the excess between its
nodes lags behind its rows once it is taken away, and fails the dynamics and objective
checks. The constraint at the rows themselves, with the exported controls, is checked
separately (:meth:`AffineRules.row_violation`): the projection would hide it there.

A constraint with two controls, or not affine in its control, is not projected (it is
checked on the dense grid as before). Where the interval is empty (the box and the
constraint disagree at that state) or ``a(t, x) = 0``, the box-clipped value is kept and the
dense check reports what it finds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..symbolic.model import TIME
from ..symbolic.numeric import family
from .interpolate import control_rows


@dataclass(frozen=True)
class Rule:
    k: int           # which path constraint (index into funcs.path)
    control: int     # the control it bounds
    lower: float
    upper: float


class AffineRules:
    """The phase's path constraints ``lower <= a(t, x) u_j + b(t, x) <= upper``, with ``a``
    and ``b`` compiled vectorised (``coefficients``) and for one point (``_point``)."""

    def __init__(self, funcs, ubounds):
        self.n = funcs.n
        self.lo = np.array([b[0] for b in ubounds], float)
        self.hi = np.array([b[1] for b in ubounds], float)
        controls = funcs.controls
        rules, exprs = [], []
        for k, (c, e) in enumerate(zip(funcs.path, funcs.path_exprs)):
            used = [j for j, u in enumerate(controls) if u in e.free_symbols]
            if len(used) != 1:
                continue
            u = controls[used[0]]
            a = sp.diff(e, u)
            if a == 0 or u in a.free_symbols:      # not affine in u
                continue
            rules.append(Rule(k, used[0], float(c.lower), float(c.upper)))
            exprs += [a, e.subs(u, 0)]             # e = a u + b, affine in u
        self.rules = rules
        self.by_control = sorted({r.control for r in rules})
        if rules:
            args = [TIME, *funcs.states]
            fns = family(args, ("verify-admissible", exprs),
                         lambda: {"np": (exprs, "numpy"), "point": (exprs, "math")})
            self._np, self._point = fns["np"], fns["point"]

    def __bool__(self) -> bool:
        return bool(self.rules)

    def coefficients(self, tt, X) -> np.ndarray:
        """(P, 2 R): a, b of each rule at the points."""
        P = len(tt)
        out = self._np(np.asarray(tt, float), *np.asarray(X, float).T)
        arr = np.empty((P, len(out)))
        for i, entry in enumerate(out):
            arr[:, i] = np.broadcast_to(np.asarray(entry, float), (P,))
        return arr

    def project(self, tt, X, U) -> np.ndarray:
        """``U`` (P, m), already clipped to the box, projected at the states ``X`` (P, n)."""
        if not self.rules or len(tt) == 0:
            return U
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            C = self.coefficients(tt, X)
            U = U.copy()
            lo = np.repeat(self.lo[None, :], len(tt), axis=0)
            hi = np.repeat(self.hi[None, :], len(tt), axis=0)
            for i, r in enumerate(self.rules):
                a, b = C[:, 2 * i], C[:, 2 * i + 1]
                ok = np.isfinite(a) & np.isfinite(b) & (a != 0)
                p, q = (r.lower - b) / a, (r.upper - b) / a      # a < 0 reverses the interval
                lo[:, r.control] = np.where(ok, np.maximum(lo[:, r.control], np.minimum(p, q)), lo[:, r.control])
                hi[:, r.control] = np.where(ok, np.minimum(hi[:, r.control], np.maximum(p, q)), hi[:, r.control])
            for j in self.by_control:
                fits = lo[:, j] <= hi[:, j]          # empty: keep the box-clipped value
                U[:, j] = np.where(fits, np.minimum(np.maximum(U[:, j], lo[:, j]), hi[:, j]), U[:, j])
        return U

    def project_point(self, t: float, y, u: list) -> list:
        """The same at one point, plain floats (what the integrator calls); ``y`` may hold
        the integrals after the states."""
        try:
            c = self._point(t, *y[:self.n])
        except (ValueError, OverflowError, ZeroDivisionError):
            return u
        lo = {j: self.lo[j] for j in self.by_control}
        hi = {j: self.hi[j] for j in self.by_control}
        for i, r in enumerate(self.rules):
            a, b = float(c[2 * i]), float(c[2 * i + 1])
            if a == 0 or not (math.isfinite(a) and math.isfinite(b)):
                continue
            p, q = (r.lower - b) / a, (r.upper - b) / a
            lo[r.control] = max(lo[r.control], min(p, q))
            hi[r.control] = min(hi[r.control], max(p, q))
        u = list(u)
        for j in self.by_control:
            if lo[j] <= hi[j]:
                u[j] = min(max(u[j], lo[j]), hi[j])
        return u


class Projected:
    """A control interpolant (:mod:`ocdsl.verify.interpolate`) projected by ``rules``: the
    control is then a function of time and state. ``at(tt)`` without states is the base
    interpolant (clipped to the box only)."""

    state_dependent = True

    def __init__(self, base, rules: AffineRules):
        self.base, self.rules = base, rules

    def at(self, tt, X=None) -> np.ndarray:
        U = self.base.at(tt)
        return U if X is None else self.rules.project(np.asarray(tt, float), X, U)

    def piece(self, tt: float):
        """The control on the piece holding ``tt`` as ``u(s, y)`` (``y``: the flown state)."""
        u_of, proj = self.base.piece(tt), self.rules.project_point

        def control(s, y):
            return proj(s, y, u_of(s))

        return control

    def kinks(self, a: float, b: float) -> list[float]:
        # the projection's own kinks move with the flown state, so no cut is placed there;
        # DOP853's step control keeps within 1e-8 at rtol 1e-10 across them (measured 1.3e-9,
        # tests/test_verify_corners.py)
        return self.base.kinks(a, b)

    def __call__(self, tt: float, x=None) -> np.ndarray:
        return self.at(np.array([tt]), None if x is None else np.asarray(x, float)[None, :])[0]


def project(uf, funcs, ubounds):
    """``uf`` projected onto what the phase's control-affine path constraints allow, or
    ``uf`` itself when there are none."""
    if not funcs.path or not funcs.controls:
        return uf
    rules = AffineRules(funcs, ubounds)
    return Projected(uf, rules) if rules else uf


def row_values(funcs, uf, traj, names_u, t, X) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The path constraints ``uf`` projects, at the rows with exported controls: their times
    (R,), values (R, K) with those controls and the rows' states, and which columns hold
    values (the projected constraints; the others are checked on the dense grid)."""
    rules = getattr(uf, "rules", None)
    if not rules:
        return np.zeros(0), np.zeros((0, len(funcs.path))), []
    tr, Ur = control_rows(traj, names_u)
    i = np.clip(np.searchsorted(t, tr), 0, len(t) - 1)
    have = t[i] == tr                  # rows with controls and finite states
    tr, Ur, Xr = tr[have], Ur[have], X[i[have]]
    if len(tr) == 0:
        return tr, np.zeros((0, len(funcs.path))), []
    return tr, funcs.g(tr, Xr, Ur), sorted({r.k for r in rules.rules})
