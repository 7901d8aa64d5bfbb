"""Warm start of a pseudospectral NLP on a new mesh from the solution on an old one,
multipliers included (``method.mesh.warm_start: multipliers``, docs/mesh-refinement.md).

``take(tr)`` keeps, per phase, what the solution on the old mesh says as functions of
normalised time s in [0, 1] (meshes differ, so NLP indices mean nothing across them):

- states and controls: each old segment's interpolating polynomials;
- the costate lambda(s) at the old collocation nodes (``costates.colloc_costates``), again as
  each old segment's polynomial through its collocation nodes;
- the path-constraint multiplier *densities* mu(s) = nu / (w_i h/2 (tf - t0))
  (``costates.path_scale``, the scaling of ``costates.path_multipliers``) and the same
  densities of the controls' bound multipliers z_L, z_U: each old segment's polynomial through
  its collocation nodes, clipped to the sign of the segment's values where they have one
  (z >= 0; mu >= 0 at an active upper bound);
- the densities of the states' bound multipliers at the interior collocated state nodes,
  interpolated piecewise linearly (which keeps their sign);
- everything that does not live on the mesh -- boundary / event / linkage constraints, the
  bound multipliers of t0, tf, the free parameters and the first and last state nodes (the
  boundary conditions' point multipliers) -- by component name.

``apply(snapshot, tr_new)`` evaluates those on the new mesh, sets the new model's free
variables to the old polynomials' values (exact, where ``transcribe.guess`` interpolates
sampled values linearly) and returns ``ipopt.Multipliers`` for ``ipopt.solve``: defect
multipliers from lambda by ``costates.defect_duals`` (nu_i = -lambda(t_i) w_i for LGR, the
inverse of the costate estimate), path multipliers nu = mu(t_i) w_i h/2 (tf - t0).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .costates import colloc_costates, defect_duals, path_scale
from .ipopt import Multipliers

_BOUND_SUFFIXES = ("ipopt_zL_out", "ipopt_zU_out")


def prepare(model) -> None:
    """Give ``model`` the import suffixes the solver fills with the bound multipliers."""
    import pyomo.core as pyo

    for name in _BOUND_SUFFIXES:
        if model.component(name) is None:
            model.add_component(name, pyo.Suffix(direction=pyo.Suffix.IMPORT))


@dataclass
class PhaseSnapshot:
    layout: object
    X: np.ndarray            # (n_state_nodes, nx)
    U: np.ndarray            # (n_colloc, nu)
    t0: float
    tf: float
    lam: np.ndarray          # (n_colloc, nx) costate at the collocation nodes
    lam_end: np.ndarray      # (segments, nx) costate at each segment's end
    mu: np.ndarray           # (n_colloc, n_path) path multiplier densities
    zu_lo: np.ndarray        # (n_colloc, nu) control bound multiplier densities
    zu_hi: np.ndarray
    zx_lo: np.ndarray        # (n_state_nodes, nx) state bound multiplier densities (NaN: none)
    zx_hi: np.ndarray
    zx_ends: dict            # (node 'first'|'last', j) -> (z_L, z_U) raw


@dataclass
class Snapshot:
    phases: dict = field(default_factory=dict)      # phase name -> PhaseSnapshot
    duals: dict = field(default_factory=dict)       # constraint name -> multiplier (off-mesh ones)
    lower: dict = field(default_factory=dict)       # variable name -> z_L (off-mesh variables)
    upper: dict = field(default_factory=dict)
    values: dict = field(default_factory=dict)      # variable name -> value (off-mesh variables)


def _suffix(model, name):
    return model.component(name) or {}


def _colloc_segment(mesh, s: np.ndarray) -> np.ndarray:
    """The old segment whose collocation polynomial holds s: segments are (a, b] when the
    scheme collocates at the segment end (LGR), else [a, b)."""
    sc = mesh.scheme(0)
    side = "left" if np.isclose(sc.colloc[-1], 1.0) else "right"
    k = np.searchsorted(mesh.breakpoints, s, side=side) - 1
    return np.clip(k, 0, mesh.segments - 1)


def _piecewise_poly(lay, nodes_of_segment, tau_nodes_of_segment, values, s, seg) -> np.ndarray:
    from ..transcribe.nodes import lagrange_matrix

    out = np.zeros((len(s), values.shape[1]))
    bps = lay.mesh.breakpoints
    for k in np.unique(seg):
        sel = seg == k
        a, b = bps[k], bps[k + 1]
        tau = 2.0 * (s[sel] - a) / (b - a) - 1.0
        nodes = np.asarray(tau_nodes_of_segment(k))
        vals = values[nodes_of_segment(k)]
        out[sel] = vals if len(nodes) == 1 else lagrange_matrix(nodes, tau) @ vals
    return out


def _states_at(ps: PhaseSnapshot, s: np.ndarray) -> np.ndarray:
    lay = ps.layout
    seg = np.clip(np.searchsorted(lay.mesh.breakpoints, s, side="right") - 1, 0, lay.mesh.segments - 1)
    return _piecewise_poly(lay, lambda k: lay.support[k], lambda k: lay.mesh.scheme(k).support, ps.X, s, seg)


def _colloc_values_at(ps: PhaseSnapshot, values: np.ndarray, s: np.ndarray) -> np.ndarray:
    lay = ps.layout
    return _piecewise_poly(lay, lambda k: lay.colloc[k], lambda k: lay.mesh.scheme(k).colloc, values, s,
                           _colloc_segment(lay.mesh, s))


def _signed_colloc_values_at(ps: PhaseSnapshot, values: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``_colloc_values_at`` for multipliers whose sign means something (inequality rows, bound
    multipliers): where all of an old segment's values have one sign, the polynomial's values
    taken from that segment are clipped to it (no ringing across a kink to the wrong sign)."""
    lay = ps.layout
    out = _colloc_values_at(ps, values, s)
    seg = _colloc_segment(lay.mesh, s)
    for k in np.unique(seg):
        sel = seg == k
        v = values[lay.colloc[k]]
        lo = np.where(v.min(axis=0) >= 0, 0.0, -np.inf)
        hi = np.where(v.max(axis=0) <= 0, 0.0, np.inf)
        out[sel] = np.clip(out[sel], lo, hi)
    return out


def _linear(s_old: np.ndarray, values: np.ndarray, s: np.ndarray) -> np.ndarray:
    out = np.zeros((len(s), values.shape[1]))
    for j in range(values.shape[1]):
        ok = np.isfinite(values[:, j])
        if ok.any():
            out[:, j] = np.interp(s, s_old[ok], values[ok, j])
    return out


def _z(suffix, var) -> float:
    return float(suffix.get(var, 0.0) or 0.0)


def take(tr) -> Snapshot:
    """What ``apply`` needs from a solved transcription (see the module doc)."""
    import pyomo.core as pyo

    from ..transcribe.solution import continuous_controls, node_values, phase_times

    m = tr.model
    zl, zu = _suffix(m, "ipopt_zL_out"), _suffix(m, "ipopt_zU_out")
    snap = Snapshot()
    on_mesh_cons, on_mesh_vars = set(), set()   # ids: component data are not hashable
    for pb in tr.phases:
        lay, ph, b = pb.layout, pb.phase, pb.block
        nx, nu, npath = len(ph.states), len(ph.controls), len(ph.path)
        N, C = lay.n_state_nodes, lay.n_colloc
        X, U = node_values(pb)
        U = continuous_controls(pb, U)     # the new mesh's nodes read one branch of an angle
        t0, tf = phase_times(pb)
        scale = path_scale(pb, tf - t0)
        lam = colloc_costates(m, pb)
        lam_end = np.zeros((lay.mesh.segments, nx))
        if pb.ends:
            lam_end = np.array([[-m.dual.get(pb.ends[(k, j)], 0.0) for j in range(nx)]
                                for k in range(lay.mesh.segments)], float).reshape(-1, nx)
        else:
            seg_end = np.array([lay.mesh.breakpoints[k + 1] for k in range(lay.mesh.segments)])
            tmp = PhaseSnapshot(lay, X, U, t0, tf, lam, lam_end, None, None, None, None, None, {})
            lam_end = _colloc_values_at(tmp, lam, seg_end)
        mu = np.zeros((C, npath))
        if npath and hasattr(b, "path"):
            for cn in range(C):
                for q in range(npath):
                    mu[cn, q] = m.dual.get(b.path[cn * npath + q], 0.0) / scale[cn]
        zu_lo = np.array([[_z(zl, b.U[i, j]) / scale[i] for j in range(nu)] for i in range(C)]).reshape(C, nu)
        zu_hi = np.array([[_z(zu, b.U[i, j]) / scale[i] for j in range(nu)] for i in range(C)]).reshape(C, nu)
        node_scale = np.full(N, np.nan)
        for k in range(lay.mesh.segments):
            node_scale[lay.colloc_state[k]] = scale[lay.colloc[k]]
        node_scale[[0, N - 1]] = np.nan      # boundary nodes: point multipliers, copied raw
        zx_lo = np.array([[_z(zl, b.X[n, j]) for j in range(nx)] for n in range(N)]).reshape(N, nx) / node_scale[:, None]
        zx_hi = np.array([[_z(zu, b.X[n, j]) for j in range(nx)] for n in range(N)]).reshape(N, nx) / node_scale[:, None]
        ends = {(w, j): (_z(zl, b.X[n, j]), _z(zu, b.X[n, j])) for w, n in (("first", 0), ("last", N - 1))
                for j in range(nx)}
        snap.phases[ph.name] = PhaseSnapshot(lay, X, U, t0, tf, lam, lam_end, mu, zu_lo, zu_hi, zx_lo, zx_hi, ends)
        on_mesh_cons.update(id(c) for c in pb.defects.values())
        on_mesh_cons.update(id(c) for c in pb.ends.values())
        if hasattr(b, "path"):
            on_mesh_cons.update(id(c) for c in b.path.values())
        on_mesh_vars.update(id(v) for v in b.X.values())
        on_mesh_vars.update(id(v) for v in b.U.values())
    for c in m.component_data_objects(pyo.Constraint, active=True):
        if id(c) not in on_mesh_cons and c in m.dual:
            snap.duals[c.name] = float(m.dual[c])
    for v in m.component_data_objects(pyo.Var):
        if id(v) not in on_mesh_vars:
            snap.values[v.name] = v.value
            snap.lower[v.name], snap.upper[v.name] = _z(zl, v), _z(zu, v)
    return snap


def apply(snap: Snapshot, tr, *, primal: bool = True) -> Multipliers:
    """Multipliers for ``tr`` (a new mesh) from ``snap``; with ``primal`` also set the free
    variables' values from the old polynomials (see the module doc)."""
    import pyomo.core as pyo

    m = tr.model
    out = Multipliers()
    for pb in tr.phases:
        ps = snap.phases.get(pb.phase.name)
        if ps is None:
            continue
        lay, ph, b = pb.layout, pb.phase, pb.block
        nx, nu, npath = len(ph.states), len(ph.controls), len(ph.path)
        N, C = lay.n_state_nodes, lay.n_colloc
        if primal:
            X = _states_at(ps, lay.s_state)
            U = _colloc_values_at(ps, ps.U, lay.s_colloc) if nu else np.zeros((C, 0))
            for (vals, var, n_rows, n_cols) in ((X, b.X, N, nx), (U, b.U, C, nu)):
                for r in range(n_rows):
                    for j in range(n_cols):
                        v = var[r, j]
                        if not v.fixed:
                            lo, hi = v.lb, v.ub
                            x = float(vals[r, j])
                            x = max(x, lo) if lo is not None else x
                            x = min(x, hi) if hi is not None else x
                            v.set_value(x, skip_validation=True)
        t0 = float(snap.values.get(b.t0.name, ps.t0)) if isinstance(b.t0, pyo.Var) else float(pyo.value(b.t0))
        tf = float(snap.values.get(b.tf.name, ps.tf)) if isinstance(b.tf, pyo.Var) else float(pyo.value(b.tf))
        scale = path_scale(pb, tf - t0)
        lam = _colloc_values_at(ps, ps.lam, lay.s_colloc)
        lam_end = None
        if pb.ends:
            seg_end = np.array([lay.mesh.breakpoints[k + 1] for k in range(lay.mesh.segments)])
            lam_end = _colloc_values_at(ps, ps.lam, seg_end)
            # at an old segment's end the old end multiplier is exact
            for k, se in enumerate(seg_end):
                hit = np.flatnonzero(np.isclose(ps.layout.mesh.breakpoints[1:], se, rtol=0, atol=1e-14))
                if hit.size:
                    lam_end[k] = ps.lam_end[hit[0]]
        out.constraints.update(defect_duals(pb, lam, lam_end))
        if npath and hasattr(b, "path"):
            mu = _signed_colloc_values_at(ps, ps.mu, lay.s_colloc)
            for cn in range(C):
                for q in range(npath):
                    out.constraints[b.path[cn * npath + q]] = float(mu[cn, q] * scale[cn])
        if nu:
            lo = _signed_colloc_values_at(ps, ps.zu_lo, lay.s_colloc) * scale[:, None]
            hi = _signed_colloc_values_at(ps, ps.zu_hi, lay.s_colloc) * scale[:, None]
            for i in range(C):
                for j in range(nu):
                    out.lower[b.U[i, j]], out.upper[b.U[i, j]] = float(lo[i, j]), float(hi[i, j])
        node_scale = np.full(N, np.nan)
        for k in range(lay.mesh.segments):
            node_scale[lay.colloc_state[k]] = scale[lay.colloc[k]]
        zlo = _linear(ps.layout.s_state, ps.zx_lo, lay.s_state) * node_scale[:, None]
        zhi = _linear(ps.layout.s_state, ps.zx_hi, lay.s_state) * node_scale[:, None]
        for n in range(1, N - 1):
            for j in range(nx):
                if np.isfinite(zlo[n, j]):
                    out.lower[b.X[n, j]] = float(zlo[n, j])
                if np.isfinite(zhi[n, j]):
                    out.upper[b.X[n, j]] = float(zhi[n, j])
        for (w, n) in (("first", 0), ("last", N - 1)):
            for j in range(nx):
                out.lower[b.X[n, j]], out.upper[b.X[n, j]] = ps.zx_ends[(w, j)]
    if snap.duals:
        # the mesh's own rows are set above; a component's name is built on every call (a
        # tenth of a mesh iteration's warm start when asked of all of them)
        for c in m.component_data_objects(pyo.Constraint, active=True):
            if c not in out.constraints and c.name in snap.duals:
                out.constraints[c] = snap.duals[c.name]
    for name, value in snap.values.items():
        v = m.find_component(name)
        if v is None or v.fixed:
            continue
        if primal and value is not None:
            v.set_value(value, skip_validation=True)
        out.lower[v], out.upper[v] = snap.lower.get(name, 0.0), snap.upper.get(name, 0.0)
    return out
