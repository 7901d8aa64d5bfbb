"""Reading the structure of a built Transcription: its variables, rows and coefficients,
the collocation rows of each phase and the node-function families of its dynamics, path
constraints and integrands, the boundary constraints and objective as scalar functions."""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from ...symbolic.model import TIME
from .codegen import INF, Unsupported, _check_smooth, _Family, _generated, _function, _Scalars


def _compile(tr):
    """The structure and compiled functions of ``tr``; a string when it is not covered."""
    import pyomo.core as pyo
    from pyomo.core.base.var import VarData

    problem, model = tr.problem, tr.model
    entries: list = []
    index: dict[int, int] = {}

    def y_of(obj) -> int:
        k = id(obj)
        if k not in index:
            index[k] = len(entries)
            entries.append(obj)
        return index[k]

    free = sorted(problem.free_parameters, key=str)
    times = {sym for pb in tr.phases for sym in (pb.phase.t0_symbol, pb.phase.tf_symbol)}
    # constants kept as symbols (build(mutable=...)) are mutable Params, arguments like parameters
    consts = sorted([s for s, v in tr.scalars.items() if _is_param(v) and s not in times], key=str)
    T0, TF, S = sp.Dummy("t0"), sp.Dummy("tf"), sp.Dummy("s")
    rows: list = []
    gl: list = []
    gu: list = []
    phases = []
    for ip, pb in enumerate(tr.phases):
        ph, lay, b = pb.phase, pb.layout, pb.block
        nx, nu = len(ph.states), len(ph.controls)
        C = lay.n_colloc
        X = _indexed(b.X, (lay.n_state_nodes, nx), entries, index)
        U = _indexed(b.U, (C, nu), entries, index)
        t0i, tfi = y_of(b.t0), y_of(b.tf)
        pidx = [y_of(tr.scalars[s]) for s in free + consts]
        colloc_state = np.concatenate(lay.colloc_state)
        W = np.concatenate([X[colloc_state], U, np.full((C, 1), t0i), np.full((C, 1), tfi),
                            np.tile(np.array(pidx, int), (C, 1)).reshape(C, len(pidx))], axis=1)
        wsyms = list(ph.states) + list(ph.controls) + [T0, TF] + free + consts
        path_exprs = [c.expr for c in ph.path]
        G, g, H = _families(ph, wsyms, (T0, TF, S))
        # rows: the model's defect, end and path constraint data, in this order
        base = len(rows)
        rows.extend(pb.defects.values())
        rows.extend(pb.ends.values())
        gl.extend([0.0] * (len(rows) - base))
        gu.extend([0.0] * (len(rows) - base))
        lin, terms, weights = _collocation_rows(pb, X, base)
        path_base = len(rows)
        if path_exprs:
            rows.extend(b.path[i] for i in range(C * len(path_exprs)))
            gl.extend([-INF if not math.isfinite(c.lower) else c.lower for c in ph.path] * C)
            gu.extend([INF if not math.isfinite(c.upper) else c.upper for c in ph.path] * C)
        phases.append({"index": ip, "nodes": C, "W": W, "S": np.asarray(lay.s_colloc, float),
                       "G": G, "g": g, "H": H, "weights": weights, "path_base": path_base,
                       "lin_row": lin[0], "lin_y": lin[1], "lin_coef": lin[2],
                       "t_row": terms[0], "t_node": terms[1], "t_out": terms[2], "t_coef": terms[3]})
    # scalar level: objective and the general boundary constraints (the model's m.boundary)
    boundary_base = len(rows)
    general = tr.boundary_general
    cons = list(model.boundary.values())
    if len(cons) != len(general):
        raise Unsupported("the boundary constraints do not match the problem's")
    for con, c in zip(cons, general):
        rows.append(con)
        gl.append(-INF if not math.isfinite(c.lower) else c.lower)
        gu.append(INF if not math.isfinite(c.upper) else c.upper)
    # a maximised objective is minimised negated, as PyNumero does, so that the multipliers
    # Ipopt returns have PyNumero's signs on both routes
    sign = 1 if problem.objective.sense == "minimize" else -1
    exprs = [sign * problem.objective.expr] + [c.expr for c in general]
    _check_smooth(exprs, "the objective or a boundary constraint")
    integral_of = {s: (ip, q) for ip, pb in enumerate(tr.phases) for q, s in enumerate(pb.phase.integrals)}
    syms = sorted(set().union(*[sp.sympify(e).free_symbols for e in exprs]), key=str)
    ysyms = [s for s in syms if s not in integral_of]
    isyms = [s for s in syms if s in integral_of]
    for s in ysyms:
        target = tr.scalars.get(s)
        if target is None or not (isinstance(target, VarData) or _is_param(target)):
            raise Unsupported(f"the objective or a boundary constraint uses {s}")
    y_of_sym = [y_of(tr.scalars[s]) for s in ysyms]
    icoef = []
    for out, e in enumerate(exprs):
        for s in isyms:
            d = sp.diff(sp.sympify(e), s)
            if d.free_symbols:
                raise Unsupported("the objective or a boundary constraint is nonlinear in an integral")
            if d != 0:
                ip, q = integral_of[s]
                icoef.append((out, ip, q, float(d)))
    gen = _generated(exprs, ysyms, isyms)
    symbols = [("y", y) for y in y_of_sym] + [("I", integral_of[s]) for s in isyms]
    scal = _Scalars(len(exprs), symbols, [tuple(j) for j in gen["jac"]], [tuple(h) for h in gen["hess"]], icoef,
                    _function(gen["values"]), _function(gen["first"]), _function(gen["second"]))
    # every variable the model has must be an entry (unused ones too: PyNumero drops them,
    # Ipopt keeps them at their start)
    for v in model.component_data_objects(pyo.Var):
        y_of(v)
    return {"entries": entries, "phases": phases, "scalars": scal, "rows": rows, "gl": gl, "gu": gu,
            "boundary_base": boundary_base}


def _indexed(var, shape, entries, index) -> np.ndarray:
    """y indices of a 2-index Var's data, appended to ``entries`` in one pass."""
    out = np.full(shape, -1, int)
    keys = list(var.keys())
    if keys:
        k = np.array(keys, int).reshape(-1, 2)
        out[k[:, 0], k[:, 1]] = np.arange(len(entries), len(entries) + len(keys))
        for v in var.values():
            index[id(v)] = len(entries)
            entries.append(v)
    return out


def _collocation_rows(pb, X, base):
    """The defect and end rows of one phase, vectorised over rows of the same scheme: linear
    parts (row, y index, coefficient) and terms coef * G_j(w_node) (row, node, j, coefficient),
    as ``pseudospectral._build_phase`` writes them, plus each collocation node's quadrature
    weight (for the integrals). Rows are numbered from ``base`` in the order of
    ``pb.defects`` then ``pb.ends``."""
    from ..nodes import lobatto_integration_matrix, scheme

    lay = pb.layout
    mesh = lay.mesh
    K = mesh.segments
    half_h = np.diff(mesh.breakpoints) / 2.0
    weights = np.zeros(lay.n_colloc)
    for k in range(K):
        weights[lay.colloc[k]] = np.asarray(mesh.scheme(k).weights, float) * half_h[k]
    lin, terms = [], []
    # defect rows (k, i, j), grouped by their segment's degree
    keys = np.array(list(pb.defects.keys()), int).reshape(-1, 3)
    rows = base + np.arange(len(keys))
    degrees = np.asarray(mesh.degrees)
    for d in np.unique(degrees):
        sc = scheme(mesh.scheme_name, int(d))
        segs = np.flatnonzero(degrees == d)
        pos = np.full(K, -1)
        pos[segs] = np.arange(len(segs))
        sup = np.array([lay.support[k] for k in segs], int)          # (segments, m)
        col = np.array([lay.colloc[k] for k in segs], int)           # (segments, n)
        sel = degrees[keys[:, 0]] == d
        r, k, i, j = rows[sel], keys[sel, 0], keys[sel, 1], keys[sel, 2]
        p = pos[k]
        if sc.name == "LGL":
            # X_i - X_0 - h/2 * sum_l A_il (tf - t0) F_l
            lin.append((np.concatenate([r, r]), np.concatenate([X[sup[p, i], j], X[sup[p, 0], j]]),
                        np.concatenate([np.ones(len(r)), -np.ones(len(r))])))
            A = lobatto_integration_matrix(sc.degree)
            coef = -half_h[k][:, None] * A[i, :]                       # (rows, n)
            nz = coef != 0.0
            terms.append((np.broadcast_to(r[:, None], coef.shape)[nz], col[p][nz],
                          np.broadcast_to(j[:, None], coef.shape)[nz], coef[nz]))
        else:
            # D_i . X - h/2 (tf - t0) F_i
            D = np.asarray(sc.D, float)[i, :]                          # (rows, m)
            nz = D != 0.0
            ys = X[sup[p], j[:, None]]                                 # (rows, m)
            lin.append((np.broadcast_to(r[:, None], D.shape)[nz], ys[nz], D[nz]))
            terms.append((r, col[p, i], j, -half_h[k]))
    # LG end rows (k, j): X_end - X_0 - h/2 sum_i w_i (tf - t0) F_i
    if pb.ends:
        ekeys = np.array(list(pb.ends.keys()), int).reshape(-1, 2)
        r = base + len(keys) + np.arange(len(ekeys))
        k, j = ekeys[:, 0], ekeys[:, 1]
        start = np.array([lay.support[kk][0] for kk in k], int)
        endn = np.array([lay.end[kk] for kk in k], int)
        lin.append((np.concatenate([r, r]), np.concatenate([X[endn, j], X[start, j]]),
                    np.concatenate([np.ones(len(r)), -np.ones(len(r))])))
        for kk_r, kk, jj in zip(r, k, j):
            sc = mesh.scheme(kk)
            cns = np.asarray(lay.colloc[kk], int)
            terms.append((np.full(len(cns), kk_r), cns, np.full(len(cns), jj),
                          -half_h[kk] * np.asarray(sc.weights, float)))
    cat = lambda parts, t: np.concatenate([np.asarray(q[t]) for q in parts]) if parts else np.zeros(0)  # noqa: E731
    return ((cat(lin, 0).astype(int), cat(lin, 1).astype(int), cat(lin, 2).astype(float)),
            (cat(terms, 0).astype(int), cat(terms, 1).astype(int), cat(terms, 2).astype(int),
             cat(terms, 3).astype(float)), weights)


def _families(ph, wsyms, times):
    """The phase's dynamics, path and integrand families; compiled once per Phase object
    (kept on it), so that rebuilt meshes (mesh refinement, multi-start) and the points of a
    reused study model do not differentiate again."""
    key = (tuple(wsyms[len(ph.states) + len(ph.controls) + 2:]),)
    cached = getattr(ph, "_direct_families", None)
    if cached is not None and cached[0] == key:
        return cached[1]         # positional functions: which dummy symbols made them is moot
    T0, TF, S = times
    t_sub = {TIME: T0 + (TF - T0) * S}
    duration = TF - T0
    rhs = list(ph.rhs())
    _check_smooth(rhs, "the dynamics")
    G = _Family.compile([duration * sp.sympify(e).xreplace(t_sub) for e in rhs], wsyms, S)
    path_exprs = [c.expr for c in ph.path]
    _check_smooth(path_exprs, "a path constraint")
    g = _Family.compile([sp.sympify(e).xreplace(t_sub) for e in path_exprs], wsyms, S) if path_exprs else None
    integrands = list(ph.integrals.values())
    _check_smooth(integrands, "an integral")
    H = _Family.compile([duration * sp.sympify(e).xreplace(t_sub) for e in integrands], wsyms, S) if integrands else None
    ph._direct_families = (key, (G, g, H))
    return G, g, H


def _linear_row(con, compiled):
    """(con, [(y index, coefficient)], lower, upper) of a linear constraint data, else None."""
    from pyomo.repn import generate_standard_repn

    repn = generate_standard_repn(con.body, compute_values=True, quadratic=False)
    if not repn.is_linear():
        return None
    index = compiled.setdefault("entry_index", {id(e): i for i, e in enumerate(compiled["entries"])})
    terms = []
    for v, coef in zip(repn.linear_vars, repn.linear_coefs):
        if id(v) not in index:
            return None
        terms.append((index[id(v)], float(coef)))
    const = float(repn.constant)
    lo = -INF if con.lb is None else float(con.lb) - const
    hi = INF if con.ub is None else float(con.ub) - const
    # the constant moves into the bounds: the row's value is the linear part alone
    return con, terms, lo, hi


def _is_param(obj) -> bool:
    from pyomo.core.base.param import ParamData, ScalarParam

    return isinstance(obj, (ParamData, ScalarParam))
