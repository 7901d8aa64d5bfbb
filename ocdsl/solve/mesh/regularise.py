"""Optional regularisation of chattering (singular) arcs: w * int (du/ds)^2 ds added to the
objective where the control zigzagged from node to node."""
from __future__ import annotations

import math

import numpy as np

from .segments import solution_arrays, zigzag


def chattering_segments(pb) -> list[tuple[float, float]]:
    """Segments (normalised time) on which a control zigzags from node to node (``zigzag`` on
    the segment's collocation points and the nearest one on either side): the discrete
    solution of a singular arc, where the control is weakly determined and the NLP chatters."""
    lay = pb.layout
    U = solution_arrays(pb)[1]
    bps = lay.mesh.breakpoints
    # steps below 1e-3 of the control's range are solver noise (a bang arc 1e-8 inside its bound)
    span = []
    for j, c in enumerate(pb.phase.controls):
        lo, hi = pb.phase.bounds_of(c)
        span.append(1e-3 * ((hi - lo) if math.isfinite(hi - lo) else 1.0 + np.max(np.abs(U[:, j]))))
    out = []
    for k in range(lay.mesh.segments):
        nodes = list(lay.colloc[k])
        if k > 0:
            nodes = [lay.colloc[k - 1][-1]] + nodes
        if k + 1 < lay.mesh.segments:
            nodes = nodes + [lay.colloc[k + 1][0]]
        if len(nodes) >= 4 and any(zigzag(U[nodes, j], span[j]) for j in range(U.shape[1])):
            out.append((float(bps[k]), float(bps[k + 1])))
    return out


def merge_intervals(old: list, new: list) -> list:
    out = []
    for a, b in sorted([tuple(x) for x in old] + [tuple(x) for x in new]):
        if out and a <= out[-1][1] + 1e-12:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def regularise(tr, regions: dict, weight: float):
    """Add weight * sum over consecutive collocation points inside ``regions`` (per phase,
    normalised-time intervals) of (u_{i+1} - u_i)^2 / (s_{i+1} - s_i) -- a quadrature of
    weight * int (du/ds)^2 ds over the detected chattering arcs -- to the objective (with the
    sign that penalises it). Returns the Pyomo expression of the added term, or None.
    The solved objective is reported without it (``solve_adaptive``)."""
    import pyomo.core as pyo

    if not weight or not any(regions.values()):
        return None
    terms = []
    for pb in tr.phases:
        iv = regions.get(pb.phase.name) or []
        lay, b = pb.layout, pb.block
        sc = lay.s_colloc
        inside = [any(a <= x <= c for a, c in iv) for x in sc]
        nu = len(pb.phase.controls)
        for i in range(lay.n_colloc - 1):
            if inside[i] and inside[i + 1] and sc[i + 1] > sc[i]:
                for j in range(nu):
                    terms.append((b.U[i + 1, j] - b.U[i, j]) ** 2 / float(sc[i + 1] - sc[i]))
    if not terms:
        return None
    m = tr.model
    m.mesh_regularisation = pyo.Expression(expr=weight * sum(terms))
    sign = 1.0 if m.objective.sense == pyo.minimize else -1.0
    m.objective.expr = m.objective.expr + sign * m.mesh_regularisation
    return m.mesh_regularisation
