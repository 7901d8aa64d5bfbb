"""The problem's boundary conditions, links and integral constraints at the returned t_f,
evaluated with every phase flown from its initial state (``estimate.phase_end``), not with
the NLP's end values and quadratures: a discrete solution can meet them on its nodes while
the trajectory it stands for misses them (the error estimate of each segment alone does
not see errors that add up over the phase)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...verify.checks import evaluate, relative_violation, sensitivity_scale


@dataclass
class TerminalError:
    error: float          # largest relative violation (0 without conditions)
    where: str            # the condition's text
    flown: str = "flown from x(t0)"   # how the ends were obtained (drive.py: piece by piece where unstable)


def terminal_error(problem, ends: dict, params: dict) -> TerminalError:
    """Largest violation of ``problem.boundary`` (relative, as the verification measures it:
    over ``sensitivity_scale``) with the re-integrated ends ``ends`` (phase name ->
    ``PhaseEnd``); ``params``: free parameter symbol -> value."""
    point: dict = {s: float(v) for s, v in params.items()}
    scales: dict = {s: max(abs(float(v)), 1e-6) for s, v in params.items()}
    if any(ends.get(ph.name) is None for ph in problem.phases):
        return TerminalError(0.0, "")
    # a phase's times are measured against the whole horizon, not the phase's own length: a
    # phase the optimum collapses (length 3.5e-11) made `a.tf - a.t0 >= 0`, broken by 3.5e-11,
    # an error of 0.5 on every mesh (unseen44 F2: refined to 3,324 variables, J right)
    horizon = max(max(e.tf for e in ends.values()) - min(e.t0 for e in ends.values()), 1e-12)
    for ph in problem.phases:
        e = ends[ph.name]
        point[ph.t0_symbol], point[ph.tf_symbol] = e.t0, e.tf
        scales[ph.t0_symbol] = scales[ph.tf_symbol] = max(abs(e.tf - e.t0), horizon)
        for k, s in enumerate(ph.integrals):
            point[s], scales[s] = float(e.q_end[k]), float(e.q_scale[k])
    for s, bv in problem.boundary_values.items():
        e = ends.get(bv.phase)
        ph = problem.phase(bv.phase)
        if bv.var in ph.states:
            j = list(ph.states).index(bv.var)
            point[s] = float(e.x0[j] if bv.which == "t0" else e.x_end[j])
            scales[s] = float(e.x_scale[j])
        elif bv.var in ph.controls:
            j = list(ph.controls).index(bv.var)
            point[s] = float(e.u0[j] if bv.which == "t0" else e.u_end[j])
            scales[s] = max(abs(point[s]), 1e-6)
    worst = TerminalError(0.0, "")
    for c in problem.boundary:
        if not c.expr.free_symbols <= set(point):
            continue
        v = evaluate(c.expr, point)
        if not math.isfinite(v):
            return TerminalError(math.inf, c.text or str(c.expr))
        viol = float(relative_violation(np.array([v]), c.lower, c.upper, 1.0)[0])
        if viol > 0:
            viol /= sensitivity_scale(c.expr, point, scales)
        if viol > worst.error:
            worst = TerminalError(viol, c.text or str(c.expr))
    return worst
