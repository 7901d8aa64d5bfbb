"""The boundary control of a bounded state (the control that keeps it on its bound), derived
symbolically."""
from __future__ import annotations

import math

import sympy as sp


def boundary_controls(ph, free_syms, max_order: int = 3) -> dict:
    """Per bounded state j: (order, control index, callable (x..., t, p...) -> u), the control
    that keeps the state on its bound (``boundary control``): the state's time derivatives along
    the dynamics are taken until a control appears (the constraint's order q) and the q-th
    derivative = 0 is solved for that control (Bryson & Ho 1975, sec. 3.11). Bryson-Denham
    x <= l: x'' = u, q = 2, u_b = 0; Goddard v <= v_max: v' = 0, q = 1, u_b = (D + m/r^2)/T_max.
    States whose derivatives meet several controls at once, or none up to ``max_order``, or
    whose equation sympy cannot solve uniquely, are left out."""
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
            try:
                sol = sp.solve(sp.Eq(c, 0), ph.controls[i], dict=False)
            except Exception:
                break
            if len(sol) == 1:
                args = list(ph.states) + [TIME] + list(free_syms)
                out[j] = (q, i, sp.lambdify(args, sol[0], "numpy"))
            break
    return out
