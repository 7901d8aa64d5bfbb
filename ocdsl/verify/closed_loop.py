"""The verification of a controller file's closed-loop runs.

A closed-loop simulation integrates the plant with its own fixed-step integrator (rk4 or
Euler) under a zero-order-hold control. What the run folder then claims (settling times,
overshoot, costs) stands on that integration, so it is checked like any trajectory: the
recorded control, held between its rows (``previous``), is flown through the plant by the
verification's tight integrator, from the first row and piece by piece, and the recorded
controls are held to the saturation limits. Each law is one phase of a problem built from
the plant model; there are no boundary conditions and no objective to recompute, but each
law's cost is integrated along its pieces and compared with the one it reports (an SDRE
law on explicit Euler reported J 7.9e-4 off while its trajectory verified; unseen22 c20).
"""
from __future__ import annotations

import sympy as sp

from ..symbolic.problem import Objective, Phase, Problem


def closed_loop_problem(model, parameters: dict[str, float], laws: list[str],
                        limits: tuple | None, horizon: float, cost=None) -> Problem:
    """One phase per law: the plant's states and controls, its constants and the
    saturation ``limits`` (lo, hi arrays, or None when the control is not saturated).
    ``cost`` (controlled states, Q, R): each phase integrates 1/2 (x^T Q x + u^T R u) as
    ``<law>.cost``, which the verification compares with the cost the law reports."""
    constants = {p: float(parameters[str(p)]) for p in model.parameters if str(p) in parameters}
    lo, hi = limits if limits is not None else (None, None)
    bounds = {} if lo is None else {u: (float(a), float(b)) for u, a, b in zip(model.controls, lo, hi)}
    integrand = None
    if cost is not None:
        xs, Q, R = cost
        x, u = sp.Matrix(list(xs)), sp.Matrix(list(model.controls))
        integrand = sp.Rational(1, 2) * ((x.T * sp.Matrix(Q) * x)[0] + (u.T * sp.Matrix(R) * u)[0])
    phases = [Phase(law, model, constants, 0.0, float(horizon), sp.Symbol(f"{law}.t0", real=True),
                    sp.Symbol(f"{law}.tf", real=True), control_bounds=dict(bounds),
                    integrals={sp.Symbol(f"{law}.cost", real=True): integrand} if integrand is not None else {})
              for law in laws]
    return Problem(f"{model.name} closed loop", phases, Objective("minimize", sp.Integer(0)))
