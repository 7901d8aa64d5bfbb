"""The problem-file schema (pydantic v2). Unknown keys are errors everywhere.

Expressions and relations stay strings here; :mod:`ocdsl.symbolic.build` parses them
with the safe parser of :mod:`ocdsl.spec.expr`. The JSON Schema printed by
``ocdsl schema`` is generated from these classes.
"""
from __future__ import annotations

import json
import math
from functools import lru_cache
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, WithJsonSchema, field_validator, model_validator

Expr = Union[str, int, float]
Number = Union[int, float]


class Strict(BaseModel):
    # NaN and infinity mean nothing as a time, bound, guess or setting (a NaN t0 once ran
    # "optimal" with every time NaN); an open bound is written null
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def constant_value(text: str) -> float:
    """The number a constant expression (`2*pi`, `9.81/2`) stands for; ValueError saying why
    not (another name, 1/0, sqrt(-1))."""
    from .expr import ExprError, Scope, parse_expression

    try:
        e = parse_expression(text, Scope({}))
    except ExprError as err:
        raise ValueError(f"`{text}` is not a number nor a constant expression (numbers, pi, e): {err.message}") from None
    if e.free_symbols or not e.is_number:
        raise ValueError(f"`{text}` is not a number nor a constant expression (numbers, pi, e)")
    value = complex(e.evalf())
    if value.imag != 0 or not math.isfinite(value.real):
        raise ValueError(f"`{text}` has no finite real value")
    return value.real


def _constant_values(values):
    """``{c: 2*pi}`` and ``{c: {value: 2*pi}}`` as numbers (unseen12 F8: the docs allow
    `tf: 2*pi`, and a parameter written so was 'unable to parse string as a number')."""
    if not isinstance(values, dict):
        return values
    out = {}
    for name, item in values.items():
        if isinstance(item, str):
            item = constant_value(item)
        elif isinstance(item, dict) and isinstance(item.get("value"), str):
            item = {**item, "value": constant_value(item["value"])}
        out[name] = item
    return out


class ParameterSpec(Strict):
    """A parameter: a constant (``value``) or a free scalar optimised with the trajectory."""

    value: float | None = Field(None, description="constant value, or the initial guess when free")
    free: bool = Field(False, description="optimise this parameter")
    bounds: tuple[float | None, float | None] | None = Field(None, description="[lower, upper] when free")
    unit: str | None = None
    integer: bool = Field(False, description="integer decision variable (parametric methods only)")

    @model_validator(mode="after")
    def _check(self):
        if not self.free and self.value is None:
            raise ValueError("a constant parameter needs a value (or set free: true)")
        if self.bounds and None not in self.bounds and self.bounds[0] > self.bounds[1]:
            raise ValueError(f"bounds reversed: {list(self.bounds)}")
        return self


class ModelSpec(Strict):
    """Either ``use:`` a registered model, or declare states, controls and dynamics inline."""

    use: str | None = Field(None, description="name of a registered SymPy model (see `ocdsl models`)")
    options: dict[str, Any] = Field(default_factory=dict, description="options of the registered model")
    states: list[str] = Field(default_factory=list)
    controls: list[str] = Field(default_factory=list)
    parameters: Annotated[dict[str, Union[float, ParameterSpec]], BeforeValidator(_constant_values)] = \
        Field(default_factory=dict)
    expressions: dict[str, Expr] = Field(default_factory=dict, description="named intermediate quantities")
    dynamics: dict[str, Expr] = Field(default_factory=dict, description="state: right-hand side")
    vectors: dict[str, list[str]] = Field(default_factory=dict, description="named vectors of states, controls "
                                          "or parameters, e.g. {r: [x, y, z]}: usable as r, norm(r), cross(r, v), "
                                          "r(tf), and as one line of dynamics")
    units: dict[str, str] = Field(default_factory=dict)
    positions: list[str] = Field(default_factory=list, description="states forming a position vector")

    @model_validator(mode="after")
    def _check(self):
        if self.use is None:
            if not self.states:
                raise ValueError("declare `states:` (or `use:` a registered model)")
            if not self.dynamics:
                raise ValueError("declare `dynamics:` for every state (or `use:` a registered model)")
        elif self.states or self.dynamics or self.controls:
            raise ValueError("`use:` a registered model or declare states/controls/dynamics, not both")
        return self


def constant_number(value, allow_names: bool = False):
    """A number written as a constant expression (``2*pi``, ``sqrt(2)/3``), read by the safe
    parser with no names but the constants; anything that is not a number stays as it is for
    the field's own check (so `free` and a wrong type keep their messages)."""
    if not isinstance(value, str) or value.strip() == "free":
        return value
    from .errors import ExprError
    from .expr import Scope, parse_expression

    why = "not a finite real number"
    try:
        e = parse_expression(value, Scope({}))
        if e.is_number and e.is_real and e.is_finite:
            return float(e)
    except ExprError as err:
        if allow_names and err.message.startswith("unknown name"):
            return value       # names a parameter, perhaps: the compiler resolves it
        why = err.message
    raise ValueError(f"`{value}` is not a number ({why}): write a number, a constant expression "
                     "such as 2*pi or sqrt(2)/3" + (", an expression of the file's constants" if allow_names
                                                    else " (no parameters)") + ", or `free`")


# what a file may write (the JSON Schema of `ocdsl schema`): a number, `free`, or a constant
# expression such as 2*pi, which the "before" validators turn into a number
_EXPRESSION = {"type": "string", "description": "a constant expression such as 2*pi (no names but pi)"}
_TIME_EXPRESSION = {"type": "string", "description": "an expression of constants and the file's constant "
                                                     "parameters, such as 2*pi or T"}
TimeValue = Annotated[Union[float, Literal["free"], str], WithJsonSchema(
    {"anyOf": [{"type": "number"}, {"const": "free", "type": "string"}, _TIME_EXPRESSION]})]
# a constraints/links item may itself be a list (`- *bounds`, an anchored list of shared
# relations), spliced in its place by the validator (spec/validate.py splice_lists)
Relations = Annotated[list[str], WithJsonSchema(
    {"type": "array", "items": {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}]}})]
GuessTime = Annotated[Union[float, None], WithJsonSchema({"anyOf": [{"type": "number"}, _EXPRESSION, {"type": "null"}]})]


class TimeSpec(Strict):
    t0: TimeValue = Field(0.0, description="initial time (a number or a constant expression "
                                              "such as 2*pi), or `free` (e.g. a later phase linked to the one before)")
    tf: TimeValue = Field(..., description="final time (a number or a constant expression such "
                                              "as 2*pi), or `free` (bounds as a constraint `lo <= tf <= hi`)")

    @field_validator("t0", "tf", mode="before")
    @classmethod
    def _constant(cls, v):
        # `tf: T` names a constant parameter: kept as text, resolved with the phase's constants
        # (spec/compile/phases.py); it said "unknown name 'T'" of a declared parameter (unseen9 F11)
        return constant_number(v, allow_names=True)


GuessValue = Union[float, list[float], dict[str, list[float]]]


class GuessSpec(Strict):
    """Initial guess: per variable a constant, ``[start, end]`` (linear) or ``{t: [...], values: [...]}``."""

    model_config = ConfigDict(extra="allow")
    t0: GuessTime = None
    tf: GuessTime = None

    @field_validator("t0", "tf", mode="before")
    @classmethod
    def _constant(cls, v):
        return constant_number(v)
    from_: str | None = Field(None, alias="from", description="a previous run folder to start from, or a "
                              "problem file solved first (docs/problem-language.md, \"Chains\")")
    transform: str | None = Field(None, description="a registered change of variables from the source's "
                                  "trajectory to this problem's (`ocdsl transforms`); default identity")
    reuse: str | None = Field(None, description="a run folder of the `from` problem file used instead of "
                              "solving it again when its problem.yaml is that file as it is now")
    random: bool = Field(False, description="seeded random controls inside their bounds")
    seed: int | None = None


class PhaseSpec(Strict):
    model: ModelSpec | None = Field(None, description="defaults to the file's top-level model")
    parameters: Annotated[dict[str, float], BeforeValidator(_constant_values)] = Field(
        default_factory=dict, description="this phase's values of constants "
                                         "of its model or of the file, e.g. {T: 4.5e6} (one model, several phases)")
    time: TimeSpec
    constraints: Relations = Field(default_factory=list)
    guess: GuessSpec = Field(default_factory=GuessSpec)
    objective: str | None = Field(None, description="phase contribution, e.g. integral(u**2)")


class ProblemSpec(Strict):
    time: TimeSpec
    constraints: Relations = Field(default_factory=list)
    objective: str = Field(..., description="`minimize EXPR` or `maximize EXPR`")
    guess: GuessSpec = Field(default_factory=GuessSpec)


class MeshSpec(Strict):
    """Adaptive mesh refinement (docs/mesh-refinement.md). The starting mesh is the method's
    ``segments``/``degree`` when given there, else this block's ``segments``/``degree``."""

    tolerance: float = Field(1e-6, gt=0, description="largest relative error per segment")
    max_iterations: int = Field(10, ge=1, description="mesh iterations (solves) at most")
    min_degree: int = Field(3, ge=1, description="degree of new segments")
    max_degree: int = Field(12, ge=2, description="above it a segment is split")
    segments: Union[int, list[float]] = Field(2, description="starting mesh when the method gives none")
    degree: Union[int, list[int]] = Field(3, description="starting degree when the method gives none")
    bracket_pieces: int = Field(2, ge=1, le=10, description="pieces a switch bracket is cut into")
    corner_tolerance: float = Field(1e-5, gt=0, description="a located control corner farther than this "
                                    "(normalised time) from a breakpoint keeps refining")
    snap: float = Field(0.25, ge=0, le=0.5, description="a located switch/corner this close to a breakpoint "
                        "(fraction of its segment's width) moves that breakpoint onto it instead of a split")
    coarsen: bool = Field(True, description="once converged, merge segments and lower degrees where a "
                          "polynomial fits within coarsen_margin * tolerance, and check by solving again")
    coarsen_margin: float = Field(0.1, gt=0, le=1, description="fit error allowed by coarsening, "
                                  "as a fraction of tolerance")
    lowest_degree: int = Field(1, ge=1, description="coarsening lowers a segment's degree down to this")
    smooth_control: bool = Field(False, description="where the error with the collocated control is above "
                                 "tolerance on a chattering or interior arc, also integrate with a smoothed "
                                 "control and keep the smaller error (docs/mesh-refinement.md: did not help Goddard)")
    growth: float = Field(3.0, ge=1.0, description="a refinement at most multiplies the segment count by this "
                          "(the segments with the largest errors are refined first)")
    regularise: float = Field(0.0, ge=0, description="weight w of w * int (du/ds)^2 ds added to the objective on "
                              "the arcs where the control has chattered (singular arcs; off when 0); the reported "
                              "objective leaves it out (docs/mesh-refinement.md)")
    warm_start: Literal["multipliers", "primal"] = Field(
        "multipliers", description="how each new mesh's solve starts from the previous mesh's solution: "
        "'multipliers' = states, controls and all NLP multipliers mapped through the costates "
        "(ocdsl/solve/warm_start.py), 'primal' = states and controls only")
    move_switches: bool = Field(True, description="solve the breakpoints that hold bang-bang switches as NLP "
                                "unknowns (free-time phases at every mesh, fixed-time ones on a mesh within "
                                "tolerance; docs/mesh.md, 'Switch times as NLP unknowns')")
    symbolic: bool = Field(True, description="the symbolic steps of refinement (the boundary control of a "
                           "bounded state, used to locate state-constrained arcs); false turns them off")
    symbolic_time: float = Field(10.0, gt=0, description="seconds each symbolic step may take; above it the "
                                 "step is skipped and the run says so")
    symbolic_memory: float = Field(1000.0, gt=0, description="megabytes each symbolic step may add; above it "
                                   "the step is skipped and the run says so")
    junction_control: Literal["limit", "free"] = Field(
        "limit", description="'limit': at a phase junction, a control collocated at the phase's end point "
        "(LGR: tau = +1 of a phase that another follows; LGR-start: tau = -1 of a phase that follows "
        "another; LGL: both) is constrained to the one-sided limit of its segment's interior control "
        "polynomial (docs/mesh-refinement.md, 'Two phases'); 'free': left to the NLP")

    @model_validator(mode="after")
    def _check(self):
        if self.min_degree > self.max_degree:
            raise ValueError(f"min_degree {self.min_degree} > max_degree {self.max_degree}")
        return self


class PseudospectralMethod(Strict):
    transcription: Literal["LG", "LGR", "LGL", "LGR-start"] = "LGR"
    segments: Union[int, list[float]] = Field(10, description="count of equal segments, or breakpoints in [0, 1]")
    degree: Union[int, list[int]] = Field(4, description="collocation points per segment (one or per segment)")
    mesh: MeshSpec | None = Field(None, description="adaptive mesh refinement")
    starts: int = Field(1, ge=1, description="several starts, best kept: start 0 is the guess (as one start); start "
                        "i >= 1 moves every state and control by a smooth seeded random curve (clipped into the "
                        "bounds, fixed boundary values kept) and draws free t0/tf around their guess; where the "
                        "guess has random controls (guess: {random: true}, --seed) start i redraws them instead")
    seed: int = Field(0, description="start i >= 1 draws from seed + i")

    @field_validator("segments")
    @classmethod
    def _segments(cls, v):
        if isinstance(v, int):
            if v < 1:
                raise ValueError("segments must be at least 1")
            if v > MAX_SEGMENTS:
                # unseen24: 100,000,000 passed `check`, and the build took 4 GB within 46 s
                raise ValueError(f"segments must be at most {MAX_SEGMENTS:,} (about 4 million NLP variables "
                                 "per state at degree 4); a finer solution: `mesh:` refines where it is needed")
        else:
            if len(v) < 2 or v[0] != 0 or v[-1] != 1 or any(b <= a for a, b in zip(v, v[1:])):
                raise ValueError("breakpoints must increase from 0 to 1, e.g. [0, 0.5, 1]")
        return v

    @field_validator("degree")
    @classmethod
    def _degree(cls, v):
        vals = [v] if isinstance(v, int) else v
        if any(d < 1 or d > 60 for d in vals):
            raise ValueError("degree must be between 1 and 60")
        return v


MAX_SEGMENTS = 1_000_000


class SolverSpec(Strict):
    name: Literal["ipopt"] = "ipopt"
    options: dict[str, Union[str, int, float]] = Field(default_factory=dict, description="Ipopt options")
    time_limit: float = Field(3600.0, gt=0, description="wall-clock seconds for the run's solves together "
                              "(mesh iterations, starts); past it the run ends `time_limit` with the last "
                              "iterate written. `ocdsl run --time-limit` overrides it")

    @field_validator("options", mode="before")
    @classmethod
    def _valid_options(cls, v):
        # a misspelt option, a value of the wrong type or out of its range is an error at
        # `ocdsl check`, not an Ipopt failure at solve time (unseen12 F4: YAML reads
        # `tol: 1e-10` as a string, and Ipopt refused it after the build)
        if not isinstance(v, dict):
            return v            # pydantic says what it expected
        known = ipopt_options()
        out, problems = {}, []
        for name, value in v.items():
            try:
                out[name] = ipopt_option_value(str(name), value, known)
            except ValueError as e:
                problems.append(str(e))
        missing = _missing_linear_solver(out.get("linear_solver"))
        if missing:
            problems.append(missing)
        if problems:
            raise ValueError("; ".join(problems))
        return out


def _missing_linear_solver(name) -> str | None:
    """Why Ipopt cannot use ``linear_solver: name`` here, or None. The bundled Ipopt has MUMPS;
    the HSL solvers and Pardiso are loaded at run time from libraries a user may install
    (libhsl, libcoinhsl, libpardiso). Without them the run ended with Ipopt's bare "Invalid
    option encountered." after `check` said ok (unseen24)."""
    import ctypes.util

    libraries = {"ma27": ("hsl", "coinhsl"), "ma57": ("hsl", "coinhsl"), "ma77": ("hsl", "coinhsl"),
                 "ma86": ("hsl", "coinhsl"), "ma97": ("hsl", "coinhsl"), "pardiso": ("pardiso", "pardisomkl")}
    if name not in libraries or any(ctypes.util.find_library(lib) for lib in libraries[name]):
        return None
    return (f"linear_solver {name}: its library ({' or '.join('lib' + lib for lib in libraries[name])}) is not "
            "installed here; the bundled Ipopt has mumps (the default)")


@lru_cache(maxsize=1)
def ipopt_options() -> dict[str, dict]:
    """Every option of the bundled Ipopt: type, valid range, possible values
    (ocdsl/solve/ipopt_options.json, made by scripts/ipopt_options.py)."""
    from importlib.resources import files

    return json.loads(files("ocdsl.solve").joinpath("ipopt_options.json").read_text())


def ipopt_option_value(name: str, value, known: dict[str, dict]):
    """``value`` as Ipopt takes option ``name`` (a number written as text, `1e-10`, becomes
    a number; `500.0` for an integer option an integer; YAML's yes/no booleans the words),
    or ValueError saying what the option takes."""
    from ..hints import did_you_mean

    spec = known.get(name)
    if spec is None:
        raise ValueError(f"unknown Ipopt option '{name}'{did_you_mean(name, list(known))}")
    kind = spec["type"]
    if kind == "string":
        values = spec.get("values")
        if isinstance(value, bool) and values and {"yes", "no"} <= set(values):
            return "yes" if value else "no"
        if not isinstance(value, (str, int, float)) or isinstance(value, bool):
            raise ValueError(f"Ipopt option '{name}' takes one of {', '.join(values or ['a text'])}, not {value!r}")
        text = str(value)
        if values and text not in values:
            raise ValueError(f"Ipopt option '{name}' takes one of {', '.join(values)}, not '{text}'"
                             + did_you_mean(text, values))
        return text
    number = None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        number = value
    elif isinstance(value, str):
        try:
            number = float(value.strip())
        except ValueError:
            pass
    what = "an integer" if kind == "integer" else "a number"
    if number is None or (kind == "integer" and not math.isfinite(number)):
        raise ValueError(f"Ipopt option '{name}' takes {what}, not {value!r}")
    if kind == "integer":
        if float(number) != int(number):
            raise ValueError(f"Ipopt option '{name}' takes an integer, not {value!r}")
        number = int(number)
    else:
        number = float(number)
    lo, hi = spec.get("lower"), spec.get("upper")
    if lo is not None and (number < lo or (spec.get("lower_strict") and number == lo)):
        raise ValueError(f"Ipopt option '{name}' must be {'>' if spec.get('lower_strict') else '>='} {lo:g}, not {value!r}")
    if hi is not None and (number > hi or (spec.get("upper_strict") and number == hi)):
        raise ValueError(f"Ipopt option '{name}' must be {'<' if spec.get('upper_strict') else '<='} {hi:g}, not {value!r}")
    return number


class ExpectItem(Strict):
    value: float
    rtol: float | None = Field(None, ge=0)
    atol: float | None = Field(None, ge=0)
    compare: Literal["equal", "at_most", "at_least"] = "equal"

    @model_validator(mode="before")
    @classmethod
    def _bare_number(cls, v):
        # `tf: 2.0` is how a user first writes a published value: the value, default tolerance
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return {"value": v}
        return v


class VerifySpec(Strict):
    """Independent verification of the returned trajectory (ocdsl/verify, docs/verification.md)."""

    tolerance: float = Field(1e-5, gt=0, lt=1, description="largest relative error of the "
                             "re-integration, the constraints met by it and the recomputed objective")
    mode: Literal["enforce", "warn"] = Field("enforce", description="`warn`: a failed verification "
                                             "is reported but does not fail the run")
    time_limit: float = Field(600.0, gt=0, le=86400, description="wall seconds for the verification "
                              "of one result; past it the verdict is `error` (not a pass)")
    bisection_check: bool = Field(True, description="a single solve (no `mesh:`) whose state bounds or "
                                  "inequality path constraints bind inside a phase is solved once more with "
                                  "every segment bisected; J must agree within a quarter of `tolerance`, else the run is "
                                  "`mesh_not_converged` (docs/verification.md)")


class ReportSpec(Strict):
    formats: list[Literal["html", "pdf"]] = Field(default_factory=lambda: ["html", "pdf"])
    enabled: bool = False


class TableSpec(Strict):
    """An interpolation table (docs/problem-language.md, "Tables"): a C2 cubic spline of one
    argument or a bicubic spline of two, from inline numbers or a CSV file beside the problem
    file; called in expressions like a function, e.g. ``CD0(M)`` or ``thrust(M, h)``."""

    x: Union[list[float], str] = Field(..., description="grid of the first argument (increasing), "
                                       "or its column name in `csv`")
    y: Union[list[float], str, None] = Field(None, description="grid of the second argument (2-D "
                                             "tables), or its column name in `csv`")
    values: Union[list[float], list[list[float]], str] = Field(..., description="1-D: one value per "
                                                               "x; 2-D: one row per x, one column per y; or the column name in `csv`")
    csv: str | None = Field(None, description="a CSV file (path relative to the problem file) with a "
                            "header row; x, y and values name its columns (2-D: one row per grid point)")
    spline: Literal["not-a-knot", "natural"] = Field("not-a-knot", description="end conditions of the "
                                                     "cubic spline")


class ScalingSpec(Strict):
    """Scaling of the NLP's variables, constraints and objective (ocdsl/solve/scaling.py,
    docs/problem-language.md "Scaling")."""

    mode: Literal["auto", "none"] = Field("none", description="`auto`: every variable, defect, "
                                          "constraint and the objective scaled by a typical magnitude "
                                          "(Ipopt user-scaling); `none`: Ipopt's own gradient-based scaling")
    variables: dict[str, float] = Field(default_factory=dict, description="typical magnitudes that "
                                        "override the automatic ones: {x: 6.4e6} or {phase.x: ...}")
    time: float | None = Field(None, gt=0, description="typical magnitude of free phase times")
    objective: float | None = Field(None, gt=0, description="typical magnitude of the objective")

    @field_validator("variables")
    @classmethod
    def _positive(cls, v):
        bad = [k for k, x in v.items() if not (x > 0 and x < float("inf"))]
        if bad:
            raise ValueError(f"a typical magnitude is a positive finite number: {bad[0]}")
        return v


class ProblemFile(Strict):
    """A whole problem file: one study."""

    name: str
    description: str = ""
    definitions: Any = Field(None, description="a home for YAML anchors (`&name`) used below with `*name` "
                             "or merged with `<<: *name`; ocdsl itself ignores this block")
    model: ModelSpec | None = None
    problem: ProblemSpec | None = None
    phases: dict[str, PhaseSpec] | None = None
    links: Relations = Field(default_factory=list, description="relations between phases")
    objective: str | None = Field(None, description="objective of a multi-phase problem")
    parameters: Annotated[dict[str, Union[float, ParameterSpec]], BeforeValidator(_constant_values)] = Field(
        default_factory=dict, description="problem-level parameters (free or constant)")
    tables: dict[str, TableSpec] = Field(default_factory=dict, description="interpolation tables, "
                                         "called in expressions as NAME(arg) or NAME(arg1, arg2)")
    method: dict[str, Any] = Field(default_factory=lambda: {"transcription": "LGR"})
    solver: SolverSpec = Field(default_factory=SolverSpec)
    scaling: ScalingSpec = Field(default_factory=ScalingSpec)
    report: ReportSpec = Field(default_factory=ReportSpec)
    expect: dict[str, ExpectItem] = Field(default_factory=dict)
    verify: VerifySpec = Field(default_factory=VerifySpec)
    study: dict[str, Any] | None = None
    controller: Any = None
    pareto: dict[str, Any] | None = None

    @model_validator(mode="after")
    def _check(self):
        if self.problem is None and self.phases is None and self.controller is None:
            raise ValueError("declare `problem:` (or `phases:` for a multi-phase problem)")
        if self.problem is not None and self.phases is not None:
            raise ValueError("use `problem:` or `phases:`, not both")
        if self.phases is not None and not self.objective:
            raise ValueError("a multi-phase problem needs a top-level `objective:`")
        if self.model is None and self.phases is None:
            raise ValueError("declare `model:`")
        if self.phases is not None:
            for name, ph in self.phases.items():
                if ph.model is None and self.model is None:
                    raise ValueError(f"phase {name!r} has no model and there is no top-level model")
        return self


def json_schema() -> dict[str, Any]:
    """The JSON Schema of a problem file for editors (``ocdsl schema``): ProblemFile's, with
    the blocks it keeps open typed by their back ends' own classes: ``method`` as one of the
    pseudospectral method and every registered method (``ocdsl.methods``), ``controller`` as
    ``ControllerSpec`` (unseen9 D2: both were ``{}``, so an editor validated neither). A file
    with a ``pareto:`` block is its own format (``ocdsl.spec.pareto``, read before this schema's
    blocks), which this schema does not describe."""
    from ..methods import registered_method_classes
    from .controller import ControllerSpec

    base = ProblemFile.model_json_schema()
    defs = base.setdefault("$defs", {})

    def ref(model) -> dict[str, Any]:
        sub = model.model_json_schema(ref_template="#/$defs/{model}")
        for name, definition in sub.pop("$defs", {}).items():
            if defs.setdefault(name, definition) != definition:
                raise ValueError(f"two schema definitions named {name}")   # kept apart by a test
        defs[model.__name__] = sub
        return {"$ref": f"#/$defs/{model.__name__}"}

    props = base["properties"]
    props["method"] = {"anyOf": [ref(PseudospectralMethod), *map(ref, registered_method_classes())],
                       "description": props["method"].get("description", "the transcription and its settings")}
    props["controller"] = {"anyOf": [ref(ControllerSpec), {"type": "null"}], "default": None}
    return base
