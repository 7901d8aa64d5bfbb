"""A bang arc at a phase end that holds no collocation node (certificate check ``end_arcs``).

LGR collocates no control at t0 (LG neither at t_f): an arc shorter than the first node
interval is dropped by the solve, and no node check of the certificate sees it. The end row's
states and costates are known, so the switching function there says which bound the control
should take (docs/verification.md).
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ocdsl.symbolic.model import Model

from .nodes import _columns, _hamiltonian_nodes, _Numeric
from .sides import _bounds, _side
from .tolerances import Tolerances


def end_arcs(model: Model, parameter_values: Mapping | None, trajectory, control_bounds, lagrange,
             gain_limit: float, tolerances: Tolerances | None = None) -> dict[str, Any] | None:
    """A bang arc at a phase end that holds no collocation node: at a row of the phase's ends
    with states and costates but no collocated control (LGR's t0; LG's t0 and t_f), the
    switching function dH/du calls for the bound opposite to the one at the nearest collocated
    node, so a switch lies between them and the arc before it is missing from the solution
    (unseen14: x' = u x, maximise int (1 - u) x on [0, 1.02]: u = 1 on [0, 0.02] lost, J 2e-4
    low, optimal, verified). Judged by the gain it predicts: |dH/du| at the end times the time
    to its zero (linear to the node), over half the bound range, above ``gain_limit``. Returns
    the check's record (``passed`` False when such an arc is found), None when nothing applies."""
    tol = tolerances or Tolerances()
    t, X, U, Lam = _columns(model, trajectory)
    if not model.controls or len(t) < 3 or Lam is None:
        return None
    bounds = _bounds(model, control_bounds)
    collocated = np.isfinite(U).all(axis=1) & np.isfinite(Lam).all(axis=1) & np.isfinite(X).all(axis=1)
    if collocated.sum() < 2:
        return None
    num = _Numeric(model, parameter_values, lagrange)
    found = []
    for end, near in ((0, int(np.argmax(collocated))), (len(t) - 1, len(t) - 1 - int(np.argmax(collocated[::-1])))):
        if collocated[end] or not (np.isfinite(X[end]).all() and np.isfinite(Lam[end]).all()) or near == end:
            continue
        rows = np.array([end, near])
        Ur = U[[near, near]]                        # the nearest node's control at both
        _, S, _, _ = _hamiltonian_nodes(num, t[rows], X[rows], Ur, Lam[rows])
        side = _side(U, bounds, tol.saturation)[near]      # the spread over the phase's nodes
        for j, c in enumerate(model.controls):
            lo, hi = bounds[j]
            if side[j] == 0 or not (math.isfinite(lo) and math.isfinite(hi)):
                continue
            s_end, s_near = float(S[0, j]), float(S[1, j])
            # PMP at a bound: dH/du < 0 at the upper one, > 0 at the lower (side * dH/du <= 0)
            if side[j] * s_end <= 0 or side[j] * s_near > 0:
                continue
            to_zero = abs(t[near] - t[end]) * abs(s_end) / (abs(s_end) + abs(s_near))
            gain = 0.5 * abs(s_end) * to_zero * (hi - lo)
            if gain > gain_limit:
                found.append({"control": c.name, "t": float(t[end]), "switching_function": s_end,
                              "nearest_node": float(t[near]), "predicted_gain": gain,
                              "bound_missing": "upper" if side[j] < 0 else "lower"})
    out = {"arcs": found, "gain_limit": gain_limit, "passed": not found}
    if found:
        a = found[0]
        out["reason"] = (f"at t = {a['t']:.6g} the switching function of {a['control']} calls for its "
                         f"{a['bound_missing']} bound, but the nearest collocated control (t = {a['nearest_node']:.6g}) "
                         f"is at the other: a bang arc shorter than that is missing from the solution (J would "
                         f"gain about {a['predicted_gain']:.1e}); a finer mesh there, or `mesh:`")
    return out
