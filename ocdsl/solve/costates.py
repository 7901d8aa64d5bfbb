"""Costate estimates from the multipliers of the collocation equations.

With the defects written ``D X - (h/2) F = 0`` and the running cost integrated with the
quadrature weights w_i, stationarity of the NLP Lagrangian in the controls matches the
continuous condition H_u = 0 when lambda_i = -nu_i / w_i (nu_i the multiplier Ipopt
returns for defect i; Pyomo's sign convention). For LG the end constraint's multiplier
nu_F is added: lambda_i = -(nu_i / w_i + nu_F) (Benson's Gauss costate mapping; the end
state enters through the quadrature). LGL is written in integral form (Lobatto IIIA,
X_i = X_0 + (h/2) sum_j A_ij F_j), so there lambda_j = -(A^T nu)_j / w_j. The mapping is tested against analytic costates.
"""
from __future__ import annotations

import numpy as np

from ..transcribe.nodes import lobatto_integration_matrix
from ..transcribe.pseudospectral import Transcription
from ..transcribe.solution import control_on_state_nodes


def costates(tr: Transcription) -> list[dict[str, np.ndarray]]:
    """Per phase: state name -> costate on the state nodes (NaN where none is defined)."""
    m = tr.model
    out = []
    for pb in tr.phases:
        lay, ph = pb.layout, pb.phase
        nx = len(ph.states)
        lam_c = np.zeros((lay.n_colloc, nx))
        for k in range(lay.mesh.segments):
            sc = lay.mesh.scheme(k)
            if sc.name == "LGL":
                # integral form: the multiplier of node j's dynamics is (A^T nu)_j
                A = lobatto_integration_matrix(sc.degree)
                nu = np.array([[m.dual.get(pb.defects[(k, i, j)], 0.0) if i > 0 else 0.0
                                for j in range(nx)] for i in range(sc.degree)])
                lam_c[lay.colloc[k]] = -(A.T @ nu) / np.asarray(sc.weights)[:, None]
                continue
            for i, cn in enumerate(lay.colloc[k]):
                for j in range(nx):
                    nu = m.dual.get(pb.defects[(k, i, j)], 0.0)
                    end = m.dual.get(pb.ends[(k, j)], 0.0) if pb.ends else 0.0
                    lam_c[cn, j] = -(nu / float(sc.weights[i]) + end)
        on_nodes = control_on_state_nodes(pb, lam_c)
        out.append({s.name: on_nodes[:, j] for j, s in enumerate(ph.states)})
    return out
