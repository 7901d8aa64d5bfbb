"""Costate estimates from the multipliers of the collocation equations.

With the defects written ``D X - (h/2) F = 0`` and the running cost integrated with the
quadrature weights w_i, stationarity of the NLP Lagrangian in the controls matches the
continuous condition H_u = 0 when lambda_i = -nu_i / w_i (nu_i the multiplier Ipopt
returns for defect i; Pyomo's sign convention). For LG the end constraint's multiplier
nu_F is added: lambda_i = -(nu_i / w_i + nu_F) (Benson's Gauss costate mapping; the end
state enters through the quadrature). LGL is written in integral form (Lobatto IIIA,
X_i = X_0 + (h/2) sum_j A_ij F_j), so there lambda_j = -(A^T nu)_j / w_j. The mapping is tested against analytic costates.

Path-constraint multipliers (:func:`path_multipliers`). Continuous conditions, in the
augmented Hamiltonian ``H_aug = L + lambda^T f + sum_k mu_k g_k``: ``dH_aug/du = 0``.
In the NLP, write ``s = (tf - t0) h/2`` (h the segment's width in normalised time, the
factor of F in the defects) and let nu_i be the defect multipliers of collocation node i,
nu^g_ik the multiplier of path row (i, k), ``g_k(X_i, U_i)`` in [lo_k, hi_k], which enters
the NLP Lagrangian *unscaled*. With Pyomo's signs the Lagrangian is
``J + sum nu_i . (D_i X - s F_i) + sum nu^g_ik g_k(X_i, U_i) + ...`` with
``J = ... + sum_i s w_i L_i``; its derivative in U_i is::

    s w_i L_u - s nu_i^T F_u + sum_k nu^g_ik g_k,u = 0
    => L_u + (-nu_i / w_i)^T F_u + sum_k (nu^g_ik / (s w_i)) g_k,u = 0.

The first factor is the costate above (lambda_i = -nu_i / w_i), so the same equation is
``dH_aug/du = 0`` with::

    mu_k(t_i) = nu^g_ik / (w_i * h/2 * (tf - t0)).

The LG end constraint and the LGL integral form only change which multipliers make
lambda (the F_u term); the path row of node i still carries only ``s w_i`` from the
objective's quadrature, so the formula holds for LG, LGR and LGL alike. In the
minimisation convention mu_k >= 0 at an active upper bound, <= 0 at an active lower bound
and of free sign for an equality. Checked against the analytic multiplier of
``min int u^2/2`` with ``u - 1/2 <= 0`` active on an arc (tests/test_path_multipliers.py).
"""
from __future__ import annotations

import numpy as np

from ..transcribe.nodes import lobatto_integration_matrix
from ..transcribe.pseudospectral import Transcription
from ..transcribe.solution import control_on_state_nodes


def colloc_costates(m, pb) -> np.ndarray:
    """(n_colloc, nx): the costate of one phase at its collocation nodes (module doc)."""
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
    return lam_c


def defect_duals(pb, lam_c: np.ndarray, lam_end: np.ndarray | None = None):
    """The inverse of ``colloc_costates``: defect (and LG end) constraint data -> the
    multiplier that gives the costate ``lam_c`` (n_colloc, nx) at the collocation nodes
    (``lam_end`` (segments, nx): the costate at each segment's end, LG only):
    nu_i = -lambda_i w_i (LGR); nu_F = -lambda(end), nu_i = -(lambda_i + nu_F) w_i (LG);
    LGL: the least-squares nu with nu_0 = 0 and (A^T nu)_j = -lambda_j w_j. Returns a
    pyomo ComponentMap."""
    from pyomo.common.collections import ComponentMap

    lay, ph = pb.layout, pb.phase
    nx = len(ph.states)
    out = ComponentMap()
    for k in range(lay.mesh.segments):
        sc = lay.mesh.scheme(k)
        w = np.asarray(sc.weights, float)
        lam = np.asarray(lam_c[lay.colloc[k]], float)
        if sc.name == "LGL":
            A = lobatto_integration_matrix(sc.degree)
            nu = np.linalg.lstsq(A[1:].T, -(w[:, None] * lam), rcond=None)[0]
            for i in range(1, sc.degree):
                for j in range(nx):
                    out[pb.defects[(k, i, j)]] = float(nu[i - 1, j])
            continue
        end = np.zeros(nx)
        if pb.ends:
            end = -np.asarray(lam_end[k], float)
            for j in range(nx):
                out[pb.ends[(k, j)]] = float(end[j])
        for i in range(len(w)):
            for j in range(nx):
                out[pb.defects[(k, i, j)]] = float(-(lam[i, j] + end[j]) * w[i])
    return out


def costates(tr: Transcription) -> list[dict[str, np.ndarray]]:
    """Per phase: state name -> costate on the state nodes (NaN where none is defined)."""
    out = []
    for pb in tr.phases:
        on_nodes = control_on_state_nodes(pb, colloc_costates(tr.model, pb))
        out.append({s.name: on_nodes[:, j] for j, s in enumerate(pb.phase.states)})
    return out


def path_scale(pb, duration: float) -> np.ndarray:
    """(n_colloc,): w_i * h/2 * (tf - t0) of every collocation node, the factor between a
    path row's multiplier and mu(t_i) (module doc)."""
    lay = pb.layout
    out = np.zeros(lay.n_colloc)
    for k in range(lay.mesh.segments):
        half_h = (lay.mesh.breakpoints[k + 1] - lay.mesh.breakpoints[k]) / 2.0
        out[lay.colloc[k]] = np.asarray(lay.mesh.scheme(k).weights, float) * half_h * duration
    return out


def path_multipliers(tr: Transcription) -> list[dict[str, np.ndarray]]:
    """Per phase: ``mu_<k>`` (k the index in ``phase.path``) -> multiplier on the state
    nodes, NaN on state nodes that are not collocation nodes (see the module doc).

    The path rows are built node by node along the collocation nodes, constraint by
    constraint, so row ``cn * n_path + k`` is constraint k at collocation node cn.
    """
    import pyomo.core as pyo

    m = tr.model
    out = []
    for pb in tr.phases:
        lay, ph, b = pb.layout, pb.phase, pb.block
        npath = len(ph.path)
        if not npath or not hasattr(b, "path"):
            out.append({})
            continue
        if len(b.path) != lay.n_colloc * npath:
            raise ValueError(f"phase {ph.name}: {len(b.path)} path rows, expected "
                             f"{lay.n_colloc} nodes x {npath} constraints")
        duration = float(pyo.value(b.tf)) - float(pyo.value(b.t0))
        mu_c = np.zeros((lay.n_colloc, npath))
        for k in range(lay.mesh.segments):
            sc = lay.mesh.scheme(k)
            half_h = (lay.mesh.breakpoints[k + 1] - lay.mesh.breakpoints[k]) / 2.0
            for i, cn in enumerate(lay.colloc[k]):
                scale = float(sc.weights[i]) * half_h * duration
                for q in range(npath):
                    nu = m.dual.get(b.path[int(cn) * npath + q], 0.0)
                    mu_c[cn, q] = nu / scale
        on_nodes = control_on_state_nodes(pb, mu_c)   # exact at collocation nodes
        collocated = np.zeros(lay.n_state_nodes, bool)
        for k in range(lay.mesh.segments):
            collocated[lay.colloc_state[k]] = True
        on_nodes[~collocated] = np.nan
        out.append({f"mu_{q}": on_nodes[:, q] for q in range(npath)})
    return out
