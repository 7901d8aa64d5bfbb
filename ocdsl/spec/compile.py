"""Problem file -> validated spec -> symbolic :class:`~ocdsl.symbolic.problem.Problem`.

Every mistake becomes an :class:`~ocdsl.spec.errors.Issue` with file, line and text;
all issues found are raised together as one :class:`SpecError`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pydantic
import sympy as sp

from ..hints import did_you_mean
from ..symbolic.model import TIME, Model, sym
from ..symbolic.problem import (INF, BoundaryValue, Constraint, FreeParameter, Objective, Phase,
                                Problem)
from ..symbolic.registry import build_model
from .errors import ExprError, Issue, SpecError
from .expr import RESERVED, Scope, is_vector, parse_continuity, parse_expression, parse_relation
from ..chain.check import check_guess, is_problem_file
from .loader import Located, load_yaml
from .schema import ModelSpec, ParameterSpec, ProblemFile, PseudospectralMethod, TimeSpec
from .validate import (_issue_from_pydantic, _schema_issues, _source_line, validate,  # noqa: F401
                       validate_all)

PSEUDOSPECTRAL = ("LG", "LGR", "LGL", "LGR-start")
NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
MAX_VARIABLES = 1000   # states + controls of a model (docs/problem-language.md, "Input limits")
MAX_CONSTRAINTS = 1000  # constraints of a phase, and links (about 1 ms each to compile)


@dataclass
class LoadedFile:
    """A parsed and compiled problem file."""

    path: Path
    located: Located
    spec: ProblemFile
    problem: Problem | None
    method: Any                                   # validated method spec
    expect: dict[str, sp.Expr] = field(default_factory=dict)
    parameters: dict[str, float] = field(default_factory=dict)   # constants in force
    model: Model | None = None                                   # controller files: the plant
    controller: Any = None                                       # validated ControllerSpec


def load(path: str | Path, parameters: dict[str, float] | None = None) -> LoadedFile:
    """Read, validate and compile ``path``; ``parameters`` override constants by name."""
    located = load_yaml(path)
    spec, issues = validate_all(located)
    return compile_spec(Path(path), located, spec, issues, parameters or {})


def compile_spec(path: Path, located: Located, spec: ProblemFile | None, issues: list[Issue],
                 parameters: dict[str, float]) -> LoadedFile:
    """Compile a validated spec; raises one SpecError with the schema's ``issues`` and every
    issue the compiler finds (none twice)."""
    if spec is None:
        raise SpecError(issues)
    try:
        loaded = _Compiler(path, located, spec, dict(parameters)).compile()
    except SpecError as e:
        found = list(issues) + [i for i in e.issues if i not in issues]
        raise SpecError(sorted(found, key=lambda i: i.line or 0)) from None
    if issues:
        raise SpecError(issues)
    return loaded


class _Compiler:
    def __init__(self, path: Path, located: Located, spec: ProblemFile, overrides: dict[str, float]):
        self.path, self.located, self.spec = path, located, spec
        self.overrides = dict(overrides)
        self.issues: list[Issue] = []
        self.boundary_values: dict[sp.Symbol, BoundaryValue] = {}
        self.free: dict[sp.Symbol, FreeParameter] = {}
        self.integral_count = 0
        self.tables: dict = {}
        self.table_calls: dict = {}

    # -- error helpers ------------------------------------------------------------
    def issue(self, loc: tuple, message: str, text: str | None = None) -> None:
        if text is None:
            text = _source_line(self.located, loc)
        self.issues.append(self.located.issue(loc, message, text))

    def guarded(self, loc: tuple, fn, *args):
        """Run fn; turn ExprError/ValueError into an issue at ``loc`` and return None."""
        try:
            return fn(*args)
        except ExprError as e:
            self.issue(loc, e.message, e.text or None)
        except (ValueError, KeyError) as e:
            self.issue(loc, str(e).strip("'\""))
        except RecursionError:     # SymPy on expressions nested inside others past its depth
            self.issue(loc, "expressions nested too deeply (named expressions inside each other)")
        return None

    # -- top level ----------------------------------------------------------------
    def compile(self) -> LoadedFile:
        spec = self.spec
        method = self.validated_method(spec.method)
        self.tables = self.build_tables()
        problem = None
        if spec.problem is not None or spec.phases is not None:
            problem = self.build_problem()
        expect = {}
        if problem is not None:
            for key in spec.expect:
                e = self.guarded(("expect", key), self.parse_expect, key, problem)
                if e is not None:
                    expect[key] = e
        model = controller = None
        if spec.controller is not None and problem is None:
            self.used_overrides = set()
            self.constants_in_force = {}
            model = self.model(spec.model, ("model",)) if spec.model else None
            controller = self.guarded_pydantic(("controller",), "ocdsl.spec.controller", "ControllerSpec",
                                               spec.controller)
        unused = set(self.overrides) - self.used_overrides if hasattr(self, "used_overrides") else set()
        if unused:
            self.issue((), f"parameters given on the command line or by a study are not in the file: {sorted(unused)}", "")
        if self.issues:
            raise SpecError(self.issues)
        return LoadedFile(self.path, self.located, spec, problem, method, expect,
                          getattr(self, "constants_in_force", {}), model, controller)

    def build_tables(self) -> dict:
        """The file's ``tables:``, each a function for expressions; a call is shown as
        ``NAME(args)`` in the report (``self.table_calls``), not as its spline expansion."""
        from .tables import TableError, build_table

        out, self.table_calls = {}, {}
        for name, tspec in self.spec.tables.items():
            if not NAME_RE.match(name) or name in RESERVED:
                self.issue(("tables", name), f"'{name}' cannot name a table (reserved or not an identifier)")
                continue
            try:
                table = build_table(name, tspec, self.path.parent)
            except TableError as e:
                self.issue(("tables", name) + ((e.key,) if e.key else ()), str(e))
                out[name] = _broken_table(name)
                continue

            def call(*args, _table=table):
                value = _table(*args)
                self.table_calls[value] = sp.Function(_table.name)(*args)
                return value
            out[name] = call
        return out

    def validated_method(self, data: dict):
        """The method block, validated by its back end's spec; errors at their own lines."""
        try:
            return _validate_method(data)
        except pydantic.ValidationError as e:
            self.issues += _schema_issues(self.located, [dict(err, loc=("method",) + tuple(err["loc"]))
                                                         for err in e.errors()])
        except (ValueError, KeyError) as e:
            self.issue(("method", "transcription") if "transcription" in data else ("method",), str(e).strip("'\""))
        return None

    def guarded_pydantic(self, loc: tuple, module: str, cls: str, data):
        """Validate a block with a back end's pydantic class, errors at their file lines."""
        import importlib

        klass = getattr(importlib.import_module(module), cls)
        try:
            return klass.model_validate(data)
        except pydantic.ValidationError as e:
            for err in e.errors():
                err = dict(err, loc=loc + tuple(err["loc"]))
                self.issues.append(_issue_from_pydantic(self.located, err))
        return None

    def build_problem(self) -> Problem:
        spec = self.spec
        before = len(self.issues)     # the method's issues do not stop the problem's checks
        self.used_overrides: set[str] = set()
        self.constants_in_force: dict[str, float] = {}
        top_params = self.parameters(spec.parameters, ("parameters",))
        # links, a multi-phase objective and expectations belong to no phase: the file's own
        # constants are substituted in them (a phase's constants are substituted in its own)
        self.top_constants = {s: v for s, v in top_params.items()
                              if v is not None and s.name not in getattr(self, "symbolic", ())}
        base_model = self.model(spec.model, ("model",)) if spec.model else None
        phases: list[Phase] = []
        if spec.problem is not None:
            p = spec.problem
            phases.append(self.phase("main", base_model, p.time, p.constraints, p.guess, ("problem",), top_params, {}))
        else:
            for name, ph in spec.phases.items():
                if not NAME_RE.match(name) or name in RESERVED:
                    self.issue(("phases", name), f"'{name}' is not a valid phase name")
                    continue
                mdl = self.model(ph.model, ("phases", name, "model")) if ph.model else base_model
                phases.append(self.phase(name, mdl, ph.time, ph.constraints, ph.guess, ("phases", name), top_params,
                                         ph.parameters))
        phases = [p for p in phases if p is not None]
        if len(self.issues) > before:
            raise SpecError(self.issues)
        boundary: list[Constraint] = []
        for ph, (phase_spec_loc, texts) in zip(phases, self._phase_constraint_texts()):
            boundary += self.constraints(ph, phases, texts, phase_spec_loc)
        multi = len(phases) > 1
        if len(spec.links) > MAX_CONSTRAINTS:
            self.issue(("links",), f"{len(spec.links)} links: more than the limit of {MAX_CONSTRAINTS}")
        for i, text in enumerate(spec.links[:MAX_CONSTRAINTS]):
            joined = self.guarded(("links", i), parse_continuity, text)
            if joined is None:
                boundary += self.relations(None, phases, text, ("links", i), link=True)
            else:
                boundary += self.continuity(phases, *joined, text, ("links", i))
        if spec.problem is not None:
            obj = self.guarded(("problem", "objective"), self.objective, spec.problem.objective, phases[0], phases)
        else:
            obj = self.guarded(("objective",), self.objective, spec.objective, None, phases)
            for ph in phases:
                extra = spec.phases[ph.name].objective
                if extra and obj is not None:
                    part = self.guarded(("phases", ph.name, "objective"), self.expression, extra, ph, phases)
                    if part is not None:
                        obj.expr = obj.expr + (part if obj.sense == "minimize" else -part)
        self.check_resolved(phases, boundary, obj)
        self.check_contradictions(boundary)
        if self.issues:
            raise SpecError(self.issues)
        desc = self.describe(phases, obj, multi)
        return Problem(spec.name, phases, obj, boundary, self.free, self.boundary_values, desc)

    def continuity(self, phases: list[Phase], names: list[str], states: list[str] | None, text: str,
                   loc: tuple) -> list[Constraint]:
        """``continuous(a, b, ..., [x, y])``: for each consecutive pair, a.tf == b.t0 and each
        named state (vectors by component; default: every state both phases have) equal
        across the junction, as if written one link each."""
        by_name = {p.name: p for p in phases}
        unknown = [n for n in names if n not in by_name]
        if unknown:
            self.issue(loc, f"unknown phase '{unknown[0]}'" + did_you_mean(unknown[0], by_name), text)
            return []
        out: list[Constraint] = []
        for a, b in zip(names, names[1:]):
            pa, pb = by_name[a], by_name[b]
            shared = [s.name for s in pa.states if s.name in {x.name for x in pb.states}]
            chosen = shared if states is None else []
            for n in states or []:
                vector = pa.model.vectors.get(n)
                comps = [c.name for c in vector] if vector is not None else [n]
                missing = [c for c in comps if c not in shared]
                if missing:
                    self.issue(loc, f"'{n}' is not a state of both '{a}' and '{b}'"
                               + did_you_mean(n, shared + list(pa.model.vectors)), text)
                    return []
                chosen += comps
            if pa.tf is not None and pb.t0 is not None:
                if abs(pa.tf - pb.t0) > 1e-12 * max(1.0, abs(pa.tf)):
                    self.issue(loc, f"'{a}' ends at tf = {pa.tf} but '{b}' starts at t0 = {pb.t0}", text)
                    return []
            else:
                out += self.relations(None, phases, f"{a}.tf == {b}.t0", loc, link=True)
            for x in chosen:
                out += self.relations(None, phases, f"{a}.{x}(tf) == {b}.{x}(t0)", loc, link=True)
        for c in out:
            c.text = f"{c.text}   ({text})"
        return out

    def check_resolved(self, phases: list[Phase], boundary: list[Constraint], obj: Objective | None) -> None:
        """Every symbol of a boundary constraint, link or the objective is one the
        transcription has a variable for; anything else is an error at its line now (as
        `ocdsl check` reports it), not at the build."""
        known = set(self.boundary_values) | set(self.free)
        for p in phases:
            known |= {p.t0_symbol, p.tf_symbol} | set(p.integrals)
        known |= {sym(n) for n in getattr(self, "symbolic", ())}
        for c in boundary:
            left = sorted(s.name for s in c.expr.free_symbols - known)
            if left:
                self.issues.append(Issue(str(self.path), c.line, f"{', '.join(left)} cannot be used here: "
                                         "a boundary constraint or link uses boundary values, phase times, "
                                         "integrals, free parameters and constants", c.text))
        if obj is not None:
            left = sorted(s.name for s in obj.expr.free_symbols - known - {sym("objective")})
            if left:
                loc = ("problem", "objective") if self.spec.problem is not None else ("objective",)
                self.issue(loc, f"the objective uses {', '.join(left)}, which has no value here "
                           "(boundary values, phase times, integrals, free parameters and constants only)")

    def check_contradictions(self, boundary: list[Constraint]) -> None:
        """Boundary constraints on the same quantity whose ranges do not meet (x(t0) == 1 and
        x(t0) == 2): an error naming both, not an infeasible solve."""
        first: dict[sp.Expr, Constraint] = {}
        for c in boundary:
            other = first.setdefault(c.expr, c)
            if other is not c and (c.lower > other.upper or c.upper < other.lower):
                self.issues.append(Issue(str(self.path), c.line, f"contradicts `{other.text}`"
                                         + (f" (line {other.line})" if other.line else "")
                                         + ": no value meets both", c.text))

    def _phase_constraint_texts(self):
        spec = self.spec
        if spec.problem is not None:
            yield ("problem", "constraints"), spec.problem.constraints
        else:
            for name, ph in spec.phases.items():
                yield ("phases", name, "constraints"), ph.constraints

    # -- parameters and models -----------------------------------------------------------
    def parameters(self, params: dict[str, Any], loc: tuple) -> dict[sp.Symbol, float | None]:
        out: dict[sp.Symbol, float | None] = {}
        for name, p in params.items():
            if not NAME_RE.match(name) or name in RESERVED:
                self.issue(loc + (name,), f"'{name}' is not a valid parameter name (reserved or not an identifier)")
                continue
            s = sym(name)
            if isinstance(p, ParameterSpec) and p.free:
                lo, hi = p.bounds or (None, None)
                guess = p.value if p.value is not None else _midpoint(lo, hi)
                self.free[s] = FreeParameter(s, -INF if lo is None else lo, INF if hi is None else hi, guess)
                out[s] = None
            else:
                value = p.value if isinstance(p, ParameterSpec) else p
                if name in self.overrides:
                    value = float(self.overrides[name])
                    self.used_overrides.add(name)
                if not math.isfinite(value):
                    self.issue(loc + (name,), f"parameter '{name}' is not a finite number")
                out[s] = value
                self.constants_in_force[name] = value
        return out

    def model(self, mspec: ModelSpec, loc: tuple) -> Model | None:
        if mspec.use:
            try:
                model = build_model(mspec.use, mspec.options)
            except (KeyError, ValueError) as e:
                self.issue(loc + ("use",), str(e).strip("'\""))
                return None
            except Exception as e:   # a model's builder is its author's code: any failure is the options'
                self.issue(loc + ("options",), f"model '{mspec.use}' cannot be built with these options "
                           f"({type(e).__name__}: {e})")
                return None
            given = self.parameters(mspec.parameters, loc + ("parameters",))
            known = {s.name: s for s in model.parameters}
            params = dict(model.parameters)
            for s, v in given.items():
                if s.name not in known:
                    self.issue(loc + ("parameters", s.name), f"model '{mspec.use}' has no parameter '{s.name}'; "
                               f"it has: {', '.join(sorted(known)) or 'none'}")
                    continue
                params[known[s.name]] = v
            for s, v in model.parameters.items():
                if s.name in self.overrides and s not in given:
                    params[s] = float(self.overrides[s.name])
                    self.used_overrides.add(s.name)
                if params[s] is not None and s not in self.free:
                    self.constants_in_force.setdefault(s.name, params[s])
            units = {**model.units, **mspec.units}
            names = {s.name: s for s in model.states + model.controls + tuple(model.parameters)}
            vectors = {**model.vectors, **self.vector_groups(mspec.vectors, names, loc)}
            return Model(model.name, model.states, model.controls, model.dynamics, params,
                         model.expressions, units, model.description,
                         tuple(mspec.positions) or model.positions, vectors, model.time_state)
        return self.inline_model(mspec, loc)

    def inline_model(self, m: ModelSpec, loc: tuple) -> Model | None:
        if len(m.states) + len(m.controls) > MAX_VARIABLES:   # compile time grows with the square
            self.issue(loc + ("states",), f"{len(m.states)} states and {len(m.controls)} controls: more "
                       f"than the limit of {MAX_VARIABLES} together")
            return None
        names: dict[str, sp.Basic] = {"t": TIME}
        ok = True
        declared: dict[str, tuple] = {}
        for group, items in (("states", m.states), ("controls", m.controls), ("parameters", list(m.parameters))):
            for i, name in enumerate(items):
                where = loc + (group, i if group != "parameters" else name)
                if not isinstance(name, str) or not NAME_RE.match(name) or name in RESERVED:
                    self.issue(where, f"'{name}' is not a valid {group[:-1]} name (reserved or not an identifier)")
                    ok = False
                elif name in declared:
                    self.issue(where, f"'{name}' is declared twice (also in {declared[name][0]})")
                    ok = False
                else:
                    declared[name] = (group,)
                    names[name] = sym(name)
        params = self.parameters(m.parameters, loc + ("parameters",))
        for name in self.spec.parameters:
            names.setdefault(name, sym(name))
        vectors = self.vector_groups(m.vectors, names, loc)
        expressions: dict[sp.Symbol, sp.Expr] = {}
        scope = Scope(names, functions=self.tables)
        clash = sorted(set(names) & set(self.tables))
        for name in clash:
            self.issue(("tables", name), f"'{name}' names both a table and a declared name of the model")
        for name, text in m.expressions.items():
            if not NAME_RE.match(name) or name in names or name in RESERVED:
                self.issue(loc + ("expressions", name), f"'{name}' cannot name an expression (reserved, declared or not an identifier)")
                ok = False
                continue
            e = self.guarded(loc + ("expressions", name), parse_expression, text, scope, True)
            if e is None:
                ok = False
                continue
            if is_vector(e):            # a vector expression is kept whole, its components inline
                vectors[name] = names[name] = sp.ImmutableMatrix(e)
                continue
            s = sym(name)
            expressions[s] = e
            names[name] = s      # later expressions and the dynamics may use it
        dynamics: dict[sp.Symbol, sp.Expr] = {}
        covered: set[str] = set()
        for name, text in m.dynamics.items():
            if name in m.states and name not in names:     # an invalid state name, reported above
                ok = False
                continue
            targets = self.dynamics_targets(name, m, vectors, loc)
            if targets is None:
                ok = False
                continue
            covered.update(targets)
            e = self.guarded(loc + ("dynamics", name), parse_expression, text, scope, len(targets) > 1)
            if e is None:
                ok = False
                continue
            values = list(e) if is_vector(e) else [e]
            if len(values) != len(targets):
                self.issue(loc + ("dynamics", name), f"'{name}' has {len(targets)} components but its "
                           f"right-hand side has {len(values)}")
                ok = False
                continue
            for target, value in zip(targets, values):
                if names[target] in dynamics:
                    self.issue(loc + ("dynamics", name), f"dynamics of '{target}' given twice")
                    ok = False
                dynamics[names[target]] = value
        for i, s in enumerate(m.states):
            if s not in covered and s in names:
                self.issue(loc + ("states", i), f"state '{s}' has no dynamics (add `{s}: ...` under dynamics)")
                ok = False
        if not ok:
            return None
        return Model(self.spec.name, tuple(names[s] for s in m.states), tuple(names[c] for c in m.controls),
                     dynamics, params, expressions, dict(m.units), "", tuple(m.positions), vectors)

    def vector_groups(self, groups: dict[str, list[str]], names: dict, loc: tuple) -> dict[str, sp.ImmutableMatrix]:
        """``vectors: {r: [x, y, z]}``: each a column of declared names, added to ``names``."""
        out: dict[str, sp.ImmutableMatrix] = {}
        for vname, comps in groups.items():
            where = loc + ("vectors", vname)
            if not NAME_RE.match(vname) or vname in names or vname in RESERVED:
                self.issue(where, f"'{vname}' cannot name a vector (reserved, declared or not an identifier)")
                continue
            unknown = [c for c in comps if c not in names or c == "t"]
            if unknown or len(comps) < 2:
                self.issue(where, f"vector '{vname}' needs at least two declared states, controls or parameters"
                           + (f"; unknown: {', '.join(map(str, unknown))}" + did_you_mean(str(unknown[0]), names)
                              if unknown else ""))
                continue
            out[vname] = names[vname] = sp.ImmutableMatrix([names[c] for c in comps])
        return out

    def dynamics_targets(self, name: str, m: ModelSpec, vectors: dict, loc: tuple) -> list[str] | None:
        """The states a line of dynamics gives: one state, or a vector of states."""
        if name in m.states:
            return [name]
        if name in vectors and name in m.vectors and all(c in m.states for c in m.vectors[name]):
            return list(m.vectors[name])
        self.issue(loc + ("dynamics", name), f"dynamics given for '{name}', which is not a state "
                   "(nor a vector of states)" + did_you_mean(name, list(m.states) + list(m.vectors)))
        return None

    # -- phases ---------------------------------------------------------------------
    def phase(self, name, model, time: TimeSpec, constraints, guess, loc, top_params, values) -> Phase | None:
        if model is None:
            return None
        multi = self.spec.phases is not None
        prefix = f"{name}." if multi else ""
        constants = {s: v for s, v in model.parameters.items() if v is not None and s not in self.free}
        constants.update({s: v for s, v in top_params.items() if v is not None})
        constants.update(self.phase_values(name, model, top_params, values, loc))
        # ``symbolic``: constants left as symbols (not folded), for a model built once with
        # them as mutable Pyomo Params and re-solved at each study point (ocdsl/solve/reuse.py)
        for s in [s for s in constants if s.name in getattr(self, "symbolic", ())]:
            del constants[s]
        for s, v in model.parameters.items():
            if v is None and s not in self.free:
                self.issue(loc, f"model parameter '{s}' has no value; give it under model: parameters:")
        t0s, tfs = sym(prefix + "t0"), sym(prefix + "tf")
        tf = None if time.tf == "free" else float(time.tf)
        t0 = None if time.t0 == "free" else float(time.t0)
        if tf is not None and t0 is not None and tf <= t0:
            self.issue(loc + ("time", "tf"), f"tf = {tf} must be greater than t0 = {t0}")
        guess_items = dict(guess.model_extra or {})
        known = {s.name for s in model.states + model.controls} | {p.name for p in self.free}
        for k in guess_items:
            if k not in known:
                self.issue(loc + ("guess", k), f"guess for unknown variable '{k}'" + did_you_mean(k, known))
            elif not _guess_value_ok(guess_items[k]):
                self.issue(loc + ("guess", k), f"guess for '{k}': a finite number, a list of finite numbers "
                           "or {t: [...], values: [...]} of the same length")
        check_guess(self.path, guess, loc, self.issue)
        # a problem file, or a transform, is a chain (ocdsl/chain): its stages give `from` at run time
        chained = guess.from_ is not None and (is_problem_file(guess.from_) or guess.transform is not None)
        guess_dict = {"values": guess_items, "tf": guess.tf, "from": None if chained else guess.from_,
                      "random": guess.random, "seed": guess.seed,
                      "chain": {"from": guess.from_, "transform": guess.transform, "reuse": guess.reuse,
                                "file": str(self.path)} if chained else None}
        return Phase(name, model, constants, t0, tf, t0s, tfs, guess=guess_dict)

    def phase_values(self, phase: str, model: Model, top_params, values: dict, loc) -> dict[sp.Symbol, float]:
        """A phase's own values of constants of its model or of the file (``parameters:`` under
        the phase); ``--param PHASE.NAME=VALUE`` overrides one."""
        known = {s.name: s for s in model.parameters} | {s.name: s for s in top_params}
        out = {}
        for pname, value in values.items():
            where = loc + ("parameters", pname)
            s = known.get(pname)
            if s is None:
                self.issue(where, f"'{pname}' is not a parameter of phase '{phase}''s model nor of the file"
                           + did_you_mean(pname, known))
                continue
            if s in self.free:
                self.issue(where, f"'{pname}' is a free parameter: it takes one value for the whole problem")
                continue
            key = f"{phase}.{pname}"
            if key in self.overrides:
                value = float(self.overrides[key])
                self.used_overrides.add(key)
            if not math.isfinite(value):
                self.issue(where, f"parameter '{pname}' is not a finite number")
                continue
            out[s] = float(value)
            self.constants_in_force[key] = float(value)
        return out

    def scope(self, ph: Phase | None, phases: list[Phase], link: bool = False) -> Scope:
        names: dict[str, sp.Basic] = {}
        if ph is not None:
            names["t"] = TIME
            for s in ph.states + ph.controls + tuple(ph.model.parameters) + tuple(ph.model.expressions):
                names[s.name] = s
            names.update(ph.model.vectors)
            names["t0"], names["tf"] = ph.t0_symbol, ph.tf_symbol
        for s in self.free:
            names[s.name] = s
        for pname in self.spec.parameters:
            names.setdefault(pname, sym(pname))
        phase_names = {p.name: {"t0": p.t0_symbol, "tf": p.tf_symbol, "phase": p} for p in phases} \
            if self.spec.phases is not None else {}

        def boundary(phase_name, var, which):
            target = ph
            if phase_name is not None:
                target = phase_names[phase_name]["phase"]
            elif target is None:
                raise ExprError(f"name the phase of {var}({which}), e.g. {phases[0].name}.{var}({which})")
            model = target.model
            if var in {s.name for s in target.states}:
                return state_at(target, var, which)
            if var in model.vectors or var in {s.name for s in model.expressions}:
                return expression_at(target, var, which)
            raise ExprError(f"'{var}' is not a state (nor a named expression) of phase '{target.name}'" +
                            did_you_mean(var, [s.name for s in target.states + tuple(model.expressions)]
                                         + list(model.vectors)))

        def state_at(target, var, which):
            label = f"{target.name}.{var}({which})" if self.spec.phases is not None else f"{var}({which})"
            s = sym(label)
            self.boundary_values[s] = BoundaryValue(target.name, target.model.symbol(var), which)
            return s

        def expression_at(target, var, which):
            """``E(tf)``: the named expression (or vector) of the states at that end."""
            model = target.model
            value = model.vectors[var] if var in model.vectors else model.symbol(var)
            parts = [target.substitute(c) for c in (value if is_vector(value) else [value])]
            used = set().union(*[p.free_symbols for p in parts])
            controls = sorted(c.name for c in used & set(target.controls))
            if controls:
                raise ExprError(f"'{var}' uses the control{'s' * (len(controls) > 1)} {', '.join(controls)}, "
                                f"which has no value at {which}: a boundary value uses states only")
            subs = {s: state_at(target, s.name, which) for s in used & set(target.states)}
            subs[TIME] = target.tf_symbol if which == "tf" else target.t0_symbol
            parts = [p.xreplace(subs) for p in parts]
            return sp.ImmutableMatrix(parts) if is_vector(value) else parts[0]

        def integral(integrand):
            target = ph
            if target is None:
                raise ExprError("integral(...) belongs to a phase; write it in the phase's objective or constraints")
            if integrand.has(*[s for p in phases for s in (p.t0_symbol, p.tf_symbol)]) or \
                    any(s in self.boundary_values for s in integrand.free_symbols):
                raise ExprError("an integrand may use states, controls, t and parameters, not boundary values")
            self.integral_count += 1
            s = sym(f"integral{self.integral_count}_{target.name}")
            target.integrals[s] = target.substitute(integrand)
            return s

        return Scope(names, boundary, integral, {k: {"t0": v["t0"], "tf": v["tf"]} for k, v in phase_names.items()},
                     self.tables)

    def expression(self, text, ph, phases) -> sp.Expr:
        e = parse_expression(text, self.scope(ph, phases))
        return ph.substitute(e) if ph is not None else self.substitute_top(e)

    def substitute_top(self, e: sp.Expr) -> sp.Expr:
        from ..symbolic.numbers import substitute_numbers

        return substitute_numbers(e, {k: sp.Float(v) for k, v in getattr(self, "top_constants", {}).items()})

    def objective(self, text: str, ph, phases) -> Objective:
        m = re.match(r"^\s*(minimize|maximize)\s+(.+)$", str(text), re.S)
        if not m:
            raise ExprError("the objective is written `minimize EXPR` or `maximize EXPR`", str(text))
        expr = self.expression(m.group(2), ph, phases)
        if ph is not None:
            bare = expr.free_symbols & set(ph.states + ph.controls + (TIME,))
            if bare:
                names = ", ".join(sorted(s.name for s in bare))
                raise ExprError(f"the objective uses {names} without a time: write e.g. {sorted(bare, key=str)[0]}(tf), "
                                f"or integral(...) for a running cost", str(text))
        return Objective(m.group(1), expr, str(text))

    def constraints(self, ph: Phase, phases, texts, loc) -> list[Constraint]:
        if len(texts) > MAX_CONSTRAINTS:
            self.issue(loc, f"{len(texts)} constraints: more than the limit of {MAX_CONSTRAINTS}")
            return []
        out: list[Constraint] = []
        for i, text in enumerate(texts):
            out += self.relations(ph, phases, text, loc + (i,))
        return out

    def relations(self, ph: Phase | None, phases, text: str, loc: tuple, link: bool = False) -> list[Constraint]:
        rels = self.guarded(loc, parse_relation, text, self.scope(ph, phases, link))
        if rels is None:
            return []
        line = self.located.line(loc)
        sub = ph.substitute if ph is not None else self.substitute_top
        parts: dict[sp.Expr, list[float]] = {}
        for r in rels:
            lhs, rhs = sub(r.lhs), sub(r.rhs)
            op = r.op
            if _is_number(rhs):
                expr, value = lhs, rhs
            elif _is_number(lhs):
                expr, value, op = rhs, lhs, {"<=": ">=", ">=": "<=", "==": "=="}[op]
            else:
                expr, value = sp.expand(lhs - rhs) if False else lhs - rhs, sp.Integer(0)
            if _is_number(expr):
                self.issue(loc, "this relation has no variables in it", text)
                return []
            v = float(value)
            lo, hi = parts.setdefault(expr, [-INF, INF])
            if op == "==":
                if not math.isfinite(v):
                    self.issue(loc, "an equality with an infinite value", text)
                    return []
                parts[expr] = [max(lo, v), min(hi, v)]
            elif op == "<=":
                parts[expr][1] = min(hi, v)
            else:
                parts[expr][0] = max(lo, v)
        out = []
        for expr, (lo, hi) in parts.items():
            if lo > hi:
                self.issue(loc, f"empty range: lower bound {lo} above upper bound {hi}", text)
                continue
            c = self.classify(ph, expr, lo, hi, text, line, loc)
            if c is not None:
                out.append(c)
        return out

    def classify(self, ph, expr, lo, hi, text, line, loc) -> Constraint | None:
        """Box bounds go to the phase; path constraints to the phase; the rest are boundary constraints."""
        syms_ = expr.free_symbols
        if ph is not None:
            bare = syms_ & (set(ph.states + ph.controls) | {TIME})
            if bare:
                if syms_ & set(self.boundary_values) or syms_ & {ph.t0_symbol, ph.tf_symbol}:
                    self.issue(loc, "a constraint cannot mix path values (bare states/controls/t) with "
                               "boundary values or t0/tf", text)
                    return None
                if expr in ph.state_bounds or expr in ph.control_bounds or expr in set(ph.states + ph.controls):
                    table = ph.state_bounds if expr in ph.states else ph.control_bounds
                    table[expr] = self.narrowed(ph, expr, table.get(expr, (-INF, INF)), lo, hi, text, loc)
                    return None
                ph.path.append(Constraint(expr, lo, hi, text, line))
                return None
            if expr == ph.tf_symbol or expr == ph.t0_symbol:
                which = "tf" if expr == ph.tf_symbol else "t0"
                fixed = ph.tf if which == "tf" else (None if ph.t0 is None else ph.t0)
                if fixed is not None and not (lo <= fixed <= hi):
                    self.issue(loc, f"{which} is fixed at {fixed} by `time:`, outside this range", text)
                    return None
                if which == "tf" and ph.t0 is not None and hi <= ph.t0:
                    self.issue(loc, f"tf must be greater than t0 = {ph.t0:g}; this leaves it no room", text)
                    return None
                setattr(ph, f"{which}_bounds",
                        self.narrowed(ph, expr, getattr(ph, f"{which}_bounds"), lo, hi, text, loc))
                return None
        return Constraint(expr, lo, hi, text, line)

    def narrowed(self, ph, expr, old, lo, hi, text, loc) -> tuple[float, float]:
        """A later bound on the same quantity intersects the earlier ones (never replaces
        them); an empty intersection names the constraint that set the other side."""
        seen = self.__dict__.setdefault("bound_texts", {})
        key = (ph.name, expr)
        new = (max(old[0], lo), min(old[1], hi))
        if new[0] > new[1]:
            other = seen.get((key, "lo" if new[0] > hi else "hi"), "an earlier bound")
            self.issue(loc, f"contradicts `{other}`: {expr} would have to lie in [{new[0]:g}, {new[1]:g}]", text)
            return old
        if lo > old[0]:
            seen[(key, "lo")] = text
        if hi < old[1]:
            seen[(key, "hi")] = text
        return new

    def parse_expect(self, key: str, problem: Problem) -> sp.Expr:
        if key == "objective":
            return sym("objective")
        multi = self.spec.phases is not None
        ph = None if multi else problem.phases[0]
        return self.expression(key, ph, problem.phases)

    # -- description for the report ------------------------------------------------------
    def describe(self, phases: list[Phase], obj: Objective, multi: bool) -> dict:
        desc: dict[str, Any] = {"name": self.spec.name, "description": self.spec.description, "phases": {},
                                "parameters": {}, "units": {}, "positions": [], "links": list(self.spec.links)}
        for ph in phases:
            f = ph.model
            shown = lambda e: sp.latex(e.xreplace(self.table_calls))  # noqa: E731  tables by name
            dyn = {s.name: shown(f.dynamics[s]) for s in f.states}
            bounds = {s.name: [_num(b[0]), _num(b[1])] for s, b in {**ph.state_bounds, **ph.control_bounds}.items()}
            texts = self.spec.problem.constraints if self.spec.phases is None else self.spec.phases[ph.name].constraints
            desc["phases"][ph.name] = {
                "states": [s.name for s in f.states], "controls": [c.name for c in f.controls],
                "dynamics_latex": dyn,
                "expressions_latex": {s.name: shown(e) for s, e in f.expressions.items()},
                "bounds": bounds, "constraints": list(texts),
                "t0": ph.t0 if ph.t0 is not None else "free", "tf": ph.tf if ph.tf is not None else "free"}
            desc["units"].update(f.units)
            desc["positions"] = list(f.positions) or desc["positions"]
            if f.time_state:        # the independent variable is not time: reports plot against this
                desc["time_variable"] = f.time_state
            for s, v in ph.constants.items():
                desc["parameters"][s.name] = {"value": v, "free": False}
        for s, fp in self.free.items():
            desc["parameters"][s.name] = {"value": fp.guess, "free": True, "bounds": [_num(fp.lower), _num(fp.upper)]}
        desc["objective"] = {"sense": obj.sense, "text": obj.text, "latex": sp.latex(obj.expr)}
        return desc


def _broken_table(name: str):
    def call(*_):
        raise ExprError(f"table '{name}' has an error (reported at its line)")
    return call


def _validate_method(method: dict) -> Any:
    kind = method.get("transcription", "LGR")
    if not isinstance(kind, str):
        raise ValueError(f"transcription: a method name such as LGR, not {kind!r}")
    if kind in PSEUDOSPECTRAL:
        return PseudospectralMethod.model_validate(method)
    from ..methods import method_spec  # other back ends register their method specs

    return method_spec(kind, method)


def _is_number(e: sp.Expr) -> bool:
    return bool(getattr(e, "is_number", False)) and (e.is_finite or e in (sp.oo, -sp.oo))


def _num(x: float):
    return x if math.isfinite(x) else None


def _guess_value_ok(value) -> bool:
    """A guess is a number, a list of numbers or {t: [...], values: [...]}, all finite."""
    def numbers(v):
        return isinstance(v, list) and len(v) > 0 and all(_finite(x) for x in v)
    if isinstance(value, dict):
        return set(value) == {"t", "values"} and numbers(value["t"]) and numbers(value["values"]) \
            and len(value["t"]) == len(value["values"])
    return _finite(value) or numbers(value)


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _midpoint(lo, hi) -> float:
    if lo is not None and hi is not None:
        return 0.5 * (lo + hi)
    return lo if lo is not None else (hi if hi is not None else 0.0)
