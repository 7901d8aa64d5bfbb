"""The boundary control of a bounded state (the control that keeps it on its bound), derived
symbolically within a time and memory bound (``budget.bounded``) and once per phase."""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from .budget import Budget, bounded

_DERIVED: dict = {}   # id(phase) -> (phase, derivation): one derivation per phase and run
_CACHE: dict = {}     # (id(phase), free symbols) -> (phase, callables)


def _derive(ph, max_order: int) -> dict:
    """Per bounded state j: (order q, control index i, kind, expression), kind "linear" with
    the expression u_b(x, t) when the q-th derivative is affine in the control, "root" with
    the q-th derivative c(x, u, t) itself otherwise (solved numerically for u)."""
    from ...symbolic.model import TIME

    f = list(ph.rhs())
    out = {}
    for j, s in enumerate(ph.states):
        lo, hi = ph.bounds_of(s)
        if not (math.isfinite(lo) or math.isfinite(hi)):
            continue
        c = s
        for q in range(1, max_order + 1):
            c = sum(sp.diff(c, x) * fx for x, fx in zip(ph.states, f)) + sp.diff(c, TIME)
            present = [i for i, u in enumerate(ph.controls) if c.has(u)]
            if not present:
                continue
            if len(present) > 1:
                break
            i = present[0]
            u = ph.controls[i]
            slope = sp.diff(c, u)
            # no sympy.solve: on large models it was what took the memory; an affine
            # derivative is solved by hand, anything else numerically at each point
            if not slope.has(u):
                out[j] = (q, i, "linear", -c.xreplace({u: 0}) / slope)
            else:
                out[j] = (q, i, "root", c)
            break
    return out


def _numeric_root(c_fun, lo: float, hi: float):
    """x..., t, p... -> the control u in [lo, hi] with c(x, u, t, p) = 0 (NaN without one)."""
    from .roots import brentq

    a = lo if math.isfinite(lo) else -1e6
    b = hi if math.isfinite(hi) else 1e6
    grid = np.linspace(a, b, 33)

    def ub(*xtp):
        with np.errstate(all="ignore"):
            vals = [float(c_fun(u, *xtp)) for u in grid]
        for k in range(len(grid) - 1):
            if math.isfinite(vals[k]) and math.isfinite(vals[k + 1]) and vals[k] * vals[k + 1] <= 0:
                return brentq(lambda u: float(c_fun(u, *xtp)), grid[k], grid[k + 1], xtol=1e-14)
        return math.nan

    return ub


def boundary_controls(ph, free_syms, max_order: int = 3, budget: Budget | None = None) -> dict:
    """Per bounded state j: (order, control index, callable (x..., t, p...) -> u), the control
    that keeps the state on its bound (``boundary control``): the state's time derivatives along
    the dynamics are taken until a control appears (the constraint's order q) and the q-th
    derivative = 0 is solved for that control (Bryson & Ho 1975, sec. 3.11). Bryson-Denham
    x <= l: x'' = u, q = 2, u_b = 0; Goddard v <= v_max: v' = 0, q = 1, u_b = (D + m/r^2)/T_max.
    States whose derivatives meet several controls at once, or none up to ``max_order``, are
    left out. The derivation runs once per phase within ``budget`` (skipped, with a note, past
    it; shuttle re-entry: 88 s and 2.7 GB in sympy.solve before, for no result)."""
    from ...symbolic.model import TIME

    budget = budget or Budget()
    key = (id(ph), tuple(free_syms))
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is ph:
        return hit[1]
    done = _DERIVED.get(id(ph))
    if done is None or done[0] is not ph:
        derived = bounded(_derive, (ph, max_order), budget, f"boundary control of phase {ph.name!r}") or {}
        if len(_DERIVED) > 64:
            _DERIVED.clear()
        _DERIVED[id(ph)] = done = (ph, derived)
    derived = done[1]
    out = {}
    args = list(ph.states) + [TIME] + list(free_syms)
    for j, (q, i, kind, expr) in derived.items():
        if kind == "linear":
            out[j] = (q, i, sp.lambdify(args, expr, "numpy"))
        else:
            lo, hi = ph.bounds_of(ph.controls[i])
            c_fun = sp.lambdify([ph.controls[i]] + args, expr, "math")
            out[j] = (q, i, _numeric_root(c_fun, lo, hi))
    if len(_CACHE) > 64:
        _CACHE.clear()
    _CACHE[key] = (ph, out)
    return out
