"""One built Pyomo model re-solved at the points of a study that sweep constant parameters.

A study point normally compiles the problem file with its parameter values folded in and
builds a fresh Pyomo model (``Loaded.solve(parameters=...)``). With reuse (the study's
``reuse_model``, default on), a worker keeps, per problem handle and per set of swept
names, one model built from the problem compiled with *those* constants left as symbols
(``_Compiler.symbolic``), each a mutable Pyomo Param ``c_<name>``; every other constant
stays folded. At each point:

1. the point's own problem is compiled as before (its Result, expectations and
   certificate use it, so nothing downstream changes);
2. the structure check: the symbolic problem with the point's values substituted must be
   *identical* to the point's problem (same bounds, fixed boundary values, path
   constraints, dynamics, integrands, objective). A swept constant that sets a bound or
   a boundary value (``x(t0) == x0``) is folded into a number by the compiler, so the
   check fails and the point gets a fresh build; so does a value that changes the
   folded expressions' shape (a factor 0). Nothing is assumed about which constants can
   be Params: the check decides per point;
3. the Params get the point's values and every free variable gets the start a fresh
   build would give it (the file's guess, or the run folder of ``warm_start``: the
   continuation neighbour), fixed variables are left as they are (identical by 2.);
4. Ipopt re-solves: ``ocdsl.solve.ipopt.solve`` makes a new PyomoNLP each time, whose NL
   writer writes the Params' current values, so the solver sees the new constants.

Only for the plain pseudospectral path (one start, no mesh refinement); anything else
returns None and the caller builds afresh. Measured in reports/bench/levers.md
(section "Model reuse across study points").
"""
from __future__ import annotations

from typing import Any

import sympy as sp

# the start of a re-solve: "guess" = what a fresh build of the point would start from
# (the file's guess or the warm_start run folder), so the reused and fresh paths take the
# same iterates; "previous" = the last solution held by the model (the previous point this
# worker solved; depends on the scheduling, so only for measuring)
START = {"from": "guess"}


class ModelReuse:
    """The reusable models of one problem handle (``ocdsl.api.Loaded``), by swept names."""

    def __init__(self, loaded):
        self.loaded = loaded
        self.entries: dict[tuple[str, ...], Any] = {}
        self.counts = {"built": 0, "reused": 0, "fresh": 0}

    def solve(self, file, parameters: dict[str, float], timer, *, seed=None, warm_start=None,
              verbose=False, progress=False):
        """The point's Result through a reused model, or None (then build afresh)."""
        why = _ineligible(file, parameters)
        if why:
            return self._fresh(why)
        key = tuple(sorted(parameters))
        entry = self.entries.get(key)
        with timer.measure("build"):
            if entry is None:
                entry = _Entry.make(self.loaded, file, key)
                self.entries[key] = entry
                if entry.tr is None:
                    return self._fresh(entry.why)
            elif entry.tr is None:
                return self._fresh(entry.why)
            subs = {s: sp.Float(file_constant(file, s)) for s in entry.symbols}
            why = _differs(entry.problem, file.problem, subs)
            if why:
                return self._fresh(f"structure differs: {why}")
            first = not entry.used
            entry.prepare(file, subs, seed, warm_start)
        from ..run import solve_built

        result = solve_built(file, entry.view(file.problem), entry.meshes, timer, verbose=verbose,
                             progress=progress)
        self.counts["built" if first else "reused"] += 1
        result.extra["model_reuse"] = "built" if first else "reused"
        return result

    def _fresh(self, why: str):
        self.counts["fresh"] += 1
        self.last_fresh = why
        return None


def file_constant(file, s: sp.Symbol) -> float:
    for ph in file.problem.phases:
        if s in ph.constants:
            return float(ph.constants[s])
    return float(file.parameters[s.name])


def _ineligible(file, parameters) -> str:
    from ..spec.schema import PseudospectralMethod

    if not parameters:
        return "no parameters"
    if file.controller is not None or file.problem is None:
        return "not a trajectory problem"
    m = file.method
    if not isinstance(m, PseudospectralMethod):
        return f"method {m.transcription} (reuse is for the pseudospectral back end)"
    if m.mesh is not None:
        return "mesh refinement"
    if m.starts != 1:
        return "several starts"
    if {s.name for s in file.problem.free_parameters} & set(parameters):
        return "a swept parameter is free"
    return ""


class _Entry:
    def __init__(self):
        self.tr = None
        self.why = ""
        self.used = False

    @classmethod
    def make(cls, loaded, file, names: tuple[str, ...]) -> "_Entry":
        from ..spec import compile as spec_compile
        from ..transcribe.mesh import Mesh
        from ..transcribe.pseudospectral import build
        from ..spec.errors import SpecError

        e = cls()
        merged = {**loaded._parameters, **{k: file.parameters[k] for k in names if k in file.parameters}}
        c = spec_compile._Compiler(loaded.path, file.located, file.spec, merged)
        c.symbolic = frozenset(names)
        try:
            sym_file = c.compile()
        except SpecError as exc:   # pragma: no cover - the folded compile passed
            e.why = f"symbolic compile failed: {exc}"
            return e
        e.problem = sym_file.problem
        e.symbols = sorted({s for ph in file.problem.phases for s in ph.constants if s.name in names},
                           key=str)
        if not e.symbols:
            e.why = "the swept parameters are not constants of any phase"
            return e
        subs = {s: sp.Float(file_constant(file, s)) for s in e.symbols}
        why = _differs(e.problem, file.problem, subs)
        if why:
            e.why = f"structure differs: {why}"
            return e
        m = file.method
        e.meshes = {ph.name: Mesh.uniform(m.transcription, m.segments, m.degree) for ph in file.problem.phases}
        guesses = _guesses(file, None, None)
        e.tr = build(e.problem, e.meshes, guesses, mutable={s: float(v) for s, v in subs.items()})
        e.params = {s: e.tr.model.component(f"c_{s.name}") for s in e.symbols}
        return e

    def prepare(self, file, subs, seed, warm_start) -> None:
        for s, p in self.params.items():
            p.set_value(float(subs[s]))
        if self.used and START["from"] == "previous" and warm_start is None:
            return                  # keep the previous point's solution as the start
        if self.used or seed is not None or warm_start is not None:
            restart(self.tr, _guesses(file, seed, warm_start), file.problem)
        self.used = True

    def view(self, problem):
        """The built transcription seen through the point's own (folded) problem, for the
        solution, costates and certificate (same structure: checked)."""
        from ..transcribe.pseudospectral import PhaseBlock, Transcription

        by_name = {ph.name: ph for ph in problem.phases}
        blocks = [PhaseBlock(by_name[pb.phase.name], pb.layout, pb.block, pb.defects, pb.ends,
                             pb.integral_exprs) for pb in self.tr.phases]
        return Transcription(problem, self.tr.model, blocks, self.tr.scalars, self.tr.boundary_general,
                             defining=self.tr)


def restart(tr, guesses, problem) -> None:
    """Give every variable of a built transcription that is not fixed the value a fresh
    ``build(problem, meshes, guesses)`` gives it (the guess is what sets them: states,
    controls, t0/tf, free parameters; the fixed ones are the problem's, unchanged)."""
    for pb in tr.phases:
        g, lay, b = guesses[pb.phase.name], pb.layout, pb.block
        xg, ug = g.states_at(lay.s_state), g.controls_at(lay.s_colloc)
        for (n, j), v in b.X.items():
            if not v.fixed:
                v.set_value(float(xg[n, j]), skip_validation=True)
        for (i, j), v in b.U.items():
            if not v.fixed:
                v.set_value(float(ug[i, j]), skip_validation=True)
        for name, value in (("t0", g.t0), ("tf", g.tf)):
            v = getattr(b, name)
            if hasattr(v, "fixed") and not v.fixed:
                v.set_value(value, skip_validation=True)
    for s, fp in problem.free_parameters.items():
        v = tr.model.component(f"p_{s.name}")
        if not v.fixed:
            v.set_value(fp.guess, skip_validation=True)


class SolvedState:
    """The values and imported suffixes (duals, bound multipliers) a solve left in a model,
    to put back after later solves of the same model (the best of several starts)."""

    def __init__(self, model):
        import pyomo.core as pyo
        from pyomo.core.base.suffix import active_import_suffix_generator

        self.values = [(v, v.value) for v in model.component_data_objects(pyo.Var)]
        self.suffixes = [(sfx, list(sfx.items())) for _, sfx in active_import_suffix_generator(model)]

    def restore(self) -> None:
        for v, x in self.values:
            v.set_value(x, skip_validation=True)
        for sfx, items in self.suffixes:
            sfx.clear()
            sfx.update(items)


def _guesses(file, seed, warm_start):
    from ..run import previous_phases
    from ..transcribe.guess import make_guess

    previous = previous_phases(file, warm_start)
    return {ph.name: make_guess(file.problem, ph, previous.get(ph.name), seed=seed)
            for ph in file.problem.phases}


def _differs(sym_problem, problem, subs) -> str:
    """'' when ``sym_problem`` with ``subs`` is the same problem as ``problem``, else what differs."""
    def same(a, b) -> bool:
        if hasattr(a, "xreplace"):       # expressions and matrices
            a = a.xreplace(subs)
        return a == b

    if len(sym_problem.phases) != len(problem.phases):
        return "phases"
    for p, q in zip(sym_problem.phases, problem.phases):
        if (p.name, p.states, p.controls, p.t0, p.tf, p.t0_bounds, p.tf_bounds) != \
                (q.name, q.states, q.controls, q.t0, q.tf, q.t0_bounds, q.tf_bounds):
            return f"phase {q.name}: time or variables"
        if p.state_bounds != q.state_bounds or p.control_bounds != q.control_bounds:
            return f"phase {q.name}: bounds"
        if len(p.path) != len(q.path) or any(
                (a.lower, a.upper) != (b.lower, b.upper) or not same(a.expr, b.expr)
                for a, b in zip(p.path, q.path)):
            return f"phase {q.name}: path constraints"
        if list(p.integrals) != list(q.integrals) or any(
                not same(p.integrals[k], q.integrals[k]) for k in q.integrals):
            return f"phase {q.name}: integrals"
        if not same(p.rhs(), q.rhs()):
            return f"phase {q.name}: dynamics"
        if p.guess != q.guess:
            return f"phase {q.name}: guess"
    if len(sym_problem.boundary) != len(problem.boundary) or any(
            (a.lower, a.upper) != (b.lower, b.upper) or not same(a.expr, b.expr)
            for a, b in zip(sym_problem.boundary, problem.boundary)):
        return "boundary constraints"
    if sym_problem.objective.sense != problem.objective.sense or \
            not same(sym_problem.objective.expr, problem.objective.expr):
        return "objective"
    if set(sym_problem.free_parameters) != set(problem.free_parameters) or \
            set(sym_problem.boundary_values) != set(problem.boundary_values):
        return "free parameters or boundary values"
    return ""
