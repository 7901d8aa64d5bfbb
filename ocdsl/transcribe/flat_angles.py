"""Angles of a flat map at the phase's ends, with their winding.

A state the flat map gives as ``atan2(S, C)`` (a heading from the velocity's components)
is known only modulo 2 pi, and the Pyomo form of atan2 is singular on its branch cut (the
negative C axis). A boundary condition on such a state read it through that principal
value: ``th(tf) == 2*pi`` (a loop) could never hold, and ``th(tf) == pi`` (a U-turn) sat on
the cut, so both runs ended at Ipopt's iteration limit (unseen37 F2). Here the value at t0 is
the branch of atan2 centred on the file's ``th(t0)`` (or the principal one without it), and
the value at tf is the branch centred on that start plus the integral of the state's own
dynamics over the phase (Gauss-Legendre on every knot span), which counts the turns. Both
are smooth wherever the direction (C, S) is defined, and exact, not the quadrature's
approximation: the integral only chooses the branch.
"""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from ocdsl.symbolic.model import TIME


def angle_states(fm, model) -> dict[sp.Symbol, tuple[sp.Expr, sp.Expr, sp.Expr]]:
    """state -> (S, C, rate) for each state whose flat map is ``atan2(S, C)``: ``rate`` is its
    dynamics in flat terms. Left out: an angle whose dynamics depend on time explicitly (the
    flat map measures time from the phase start)."""
    out = {}
    rhs = dict(zip(model.states, model.rhs()))
    for x, e in fm.states.items():
        if not isinstance(e, sp.atan2) or x not in rhs or rhs[x].has(TIME):
            continue
        rate = rhs[x].xreplace({**fm.states, **fm.controls})
        out[x] = (e.args[0], e.args[1], rate)
    return out


def branch_at(centre, S, C, sin, cos, atan2):
    """The value of atan2(S, C) in (centre - pi, centre + pi]: ``centre`` plus the angle of
    (C, S) rotated by -centre (``sin``, ``cos``, ``atan2``: Pyomo's or NumPy's)."""
    c, s = cos(centre), sin(centre)
    return centre + atan2(c * S - s * C, c * C + s * S)


def quadrature_rule(degree: int, n_ctrl: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights in [0, 1], degree + 1 per knot span."""
    x, w = np.polynomial.legendre.leggauss(degree + 1)
    knots = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
    a, b = knots[:-1, None], knots[1:, None]
    return (0.5 * (a + b) + 0.5 * (b - a) * x).ravel(), (0.5 * (b - a) * w).ravel()


def unwrap_from(values: np.ndarray, start: float) -> np.ndarray:
    """Principal values made continuous along the rows, shifted by a whole number of turns so
    that the first is ``start`` (an angle exported as atan2 gives it jumped 2 pi at the cut)."""
    values = np.asarray(values, float)
    if len(values) == 0 or not np.all(np.isfinite(values)) or not math.isfinite(start):
        return values
    out = np.unwrap(values)
    return out + 2 * np.pi * round((start - out[0]) / (2 * np.pi))
