"""Read a solved transcription back as time histories on the state nodes."""
from __future__ import annotations

import numpy as np
import pyomo.environ as pyo

from ..result import PhaseTrajectory
from .nodes import lagrange_matrix
from .pseudospectral import PhaseBlock, Transcription


def phase_times(pb: PhaseBlock) -> tuple[float, float]:
    return float(pyo.value(pb.block.t0)), float(pyo.value(pb.block.tf))


def control_on_state_nodes(pb: PhaseBlock, U: np.ndarray) -> np.ndarray:
    """Controls (given at collocation nodes) on the state nodes, by each segment's polynomial.

    Where a state node is a collocation node the value is exact; elsewhere (segment starts
    for LGR, both ends for LG) it is the segment's interpolating polynomial extrapolated.
    """
    lay = pb.layout
    out = np.full((lay.n_state_nodes, U.shape[1]), np.nan)
    for k in range(lay.mesh.segments):
        sc = lay.mesh.scheme(k)
        nodes = lay.support[k]
        targets = list(nodes) + ([lay.end[k]] if lay.end[k] not in nodes else [])
        a, b = lay.mesh.breakpoints[k], lay.mesh.breakpoints[k + 1]
        tau = 2.0 * (lay.s_state[targets] - a) / (b - a) - 1.0
        vals = lagrange_matrix(np.asarray(sc.colloc), tau) @ U[lay.colloc[k]] if len(sc.colloc) > 1 \
            else np.repeat(U[lay.colloc[k]], len(targets), axis=0)
        for row, n in enumerate(targets):
            if k == 0 or n != nodes[0]:   # a shared start belongs to the previous segment's end
                out[n] = vals[row]
    return out


def extract(tr: Transcription) -> list[PhaseTrajectory]:
    out = []
    for pb in tr.phases:
        ph, lay, b = pb.phase, pb.layout, pb.block
        nx, nu = len(ph.states), len(ph.controls)
        X = np.array([[pyo.value(b.X[n, j]) for j in range(nx)] for n in range(lay.n_state_nodes)])
        U = np.array([[pyo.value(b.U[i, j]) for j in range(nu)] for i in range(lay.n_colloc)]).reshape(lay.n_colloc, nu)
        t0, tf = phase_times(pb)
        time = t0 + (tf - t0) * lay.s_state
        Us = control_on_state_nodes(pb, U)
        collocated = np.zeros(lay.n_state_nodes)
        for k in range(lay.mesh.segments):
            collocated[lay.colloc_state[k]] = 1.0
        out.append(PhaseTrajectory(
            ph.name, time,
            states={s.name: X[:, j] for j, s in enumerate(ph.states)},
            controls={c.name: Us[:, j] for j, c in enumerate(ph.controls)},
            extra={"collocated": collocated}))
    return out
