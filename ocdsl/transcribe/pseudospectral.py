"""LG / LGR / LGL pseudospectral collocation of a symbolic Problem into a Pyomo model.

The NLP has no derivative variables: in each segment the collocation equations are
written with the differentiation matrix, ``D @ X = (h_k/2)(tf - t0) F(X, U, t, p)``.
Box bounds on states, controls, t0/tf and free parameters become variable bounds and
boundary values fixed by an equality become fixed variables, because the size of the
KKT system sets Ipopt's time (../shared/design/transcription-notes.md).
"""
from __future__ import annotations

import contextlib
import gc
import math
from dataclasses import dataclass, field
from typing import Any

import pyomo.core as pyo
import sympy as sp

from ..symbolic.model import TIME
from ..symbolic.problem import Phase, Problem
from .guess import PhaseGuess
from .mesh import Layout, Mesh
from .nodes import lobatto_integration_matrix
from .pyomo_expr import pyomo_function


@dataclass
class PhaseBlock:
    """The Pyomo pieces of one phase, kept to read the solution back."""

    phase: Phase
    layout: Layout
    block: Any
    defects: dict = field(default_factory=dict)     # (segment, i, j) -> constraint data
    ends: dict = field(default_factory=dict)        # LG (segment, j) -> end constraint data
    integral_exprs: dict = field(default_factory=dict)
    # breakpoint index -> its Pyomo variable, for a build whose breakpoints there are unknowns
    # (``build(free_breakpoints=...)``); the layout keeps the mesh the variables start from
    free_breakpoints: dict = field(default_factory=dict)
    # controls tied to their segment's interior polynomial (mesh refinement's junction
    # controls): (segment, tied node, other nodes, Lagrange coefficients), positions in the
    # segment's collocation points; the certificate judges such a segment's reduced stationarity
    control_ties: list = field(default_factory=list)


@dataclass
class Transcription:
    problem: Problem
    model: Any
    phases: list[PhaseBlock]
    scalars: dict[sp.Symbol, Any]        # boundary values, t0/tf, integrals, free params -> Pyomo
    # the boundary constraints that are rows of ``model.boundary`` (in its order); the others
    # became variable bounds or fixed variables
    boundary_general: list = field(default_factory=list)
    # the transcription whose symbolic problem defines the NLP: itself, or for a reused
    # model's per-point view (ocdsl/solve/reuse.py) the built one, whose constants are Params
    defining: "Transcription | None" = None
    # the objective expression as built: one changed later is no longer the symbolic
    # problem's, so direct_nlp declines the model unless the change is ``penalty``'s
    built_objective: Any = None
    # a sum of squared differences of variables added to the built objective (mesh
    # refinement's regularisation): (the objective expression it made, [(coef, var_a,
    # var_b), ...]), the term being sum coef (a - b)^2 in the minimised sense
    penalty: tuple | None = None
    # the spread of the variables' typical magnitudes at the start, of an unscaled model
    # (ocdsl/solve/scaling.py ``spread``): measured before Ipopt moves them, for the hint of a failure
    start_spread: tuple | None = None
    # with `scaling: {mode: auto}`: the variables it found no size for at the start (scaling.sizeless)
    start_sizeless: tuple = ()


def _bound(v: float):
    return None if not math.isfinite(v) else float(v)


# Construction fast paths (same NLP, fewer Python objects and passes); tests turn them off
# to check that the optimum does not move (tests/test_fast_paths.py), reports/bench/levers.md
# has what each one saves.
FAST = {
    # no cyclic garbage collection while the model is built: the collector otherwise walks
    # every expression object already made, again and again (build time grew ~K^1.6)
    "no_gc": True,
    # D @ X as one Pyomo LinearExpression from precomputed monomials, not a sum() that
    # rebuilds the expression term by term, and variable data looked up once per node
    "linear_defects": True,
    # on leaving build(), hand every object made during the pause straight to the oldest
    # generation (gc.freeze + gc.unfreeze, O(1)) instead of letting the first young
    # collection after gc.enable() walk them all and promote them generation by generation
    # (0.3 s CPU of a 0.9 s build at 2,000 segments)
    "gc_to_oldest": True,
    # Ipopt evaluates the NLP through NumPy, node-vectorised (direct_nlp.py), instead of
    # Pyomo's NL writer and the ASL, wherever direct_nlp covers the model
    "direct_nlp": True,
}


# Objects moved to the oldest generation by freeze/unfreeze bypass CPython's count of
# long-lived objects, so no full collection is ever triggered by them: a process building
# model after model (study workers, multi-start, mesh refinement) kept every dropped model
# (they hold reference cycles), ~40 MB per point at 200 segments (measured). So the next
# build starts with one full collection once the objects handed over this way since the last
# one (a count kept here, not gc.get_freeze_count(), which walks them: 0.05 s at 100k
# variables) pass COLLECT_AFTER. Not on every build: a full collection walks the whole heap
# (SymPy, Pyomo, SciPy), 0.04-0.07 s even for a 30-variable model, which was a fifth of each
# iteration of a small mesh refinement (moon landing: ~8,000 objects per build).
COLLECT_AFTER = 250_000
_bypassed_since_collection = 0


def _to_oldest_generation():
    global _bypassed_since_collection
    _bypassed_since_collection += gc.get_count()[0]   # container objects made since the freeze
    gc.freeze()
    gc.unfreeze()


@contextlib.contextmanager
def _gc_paused(collect: bool = True):
    global _bypassed_since_collection
    if not FAST["no_gc"] or not gc.isenabled():
        yield
        return
    if _bypassed_since_collection > COLLECT_AFTER and collect:
        gc.collect()
        _bypassed_since_collection = 0
    gc.disable()
    try:
        yield
    finally:
        if FAST["gc_to_oldest"]:
            _to_oldest_generation()
        gc.enable()


@contextlib.contextmanager
def gc_frozen():
    """Keep the objects that exist now (the built model) out of cyclic collections.

    For the hand-over to Ipopt: the NL writer allocates millions of small objects, and each
    full collection they trigger otherwise walks the whole model again (measured: one such
    collection made the hand-over 1.5 -> 2.6 s CPU at 2,000 segments). gc.unfreeze() on exit
    puts everything back in the oldest generation, so nothing is kept alive longer. Used by
    ``ocdsl.solve.ipopt.solve`` around the hand-over and the solve (not re-entrant: an inner
    use would unfreeze the outer one's objects early, which is harmless but undoes it).
    """
    if not FAST["no_gc"] or not gc.isenabled():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        _to_oldest_generation()


def build(problem: Problem, meshes: dict[str, Mesh], guesses: dict[str, PhaseGuess],
          mutable: dict[sp.Symbol, float] | None = None, collect: bool = True,
          free_breakpoints: dict[str, list[int]] | None = None) -> Transcription:
    """Build the Pyomo model of ``problem`` on ``meshes`` (one per phase) from ``guesses``.

    ``mutable``: constant parameters the problem keeps as symbols (compiled with them not
    folded), each made a mutable Pyomo Param ``c_<name>`` with this value, so that the model
    can be re-solved with other values (ocdsl/solve/reuse.py).

    ``collect``: first free what earlier builds left for the collector, once it is more than
    ``COLLECT_AFTER`` objects (a full collection walks the whole heap); false for
    the short-lived trial models of a mesh iteration (ocdsl/solve/mesh/switches.py), whose
    garbage the next build that collects frees.

    ``free_breakpoints``: per phase, interior breakpoints whose normalised times are unknowns
    of the NLP (each between the middles of its neighbouring segments), not data: a
    bang-bang switch's time solved for with everything else (ocdsl/solve/mesh/switches.py).
    Such a model is evaluated by Pyomo's route, not ``direct_nlp``."""
    from .. import pyomo_logs

    pyomo_logs.quiet()
    with _gc_paused(collect):
        return _build(problem, meshes, guesses, mutable or {}, free_breakpoints or {})


def _build(problem: Problem, meshes: dict[str, Mesh], guesses: dict[str, PhaseGuess],
           mutable: dict[sp.Symbol, float], free_breakpoints: dict[str, list[int]]) -> Transcription:
    m = pyo.ConcreteModel(name=problem.name)
    m.dual = pyo.Suffix(direction=pyo.Suffix.IMPORT)
    scalars: dict[sp.Symbol, Any] = {}
    for s, value in mutable.items():
        prm = pyo.Param(initialize=float(value), mutable=True)
        m.add_component(f"c_{s.name}", prm)
        scalars[s] = prm
    for s, fp in problem.free_parameters.items():
        v = pyo.Var(bounds=(_bound(fp.lower), _bound(fp.upper)), initialize=fp.guess)
        m.add_component(f"p_{s.name}", v)
        scalars[s] = v
    blocks = []
    for ph in problem.phases:
        pb = _build_phase(m, ph, meshes[ph.name], guesses[ph.name], problem, scalars,
                          sorted(mutable, key=str), free_breakpoints.get(ph.name, ()))
        blocks.append(pb)
    # boundary values are the first/last state nodes
    for s, bv in problem.boundary_values.items():
        pb = next(b for b in blocks if b.phase.name == bv.phase)
        j = pb.phase.states.index(bv.var)
        node = 0 if bv.which == "t0" else pb.layout.n_state_nodes - 1
        scalars[s] = pb.block.X[node, j]
    # boundary constraints: a single boundary value or t0/tf with bounds becomes variable bounds
    m.boundary = pyo.ConstraintList()
    general = []
    for c in problem.boundary:
        target = scalars.get(c.expr) if isinstance(c.expr, sp.Symbol) else None
        if _is_vardata(target):
            _tighten(target, c.lower, c.upper)
        else:
            general.append(c)
    if general:
        syms = sorted(set().union(*[c.expr.free_symbols for c in general]), key=str)
        _check_known(syms, scalars, "boundary constraint")
        fn = pyomo_function(syms, [c.expr for c in general])
        values = fn(*[scalars[s] for s in syms])
        for c, e in zip(general, values):
            m.boundary.add(_ranged(e, c.lower, c.upper))
    obj = problem.objective
    syms = sorted(obj.expr.free_symbols, key=str)
    _check_known(syms, scalars, "objective")
    e = pyomo_function(syms, [obj.expr])(*[scalars[s] for s in syms])[0]
    m.objective = pyo.Objective(expr=e, sense=pyo.minimize if obj.sense == "minimize" else pyo.maximize)
    return Transcription(problem, m, blocks, scalars, general, built_objective=m.objective.expr)


def _is_vardata(x) -> bool:
    from pyomo.core.base.var import VarData

    return isinstance(x, VarData)


def _check_known(syms, scalars, what):
    unknown = [str(s) for s in syms if s not in scalars]
    if unknown:
        raise ValueError(f"{what} uses {', '.join(unknown)}, which the transcription cannot resolve")


def _tighten(var, lo: float, hi: float) -> None:
    if lo == hi:
        var.fix(lo)
        return
    if math.isfinite(lo):
        var.setlb(lo if var.lb is None else max(var.lb, lo))
    if math.isfinite(hi):
        var.setub(hi if var.ub is None else min(var.ub, hi))


def _ranged(e, lo: float, hi: float):
    if lo == hi:
        return e == lo
    if math.isfinite(lo) and math.isfinite(hi):
        return pyo.inequality(lo, e, hi)
    if math.isfinite(lo):
        return e >= lo
    return e <= hi


def _free_breakpoints(b, mesh: Mesh, free) -> list:
    """The phase's breakpoints: floats, and Pyomo variables at the indices ``free``."""
    bps = [float(x) for x in mesh.breakpoints]
    free = sorted({int(q) for q in free if 0 < int(q) < len(bps) - 1})
    if not free:
        return bps
    mid = lambda q: 0.5 * (bps[q] + bps[q + 1])      # noqa: E731
    b.S = pyo.Var(free, bounds=lambda _, q: (mid(q - 1), mid(q)), initialize=lambda _, q: bps[q])
    return [b.S[q] if q in free else x for q, x in enumerate(bps)]


def _build_phase(m, ph: Phase, mesh: Mesh, guess: PhaseGuess, problem: Problem, scalars,
                 consts: list = (), free_breakpoints=()) -> PhaseBlock:
    lay = Layout.of(mesh)
    b = pyo.Block()
    m.add_component(f"phase_{ph.name}", b)
    nx, nu = len(ph.states), len(ph.controls)
    N, C = lay.n_state_nodes, lay.n_colloc

    def state_bounds(model, n, j):
        lo, hi = ph.state_bounds.get(ph.states[j], (-math.inf, math.inf))
        return _bound(lo), _bound(hi)

    def control_bounds(model, i, j):
        lo, hi = ph.control_bounds.get(ph.controls[j], (-math.inf, math.inf))
        return _bound(lo), _bound(hi)

    xg = guess.states_at(lay.s_state)            # (N, nx)
    ug = guess.controls_at(lay.s_colloc)         # (C, nu)
    b.X = pyo.Var(range(N), range(nx), bounds=state_bounds, initialize=lambda _, n, j: float(xg[n, j]))
    b.U = pyo.Var(range(C), range(nu), bounds=control_bounds, initialize=lambda _, i, j: float(ug[i, j]))
    if ph.t0 is None:
        b.t0 = pyo.Var(bounds=(_bound(ph.t0_bounds[0]), _bound(ph.t0_bounds[1])), initialize=guess.t0)
    else:
        b.t0 = pyo.Param(initialize=ph.t0, mutable=True)
    if ph.tf is None:
        b.tf = pyo.Var(bounds=(_bound(ph.tf_bounds[0]), _bound(ph.tf_bounds[1])), initialize=guess.tf)
    else:
        b.tf = pyo.Param(initialize=ph.tf, mutable=True)
    scalars[ph.t0_symbol] = b.t0
    scalars[ph.tf_symbol] = b.tf
    duration = b.tf - b.t0 if (ph.t0 is None or ph.tf is None) else float(ph.tf - ph.t0)

    free = sorted(problem.free_parameters, key=str)
    # constants kept as symbols (``build(mutable=...)``) are arguments like free parameters
    free += list(consts)
    params = [scalars[s] for s in free]
    rhs = ph.rhs()
    args = list(ph.states) + list(ph.controls) + [TIME] + free
    _check_free(rhs, args, ph, "dynamics")
    f = pyomo_function(args, list(rhs))
    path_exprs = [c.expr for c in ph.path]
    for c in ph.path:
        _check_free(sp.Matrix([c.expr]), args, ph, f"path constraint '{c.text}'")
    g = pyomo_function(args, path_exprs) if path_exprs else None
    integrands = list(ph.integrals.values())
    L = pyomo_function(args, integrands) if integrands else None

    pb = PhaseBlock(ph, lay, b)
    bps = _free_breakpoints(b, mesh, free_breakpoints)
    pb.free_breakpoints = {q: v for q, v in enumerate(bps) if not isinstance(v, float)}
    linear = FAST["linear_defects"]
    if linear:
        from pyomo.core.expr.numeric_expr import LinearExpression, MonomialTermExpression

        Xd = [[b.X[n, j] for j in range(nx)] for n in range(N)]
        Ud = [[b.U[i, j] for j in range(nu)] for i in range(C)]
    defect_exprs: dict[tuple, Any] = {}
    end_exprs: dict[tuple, Any] = {}
    path_list: list = []
    integral_terms = [0.0] * len(integrands)
    for k in range(mesh.segments):
        sc = mesh.scheme(k)
        half_h = (bps[k + 1] - bps[k]) / 2.0
        moving = not isinstance(half_h, float)
        scale = duration * half_h
        sup = lay.support[k]
        Fk = []
        integral_form = sc.name == "LGL"
        if linear:
            Drows = [[(float(sc.D[i, l]), int(sup[l])) for l in range(len(sup)) if sc.D[i, l] != 0.0]
                     for i in range(sc.D.shape[0])]
        for i, (cn, sn) in enumerate(zip(lay.colloc[k], lay.colloc_state[k])):
            if moving:
                t = b.t0 + duration * (bps[k] + (float(sc.colloc[i]) + 1.0) * half_h)
            else:
                t = b.t0 + duration * float(lay.s_colloc[cn])
            if linear:
                xs, us = Xd[sn], Ud[cn]
            else:
                xs = [b.X[sn, j] for j in range(nx)]
                us = [b.U[cn, j] for j in range(nu)]
            vals = list(xs) + list(us) + [t] + params
            Fi = f(*vals)
            Fk.append(Fi)
            for j in range(nx if not integral_form else 0):
                if linear:
                    dx = LinearExpression([MonomialTermExpression((c, Xd[n][j])) for c, n in Drows[i]])
                else:
                    dx = sum(float(sc.D[i, l]) * b.X[sup[l], j] for l in range(len(sup)) if sc.D[i, l] != 0.0)
                defect_exprs[(k, i, j)] = dx - scale * Fi[j] == 0
            if g is not None:
                for c, e in zip(ph.path, g(*vals)):
                    path_list.append(_ranged(e, c.lower, c.upper))
            if L is not None:
                # the duration goes into every node's term, not in front of the sum: with a
                # free time, (tf - t0) * sum(...) is one nonlinear element of the NL file in
                # all the nodes' variables, and the ASL gives it a dense Hessian (moon landing,
                # 800 segments: 10.3 M nonzeros, 430 ms per evaluation); per node it is sparse
                weight = float(sc.weights[i]) * half_h     # an expression when the segment moves
                for q, e in enumerate(L(*vals)):
                    integral_terms[q] = integral_terms[q] + weight * duration * e
        if integral_form:
            # LGL (Lobatto IIIA): D on the Lobatto points is rank-deficient, so the collocation
            # equations are imposed in integral form, X_i = X_0 + scale * sum_j A_ij F_j.
            A = lobatto_integration_matrix(sc.degree)
            for i in range(1, len(sup)):
                for j in range(nx):
                    quad = sum(float(A[i, l]) * Fk[l][j] for l in range(len(Fk)) if A[i, l] != 0.0)
                    defect_exprs[(k, i, j)] = b.X[sup[i], j] - b.X[sup[0], j] - scale * quad == 0
        if not sc.end_from_support:
            # LG: the segment end follows from Gauss quadrature of the dynamics
            for j in range(nx):
                quad = sum(float(sc.weights[i]) * Fk[i][j] for i in range(len(Fk)))
                end_exprs[(k, j)] = b.X[lay.end[k], j] - b.X[sup[0], j] - scale * quad == 0
    b.defect = pyo.Constraint(list(defect_exprs), rule=lambda _, *idx: defect_exprs[idx])
    if end_exprs:
        b.end = pyo.Constraint(list(end_exprs), rule=lambda _, *idx: end_exprs[idx])
        pb.ends = {idx: b.end[idx] for idx in end_exprs}
    if path_list:
        b.path = pyo.Constraint(range(len(path_list)), rule=lambda _, i: path_list[i])
    pb.defects = {idx: b.defect[idx] for idx in defect_exprs}
    for q, s in enumerate(ph.integrals):
        e = pyo.Expression(expr=integral_terms[q])
        b.add_component(f"integral_{q}", e)
        scalars[s] = e
        pb.integral_exprs[s] = e
    return pb


def _check_free(exprs: sp.Matrix, args, ph: Phase, what: str) -> None:
    extra = set().union(*[sp.sympify(e).free_symbols for e in exprs]) - set(args)
    if extra:
        raise ValueError(f"phase '{ph.name}': {what} uses {', '.join(sorted(map(str, extra)))}, "
                         "which is neither a state, a control, t, nor a parameter with a value")
