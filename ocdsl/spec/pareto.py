"""The ``pareto:`` block of a problem file (pydantic v2 schema) and its loader.

```yaml
pareto:
  method: enumerate            # enumerate | epsilon | weighted
  objectives:                  # two or more, name: expression (or {expr:, sense:})
    t_mot: burn1.duration + burn2.duration
    t_sum: {expr: wait.duration + burn1.duration + coast.duration + burn2.duration}
  window:                      # enumerate: free parameters / phase durations searched
    wait.duration:  {range: [0, 2*pi], starts: 12}
    coast.duration: {range: [0, 40], split: 2*pi, starts: 6}   # cells [2 pi k, 2 pi (k+1)]
  dedup_tol: 1.0e-6
  residual_tol: 1.0e-10
  solver: closed_form          # closed_form (model-provided roots) | nlp (the transcription)
  executor: serial             # serial | local (studies executor)
```
``epsilon: {objective: t_sum, values: [..] | {from:, to:, num:}, chains: 1}`` and
``weights: {num: 11} | {values: [[w1, w2], ...]}`` configure the other two methods.

Numbers may be written as constant expressions (``2*pi``, ``pi/2``, ``1e-3``), evaluated
by a whitelisted syntax-tree walker (nothing is ``eval``-ed).

:func:`load_pareto` reads a problem file and raises :class:`ParetoSpecError` (a
``ocdsl.spec.errors.SpecError``) naming the file, the line and
the offending text for: fewer than two objectives, an empty window, a phase with a
negative duration bound, and every other schema error.
"""
from __future__ import annotations

import ast
import math
import operator
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ocdsl.spec.errors import Issue, SpecError

__all__ = ["ParetoSpec", "Objective", "Window", "EpsilonSpec", "WeightsSpec", "ParetoSpecError",
           "load_pareto", "parse_pareto", "check_phase_durations", "constant"]


class ParetoSpecError(SpecError):
    """A bad ``pareto:`` block (a :class:`SpecError` with one issue): ``file``, ``line``
    (1-based) and offending ``text``."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None,
                 text: str | None = None):
        super().__init__([Issue(file or "<pareto>", line, message, text or "")])
        self.message, self.file, self.line, self.text = message, file, line, text


# ---------------------------------------------------------------------------------------
# Constant expressions
# ---------------------------------------------------------------------------------------
_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv, ast.Pow: operator.pow}
_NAMES = {"pi": math.pi, "tau": math.tau, "e": math.e, "inf": math.inf}


def constant(value: Any) -> float:
    """A number, or a constant expression such as ``2*pi`` (whitelisted AST, never eval)."""
    if isinstance(value, bool):
        raise ValueError(f"expected a number, got {value!r}")
    if isinstance(value, (int, float)):
        try:
            return float(value)
        except OverflowError:
            raise ValueError(f"number too large: {str(value)[:40]}...") from None
    if not isinstance(value, str):
        raise ValueError(f"expected a number or a constant expression, got {value!r}")

    def walk(node: ast.AST) -> float:
        if isinstance(node, ast.Expression):
            return walk(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id in _NAMES:
            return _NAMES[node.id]
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            left, right = walk(node.left), walk(node.right)
            if isinstance(node.op, ast.Pow) and (abs(right) > 64 or abs(left) > 1e6):
                raise ValueError(f"power too large in {value!r}")
            return _OPS[type(node.op)](left, right)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = walk(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        raise ValueError(f"not a constant expression: {value!r}")

    try:
        tree = ast.parse(value.strip(), mode="eval")
        return float(walk(tree))
    except (SyntaxError, RecursionError, MemoryError):
        raise ValueError(f"not a constant expression: {value[:60]!r}") from None
    except (OverflowError, ZeroDivisionError) as e:
        raise ValueError(f"{e} in {value[:60]!r}") from None


# ---------------------------------------------------------------------------------------
# Schema
# ---------------------------------------------------------------------------------------
class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Objective(_Strict):
    expr: str
    sense: Literal["minimize", "maximize"] = "minimize"


class Window(_Strict):
    """Search window of one free parameter (or phase duration ``<phase>.duration``)."""

    range: tuple[float, float]
    split: float | None = None    # cells of this width (e.g. 2*pi: one coast revolution each)
    starts: int = Field(4, ge=1)  # start points per cell

    @field_validator("range", mode="before")
    @classmethod
    def _range(cls, v: Any) -> Any:
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise ValueError("range must be [lo, hi]")
        return tuple(constant(x) for x in v)

    @field_validator("split", mode="before")
    @classmethod
    def _split(cls, v: Any) -> Any:
        return None if v is None else constant(v)

    @model_validator(mode="after")
    def _nonempty(self) -> "Window":
        lo, hi = self.range
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ValueError(f"window range [{lo}, {hi}] must be finite")
        if not hi > lo:
            raise ValueError(f"empty window: range [{lo:g}, {hi:g}] has hi <= lo")
        if self.split is not None and not self.split > 0:
            raise ValueError(f"window split must be > 0, got {self.split:g}")
        return self


class EpsilonSpec(_Strict):
    objective: str                       # the objective turned into a constraint
    values: list[float] | dict[str, Any]  # list, or {from:, to:, num:}
    chains: int = Field(1, ge=1)
    parameter: str | None = None         # solver nlp: the file's parameter that carries eps
    seed_study: str | None = None        # solver nlp: a problem file (path relative to this one)
                                         # whose Pareto points seed a second start of every solve

    @field_validator("values", mode="before")
    @classmethod
    def _values(cls, v: Any) -> Any:
        if isinstance(v, dict):
            unknown = set(v) - {"from", "to", "num"}
            if unknown or not {"from", "to", "num"} <= set(v):
                raise ValueError("epsilon values must be a list or {from:, to:, num:}")
            try:
                num = int(v["num"])
            except (TypeError, ValueError, OverflowError):     # `num: .inf` was an OverflowError (fuzzing)
                raise ValueError(f"epsilon values: num must be a whole number >= 2, got {v['num']!r}") from None
            if num < 2:
                raise ValueError("epsilon values: num must be >= 2")
            a, b = constant(v["from"]), constant(v["to"])
            return [a + (b - a) * i / (num - 1) for i in range(num)]
        if not isinstance(v, list) or len(v) < 2:
            raise ValueError("epsilon values: give at least two values")
        return [constant(x) for x in v]


class WeightsSpec(_Strict):
    num: int | None = Field(None, ge=2)
    values: list[list[float]] | None = None
    chains: int = Field(1, ge=1)

    @model_validator(mode="after")
    def _one(self) -> "WeightsSpec":
        if (self.num is None) == (self.values is None):
            raise ValueError("weights: give either num or values")
        for w in self.values or []:
            if any(x < 0 for x in w) or not any(x > 0 for x in w):
                raise ValueError(f"weights {w}: non-negative, not all zero")
        return self


class ParetoSpec(_Strict):
    """The ``pareto:`` block."""

    method: Literal["enumerate", "epsilon", "weighted"]
    objectives: dict[str, Objective]
    window: dict[str, Window] = Field(default_factory=dict)
    epsilon: EpsilonSpec | None = None
    weights: WeightsSpec | None = None
    dedup_tol: float = Field(1e-6, gt=0)
    residual_tol: float = Field(1e-10, gt=0)
    solver: Literal["closed_form", "nlp"] = "nlp"
    executor: Literal["serial", "local"] = "serial"
    workers: int | None = Field(None, ge=1)
    # solver nlp, method enumerate: families as parameter sets of the problem file
    # ({family: [{param: value, ...}, ...]}), where the starts come from ("window": grid of
    # the window; "closed_form": the model's closed-form roots, perturbed by `perturbation`,
    # in time units, each way) and the study's own expect checks (n_solutions, pareto_labels)
    alternatives: dict[str, list[dict[str, float]]] = Field(default_factory=dict)
    starts_from: Literal["window", "closed_form"] = "window"
    perturbation: float = Field(0.05, ge=0)
    expect: dict[str, Any] = Field(default_factory=dict)
    family: str | None = None     # family name given to every point (e.g. "unrestricted")
    dominance_tol: float = Field(0.0, ge=0)   # objectives equal within it are ties (NLP noise)

    @field_validator("objectives", mode="before")
    @classmethod
    def _objectives(cls, v: Any) -> Any:
        if isinstance(v, list):  # [{name: expr}, ...] or [name: expr] pairs
            out: dict[str, Any] = {}
            for item in v:
                if not isinstance(item, dict) or len(item) != 1:
                    raise ValueError("objectives: write 'name: expression' entries")
                out.update(item)
            v = out
        if not isinstance(v, dict):
            raise ValueError("objectives: a mapping name -> expression")
        if len(v) < 2:
            raise ValueError(f"a Pareto study needs at least two objectives, got {len(v)}"
                             + (f" ({', '.join(v)})" if v else ""))
        return {k: ({"expr": e} if isinstance(e, str) else e) for k, e in v.items()}

    @field_validator("window", mode="after")
    @classmethod
    def _durations(cls, v: dict[str, Window]) -> dict[str, Window]:
        for name, w in v.items():
            if name.endswith(".duration") and w.range[0] < 0:
                raise ValueError(f"phase {name.rsplit('.', 1)[0]!r}: negative duration bound "
                                 f"{w.range[0]:g} (durations are >= 0)")
        return v

    @model_validator(mode="after")
    def _method(self) -> "ParetoSpec":
        if self.method == "enumerate" and not self.window:
            raise ValueError("method enumerate needs a window: of free parameters to search")
        if self.method == "epsilon":
            if self.epsilon is None:
                raise ValueError("method epsilon needs an epsilon: {objective:, values:} entry")
            if self.epsilon.objective not in self.objectives:
                raise ValueError(f"epsilon objective {self.epsilon.objective!r} is not one of "
                                 f"the objectives {list(self.objectives)}")
        if self.method == "weighted":
            if self.weights is None:
                raise ValueError("method weighted needs a weights: {num:} or {values:} entry")
            for w in self.weights.values or []:
                if len(w) != len(self.objectives):
                    raise ValueError(f"weights {w}: one weight per objective ({len(self.objectives)})")
        return self

    @property
    def objective_names(self) -> list[str]:
        return list(self.objectives)

    @property
    def senses(self) -> list[str]:
        return [o.sense for o in self.objectives.values()]


# ---------------------------------------------------------------------------------------
# Loading with file and line
# ---------------------------------------------------------------------------------------
def _node_at(node: yaml.Node | None, path: tuple[Any, ...]) -> yaml.Node | None:
    """Deepest YAML node along ``path`` (mapping keys / sequence indices).

    When the path ends at a mapping entry whose value is a block (mapping or sequence on
    the following lines), the key node is returned so that the line is the key's.
    """
    for i, key in enumerate(path):
        if isinstance(node, yaml.MappingNode):
            nxt = None
            for k, v in node.value:
                if k.value == str(key):
                    nxt = v
                    if i == len(path) - 1 and isinstance(v, (yaml.MappingNode, yaml.SequenceNode)) \
                            and v.start_mark.line != k.start_mark.line:
                        nxt = k
                    break
            if nxt is None:
                return node
            node = nxt
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
        else:
            return node
    return node


def _line_text(source: str, line: int) -> str:
    lines = source.splitlines()
    return lines[line - 1].strip() if 0 < line <= len(lines) else ""


def parse_pareto(block: Any, file: str | None = None, source: str | None = None,
                 root: yaml.Node | None = None, prefix: tuple[Any, ...] = ("pareto",)) -> ParetoSpec:
    """Validate a ``pareto:`` mapping; errors as :class:`ParetoSpecError` with the line."""
    def fail(msg: str, loc: tuple[Any, ...]) -> None:
        node = _node_at(root, prefix + loc) if root is not None else None
        line = node.start_mark.line + 1 if node is not None else None
        text = _line_text(source, line) if (source and line) else None
        raise ParetoSpecError(f"{'.'.join(str(x) for x in prefix + loc)}: {msg}", file, line, text) from None

    # durations first, so that the error points at the window entry itself
    window = block.get("window") if isinstance(block, dict) else None
    for key, w in (window.items() if isinstance(window, dict) else ()):
        rng = w.get("range") if isinstance(w, dict) else None
        if str(key).endswith(".duration") and isinstance(rng, (list, tuple)) and rng:
            try:
                lo = constant(rng[0])
            except ValueError:
                continue
            if lo < 0:
                fail(f"phase {str(key).rsplit('.', 1)[0]!r}: negative duration bound {lo:g} "
                     f"(durations are >= 0)", ("window", key))
    try:
        return ParetoSpec.model_validate(block)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = tuple(x for x in err["loc"] if not (isinstance(x, str) and x.startswith("function-")))
        fail(err["msg"].removeprefix("Value error, "), loc)
        raise  # unreachable: fail raises


def check_phase_durations(phases: Any, file: str | None = None, source: str | None = None,
                          root: yaml.Node | None = None) -> dict[str, tuple[float, float]]:
    """Duration bounds ``{phase: [lo, hi]}`` of a ``phases:`` block; a negative bound is an error."""
    out: dict[str, tuple[float, float]] = {}
    for name, ph in (phases or {}).items():
        if not isinstance(ph, dict) or "duration" not in ph:
            continue
        node = _node_at(root, ("phases", name, "duration")) if root is not None else None
        line = node.start_mark.line + 1 if node is not None else None
        text = _line_text(source, line) if (source and line) else None
        try:
            d = ph["duration"]
            lo, hi = (constant(d), constant(d)) if not isinstance(d, list) else tuple(constant(x) for x in d)
        except (ValueError, TypeError) as exc:
            raise ParetoSpecError(f"phases.{name}.duration: {exc}", file, line, text) from None
        if lo < 0 or hi < 0:
            raise ParetoSpecError(f"phase {name!r}: negative duration bound {min(lo, hi):g} "
                                  f"(durations are >= 0)", file, line, text)
        if hi < lo:
            raise ParetoSpecError(f"phase {name!r}: empty duration range [{lo:g}, {hi:g}]", file, line, text)
        out[name] = (lo, hi)
    return out


def load_pareto(path: str | Path) -> tuple[ParetoSpec, dict[str, Any]]:
    """Read a problem file; return its validated ``pareto:`` block and the whole document."""
    from .loader import load_yaml
    from .pareto_check import check_sections

    path = Path(path)
    located = load_yaml(path)       # the problem file's reader: limits, tags and merge keys alike
    source = path.read_text()
    root = yaml.compose(source, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    doc = located.data
    if "pareto" not in doc:
        raise ParetoSpecError("no pareto: block", str(path), 1, None)
    check_phase_durations(doc.get("phases"), str(path), source, root)
    spec = parse_pareto(doc["pareto"], str(path), source, root)
    check_sections(path, located, spec.solver, spec.method)
    return spec, doc
