"""The compiler of a validated problem file: top level, tables, method, the problem's
assembly and its description for the report; models, phases and constraints in their
own modules (mixed in)."""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pydantic
import sympy as sp

from ...hints import did_you_mean
from ...symbolic.latex import latex
from ...symbolic.model import TIME
from ...symbolic.problem import INF, BoundaryValue, Constraint, FreeParameter, Objective, Phase, Problem
from ..errors import ExprError, FollowOnError, Issue, SpecError, UnknownNames
from ..expr import RESERVED, parse_continuity
from ..loader import Located
from ..schema import ProblemFile
from ..validate import _document_loc, _issue_from_pydantic, _schema_issues, _set_aside, _source_line
from .common import MAX_CONSTRAINTS, NAME_RE, _broken_table, _method_class, _num, _validate_method
from .loaded import LoadedFile
from .constraints import ConstraintCompiler
from .models import ModelCompiler
from .phases import PhaseCompiler


def validated_method(located: Located, data: dict) -> tuple[Any, list[Issue]]:
    """The method block validated by its back end's spec, or None and its issues at their
    own lines (also where the rest of the file failed the schema: one pass, unseen12 F6)."""
    try:
        return _validate_method(data), []
    except pydantic.ValidationError as e:
        return None, _schema_issues(located, [dict(err, loc=("method",) + tuple(err["loc"])) for err in e.errors()],
                                    root=(("method",), _method_class(data)))
    except (ValueError, KeyError) as e:
        loc = ("method", "transcription") if "transcription" in data else ("method",)
        return None, [located.issue(loc, str(e).strip("'\""), _source_line(located, loc))]


class Compiler(ModelCompiler, PhaseCompiler, ConstraintCompiler):
    def __init__(self, path: Path, located: Located, spec: ProblemFile, overrides: dict[str, float]):
        self.path, self.located, self.spec = path, located, spec
        self.overrides = dict(overrides)
        # name (or PHASE.NAME) -> the file's value, for each override applied: the report's
        # "overridden (file: ...)" note comes from here only
        self.file_values: dict[str, float | None] = {}
        self.issues: list[Issue] = []
        self.refused_names: set[str] = set()   # declared names refused: their uses are no new error
        self.boundary_values: dict[sp.Symbol, BoundaryValue] = {}
        self.free: dict[sp.Symbol, FreeParameter] = {}
        self.free_locs: dict[sp.Symbol, tuple] = {}     # where each is declared, for errors
        self.integral_count = 0
        self.tables: dict = {}
        self.table_calls: dict = {}
        # ((phase, quantity), "lo" | "hi") -> the constraint text that set that side of its bounds
        self.bound_texts: dict[tuple, str] = {}
        self.bound_lines: dict[tuple, int | None] = {}

    def issue(self, loc: tuple, message: str, text: str | None = None) -> None:
        if text is None:
            text = _source_line(self.located, loc)
        self.issues.append(self.located.issue(loc, message, text))

    def refused_parameters(self) -> set[str]:
        """Parameters written in the file (top level or an inline model) that validation
        refused, so that the spec lacks them."""
        data = self.located.data if isinstance(self.located.data, dict) else {}
        written, kept = set(), set(self.spec.parameters)
        for block, spec_block in ((data, self.spec), (data.get("model"), self.spec.model)):
            raw = block.get("parameters") if isinstance(block, dict) else None
            if isinstance(raw, dict):
                written |= {str(k) for k in raw}
            if spec_block is not None:
                kept |= set(getattr(spec_block, "parameters", None) or {})
        return written - kept

    def guarded(self, loc: tuple, fn, *args):
        """Run fn; turn ExprError/ValueError into an issue at ``loc`` and return None."""
        try:
            return fn(*args)
        except FollowOnError:      # the root error is reported where it is
            pass
        except UnknownNames as e:
            # a parameter whose value validation refused is reported there, not at each use
            # (`c: 1/0`, then 'unknown name c' wherever c is used)
            rest = e.without(self.refused_parameters())
            if rest is not None:
                self.issue(loc, rest.message, rest.text or None)
        except ExprError as e:
            # an expression that fails on a declared name already refused (`lambda`, a Python
            # keyword: "syntax error" after "not a valid state name", unseen55 F5) is its echo
            if not any(isinstance(a, str) and _mentions(a, self.refused_names) for a in args):
                self.issue(loc, e.message, e.text or None)
        except (ValueError, KeyError) as e:
            self.issue(loc, str(e).strip("'\""))
        except RecursionError:     # SymPy on expressions nested inside others past its depth
            self.issue(loc, "expressions nested too deeply (named expressions inside each other)")
        return None

    def compile(self) -> LoadedFile:
        spec = self.spec
        method = self.validated_method(spec.method)
        self.tables = self.build_tables()
        problem = None
        if spec.problem is not None or spec.phases is not None:
            problem = self.build_problem()
        check = getattr(method, "problems_with", None)
        if problem is not None and check is not None:
            for where, message in check(problem):
                self.issue(("method",) + where, message)
        expect = {}
        if problem is not None:
            for key in spec.expect:
                e = self.guarded(("expect", key), self.parse_expect, key, problem)
                if e is not None:
                    expect[key] = e
        model = controller = None
        if spec.controller is not None and problem is not None:
            # one or the other: the controller block was silently not read (helper review)
            self.issue(("controller",), "a file has either a controller: block (a closed-loop study) or "
                                        "problem:/phases: (an optimal control problem), not both")
        if spec.controller is not None and problem is None and spec.expect:
            # its laws' costs are in result.json extra.<law>.cost; an expect was silently never checked
            self.issue(("expect",), "expect: is not checked in a controller file (each law's cost J is in "
                                    "result.json extra.<law>.cost and printed by ocdsl run); remove it")
        if spec.controller is not None and problem is None:
            self.used_overrides = set()
            self.constants_in_force = {}
            model = self.model(spec.model, ("model",)) if spec.model else None
            controller = self.guarded_pydantic(("controller",), "ocdsl.spec.controller", "ControllerSpec",
                                               spec.controller)
            if model is not None and controller is not None:
                self.check_controller(model, controller)
        unused = set(self.overrides) - self.used_overrides if hasattr(self, "used_overrides") else set()
        # a free parameter is in the file but the solver chooses it: "not in the file" misled
        free = {s.name: loc for s, loc in self.free_locs.items()}
        for name in sorted(n for n in unused if n.rpartition(".")[2] in free):
            unused.discard(name)
            self.issue(free[name.rpartition(".")[2]],
                       f"'{name}' is a free parameter (optimised by the solver), which --param cannot set: "
                       "--param and a study's parameters set constants; to fix its value, drop `free: true`")
        if unused:
            self.issue((), f"parameters given on the command line or by a study are not in the file: {sorted(unused)}", "")
        if self.issues:
            raise SpecError(self.issues)
        return LoadedFile(self.path, self.located, spec, problem, method, expect,
                          getattr(self, "constants_in_force", {}), model, controller)

    def build_tables(self) -> dict:
        """The file's ``tables:``, each a function for expressions; a call is shown as
        ``NAME(args)`` in the report (``self.table_calls``), not as its spline expansion."""
        out, self.table_calls = {}, {}
        if not self.spec.tables:
            return out                  # the spline code (ocdsl.symbolic.tables) stays unloaded
        from ..tables import TableError, build_table

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
        method, issues = validated_method(self.located, data)
        self.issues += issues
        return method

    def check_controller(self, model, controller) -> None:
        """The controller block against its plant, at compile time (``ocdsl check``): Q and R
        of the plant's sizes, x0 naming its states, given A/B entries inside their matrices
        (unseen9 F4: a 1x1 Q for two states passed the check and the run ended 'error')."""
        from ...symbolic.sdc import _split_states

        try:
            xs, _ = _split_states(model, controller.auxiliary, controller.states)
        except ValueError as e:
            self.issue(("controller", "states" if controller.states else "auxiliary"), str(e))
            return
        n, m = len(xs), len(model.controls)
        values = {p: v for p, v in model.parameters.items() if v is not None}
        for state, rhs in model.dynamics.items():
            # `--param l=0` in a pendulum: the laws' code failed with KeyError: 'ComplexInfinity'
            if values and sp.sympify(rhs).xreplace(values).has(sp.zoo, sp.nan, sp.oo, -sp.oo):
                shown = ", ".join(f"{p} = {v:g}" for p, v in values.items() if p in rhs.free_symbols)
                self.issue(("model", "dynamics", state.name), f"with {shown} the right-hand side of {state.name} "
                                                              "is not finite (a division by zero)")
        names = ", ".join(str(s) for s in xs)
        for key, size, what in (("Q", n, f"the {n} controlled states ({names})"), ("R", m, f"the {m} controls")):
            try:
                controller.matrix(key, size)
            except ValueError as e:
                self.issue(("controller", key), f"{e} (for {what})")
        try:
            controller.simulate.initial_state([s.name for s in model.states])
        except ValueError as e:
            self.issue(("controller", "simulate", "x0"), str(e))
        from ...control.simulate import saturation_limits

        try:
            saturation_limits(controller.saturation, m)
        except ValueError as e:
            self.issue(("controller", "saturation"), f"{e} (for the {m} control(s))")
        if controller.robustness is not None:
            names = [str(p) for p in model.parameters]
            for i, name in enumerate(controller.robustness.parameters):
                if name not in names:
                    self.issue(("controller", "robustness", "parameters", i),
                               f"'{name}' is not a parameter of the model" + did_you_mean(name, names)
                               + (f"; parameters: {', '.join(names)}" if names else " (it has none)"))
        if controller.sdc == "given":
            for key, shape in (("A", (n, n)), ("B", (n, m))):
                try:
                    controller.given_matrix(key, shape, model.symbols())
                except ValueError as e:
                    self.issue(("controller", key), str(e))

    def guarded_pydantic(self, loc: tuple, module: str, cls: str, data):
        """Validate a block with a back end's pydantic class, errors at their file lines. With
        errors, what is left once the entries they name are set aside is validated again, and
        that partial block returned, so that the checks that need a valid block (sizes against
        the model, cross-field rules) report in the same pass (unseen12 F6: a controller file
        took four `check` runs); the issues recorded refuse the file all the same."""
        import copy
        import importlib

        klass = getattr(importlib.import_module(module), cls)
        seen: set = set()
        aside: set = set()
        for _ in range(4):
            try:
                return klass.model_validate(data)
            except pydantic.ValidationError as e:
                errors = e.errors()
            # a required entry set aside is missing now: reported already, and nothing is left
            if any(err["type"] == "missing" and _document_loc(tuple(err["loc"])) in aside for err in errors):
                return None
            new = [err for err in errors if (tuple(err["loc"]), err["msg"]) not in seen]
            for err in new:
                seen.add((tuple(err["loc"]), err["msg"]))
                self.issues.append(_issue_from_pydantic(self.located, dict(err, loc=loc + tuple(err["loc"]))))
            if not new or not isinstance(data, dict) or any(err["type"] == "missing" or not err["loc"]
                                                            for err in errors):
                return None
            data = copy.deepcopy(data)
            for err in errors:
                aside.add(_document_loc(tuple(err["loc"])))
                _set_aside(data, _document_loc(tuple(err["loc"])))
        return None

    def build_problem(self) -> Problem:
        spec = self.spec
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
        dropped = None in phases      # its error may be a table's, reported before
        phases = [p for p in phases if p is not None]
        if dropped and self.issues:
            raise SpecError(self.issues)
        # every phase stands (its names declared; a right-hand side that did not compile is
        # recorded): its constraints and the objective are compiled too, so that their own
        # mistakes come in the same pass; the file is refused at the end all the same
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
        boundary += self.time_runs_forward(phases, boundary)
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
        if obj is not None:
            self.check_objective_varies(obj, phases, ("problem", "objective") if spec.problem is not None else ("objective",))
        self.check_resolved(phases, boundary, obj)
        self.check_contradictions(boundary, phases)
        self.check_repeated(boundary, phases)
        if self.issues:
            raise SpecError(self.issues)
        desc = self.describe(phases, obj, multi)
        return Problem(spec.name, phases, obj, boundary, self.free, self.boundary_values, desc)

    def check_objective_varies(self, obj: Objective, phases: list[Phase], loc: tuple) -> None:
        """Refuse an objective that names something yet is one number once fixed times and
        constants are put in (`minimize tf` with `tf: 1`): nothing is optimised, and the run
        then failed with a mesh hint and an arbitrary answer. A bare number (`minimize 0`,
        a feasibility problem or a multi-phase file whose phases add their own costs) is meant."""
        fixed: dict = {}
        label: dict = {}
        multi = len(phases) > 1
        for ph in phases:
            fixed.update(ph.constants)
            for end, value, symbol in (("t0", ph.t0, ph.t0_symbol), ("tf", ph.tf, ph.tf_symbol)):
                if value is not None:
                    fixed[symbol] = value
                    label[symbol] = f"{ph.name}.{end}" if multi else end
        named = obj.expr.free_symbols
        written = re.sub(r"^\s*(minimize|maximize)\s+", "", obj.text).strip()
        if not named and not re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", written):
            # names that cancel (`x(tf) - x(tf)`): a constant that was not meant as one
            self.issue(loc, f"the objective `{written}` simplifies to the constant {obj.expr}, so it does not "
                            "depend on the solution: write the cost meant, or `minimize 0` for a feasibility "
                            "problem", obj.text)
            return
        if not named or sp.sympify(obj.expr.xreplace(fixed)).free_symbols:
            return
        # every name was replaced by a number (times and constants are floats)
        shown = ", ".join(sorted(f"{label.get(s, s.name)} = {fixed[s]:g}" for s in named))
        self.issue(loc, f"the objective is a constant ({shown}, fixed), so it does not depend on the solution: "
                        "free what it names (e.g. `time: {tf: free}`) or write another objective", obj.text)

    @staticmethod
    def time_runs_forward(phases: list[Phase], given: list[Constraint]) -> list[Constraint]:
        """tf >= t0 for a phase with both ends free (one fixed end bounds the other directly,
        ocdsl/spec/compile/phases.py): without it `minimize tf - t0` flew a phase backwards to a
        duration of -10 and called it optimal. Not where the file says it already (`tf - t0
        >= 0`, or a positive minimum duration): a second identical row (``check_repeated``)."""
        multi = len(phases) > 1
        out = []
        for ph in phases:
            duration = ph.tf_symbol - ph.t0_symbol
            said = any(c.expr == duration and c.lower >= 0.0 for c in given)
            if ph.t0 is None and ph.tf is None and not said:
                name = f"{ph.name}." if multi else ""
                out.append(Constraint(duration, 0.0, INF,
                                      f"{name}tf >= {name}t0 (time runs forward)"))
        return out

    def describe(self, phases: list[Phase], obj: Objective, multi: bool) -> dict:
        desc: dict[str, Any] = {"name": self.spec.name, "description": self.spec.description, "phases": {},
                                "parameters": {}, "units": {}, "positions": [], "links": list(self.spec.links)}
        for ph in phases:
            f = ph.model
            shown = lambda e: latex(e.xreplace(self.table_calls))  # noqa: E731  tables by name
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
            if f.frame is not None:     # the frame the positions are drawn in (models/cr3bp.py)
                desc["frame"] = f.frame({s.name: float(v) for s, v in ph.constants.items()})
            if f.time_state:        # the independent variable is not time: reports plot against this
                desc["time_variable"] = f.time_state
        # the constants in force under the run's names (b, and PHASE.b for a phase's own value):
        # a phase's own value does not overwrite the file's b
        for name, v in self.constants_in_force.items():
            desc["parameters"][name] = {"value": v, "free": False}
            if name in self.file_values:
                desc["parameters"][name]["file"] = self.file_values[name]
        for s, fp in self.free.items():
            desc["parameters"][s.name] = {"value": fp.guess, "free": True, "bounds": [_num(fp.lower), _num(fp.upper)]}
        desc["objective"] = {"sense": obj.sense, "text": obj.text, "latex": latex(self.shown_integrals(obj.expr, phases))}
        return desc

    @staticmethod
    def shown_integrals(expr: sp.Expr, phases: list[Phase]) -> sp.Expr:
        """``expr`` with each integral's internal symbol (``integral1_main``) as the integral
        it stands for, over its phase's time: what the report typesets."""
        multi = len(phases) > 1
        subs = {}
        for ph in phases:
            t0, tf = (sp.Symbol(f"t_{{{k},{ph.name}}}" if multi else f"t_{k}") for k in ("0", "f"))
            subs.update({s: sp.Integral(e, (TIME, t0, tf)) for s, e in ph.integrals.items()})
        return expr.xreplace(subs)


def _mentions(text: str, names: set[str]) -> bool:
    """``text`` uses one of ``names`` as a whole word."""
    return any(re.search(rf"(?<![\w.]){re.escape(n)}(?!\w)", text) for n in names)
