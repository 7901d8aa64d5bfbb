"""The ``study:`` block: sweeps, multi-starts and Monte Carlo over one problem file.

A study lives either in the problem file itself (a top-level ``study:`` key) or in a
separate study file that names its problem file::

    problem_file: lander.yaml        # relative to the study file
    study:
      seed: 7
      sweep:
        grid:                         # Cartesian product (or `zip:` / `list:`)
          h0: [10, 15, 20]
          T_max: {start: 400, stop: 480, num: 5}
      starts: 4                       # seeded random initial guesses (or {n: 4, seed: 1})
      monte-carlo:                    # seeded random perturbations of parameters
        n: 100
        parameters:
          Isp: {dist: normal, std: 3}           # nominal + N(0, 3^2)
          mu:  {dist: uniform, delta: 10}       # nominal + U(-10, 10)
      continuation: true              # warm start each sweep point from its neighbour

The points are the product sweep x Monte-Carlo samples x starts, numbered ``p0000``,
``p0001``, ... in that order; they are a pure function of the block (and of the problem's
nominal parameter values), so a resumed study finds the same points under the same ids.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import StrictBool, BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator


MAX_POINTS = 100_000      # docs/problem-language.md, "Input limits"

class StudyError(ValueError):
    """A mistake in a study (or in how it is run): one clear line, with file and line."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None,
                 text: str | None = None):
        self.file, self.line, self.text, self.reason = file, line, text, message
        where = f"{file}:{line}: " if file and line else (f"{file}: " if file else "")
        tail = f": {text}" if text else ""
        super().__init__(f"{where}{message}{tail}")


# ---------------------------------------------------------------------------------------
# schema
# ---------------------------------------------------------------------------------------
class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)


class Range(_Strict):
    """``{start, stop, num}``: ``num`` values from start to stop inclusive (``log: true``
    for geometric spacing)."""

    start: float
    stop: float
    num: int
    log: bool = False

    @field_validator("num")
    @classmethod
    def _num(cls, v: int) -> int:
        if v < 1:
            raise ValueError(f"num must be at least 1 (got {v}): the sweep would be empty")
        return v

    def values(self) -> list[float]:
        if self.log:
            if self.start <= 0 or self.stop <= 0:
                raise ValueError("log range needs positive start and stop")
            return [float(v) for v in np.geomspace(self.start, self.stop, self.num)]
        return [float(v) for v in np.linspace(self.start, self.stop, self.num)]


Values = list[float] | Range


class Sweep(_Strict):
    """Exactly one of ``grid`` (Cartesian product), ``zip`` (equal-length lists side by
    side) or ``list`` (explicit points)."""

    grid: dict[str, Values] | None = None
    zip_: dict[str, Values] | None = Field(default=None, alias="zip")
    list_: list[dict[str, float]] | None = Field(default=None, alias="list")

    @model_validator(mode="after")
    def _one(self) -> "Sweep":
        given = [k for k, v in (("grid", self.grid), ("zip", self.zip_), ("list", self.list_))
                 if v is not None]
        if len(given) != 1:
            raise ValueError("sweep needs exactly one of `grid`, `zip` or `list`"
                             + (f" (got {', '.join(given)})" if given else ""))
        return self

    @property
    def mode(self) -> str:
        return "grid" if self.grid is not None else "zip" if self.zip_ is not None else "list"

    def names(self) -> list[str]:
        if self.list_ is not None:
            seen: dict[str, None] = {}
            for p in self.list_:
                seen.update(dict.fromkeys(p))
            return list(seen)
        return list((self.grid if self.grid is not None else self.zip_) or {})


class Starts(_Strict):
    n: int
    seed: int | None = None

    @field_validator("n")
    @classmethod
    def _n(cls, v: int) -> int:
        if v < 0:
            raise ValueError(f"the number of starts must not be negative (got {v})")
        if v == 0:
            raise ValueError("the number of starts must be at least 1 (got 0)")
        return v


class Perturbation(_Strict):
    """``normal``: ``mean`` (default: nominal) and ``std`` or ``rel_std`` (x |mean|);
    ``uniform``: ``low``/``high``, or nominal +- ``delta`` / +- ``rel_delta`` x |nominal|."""

    dist: Literal["normal", "uniform"]
    mean: float | None = None
    std: float | None = None
    rel_std: float | None = None
    low: float | None = None
    high: float | None = None
    delta: float | None = None
    rel_delta: float | None = None

    @model_validator(mode="after")
    def _shape(self) -> "Perturbation":
        for k in ("std", "rel_std", "delta", "rel_delta"):
            v = getattr(self, k)
            if v is not None and not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{k} must be a finite number >= 0 (got {v})")
        if self.dist == "normal":
            if (self.std is None) == (self.rel_std is None):
                raise ValueError("a normal perturbation needs exactly one of `std`, `rel_std`")
            if any(v is not None for v in (self.low, self.high, self.delta, self.rel_delta)):
                raise ValueError("a normal perturbation takes mean and std/rel_std only")
        else:
            forms = [self.low is not None or self.high is not None, self.delta is not None,
                     self.rel_delta is not None]
            if sum(forms) != 1:
                raise ValueError("a uniform perturbation needs `low` and `high`, or `delta`,"
                                 " or `rel_delta`")
            if forms[0] and (self.low is None or self.high is None or self.low > self.high):
                raise ValueError("a uniform perturbation needs low <= high")
            if self.mean is not None or self.std is not None or self.rel_std is not None:
                raise ValueError("a uniform perturbation takes low/high, delta or rel_delta only")
        return self

    def needs_nominal(self) -> bool:
        return (self.dist == "normal" and self.mean is None) or (
            self.dist == "uniform" and self.low is None)


class MonteCarlo(_Strict):
    n: int
    seed: int | None = None
    parameters: dict[str, Perturbation]

    @field_validator("n")
    @classmethod
    def _n(cls, v: int) -> int:
        if v < 0:
            raise ValueError(f"the Monte-Carlo sample count must not be negative (got {v})")
        if v == 0:
            raise ValueError("the Monte-Carlo sample count must be at least 1 (got 0)")
        return v

    @field_validator("parameters")
    @classmethod
    def _nonempty(cls, v: dict) -> dict:
        if not v:
            raise ValueError("monte-carlo needs at least one parameter to perturb")
        return v


class StudySpec(_Strict):
    name: str | None = None
    seed: int = 0
    sweep: Sweep | None = None
    starts: Starts | None = None
    monte_carlo: MonteCarlo | None = Field(default=None, alias="monte-carlo")
    continuation: bool = False
    # one Pyomo model per worker, with the swept constants as mutable Params, re-solved at
    # each point of the same structure (ocdsl/solve/reuse.py; docs/studies.md)
    reuse_model: StrictBool = True

    @field_validator("starts", mode="before")
    @classmethod
    def _starts_int(cls, v: Any) -> Any:
        if isinstance(v, int) and not isinstance(v, bool):
            return {"n": v}
        return v

    @model_validator(mode="after")
    def _something(self) -> "StudySpec":
        if self.sweep is None and self.starts is None and self.monte_carlo is None:
            raise ValueError("a study needs at least one of `sweep`, `starts`, `monte-carlo`")
        n = self.point_count()
        if n > MAX_POINTS:     # counted, not generated (num: 200000000 once ended in MemoryError)
            raise ValueError(f"the study has {n:,} points, more than the limit of {MAX_POINTS:,}")
        if self.continuation and self.sweep is None:
            raise ValueError("`continuation: true` needs a `sweep` to continue along")
        return self

    def point_count(self) -> int:
        """Points of the study (sweep x samples x starts), without making them."""
        def size(v: Values) -> int:
            return v.num if isinstance(v, Range) else len(v)

        n = 1
        if self.sweep is not None:
            if self.sweep.grid is not None:
                n = math.prod(size(v) for v in self.sweep.grid.values())
            elif self.sweep.zip_ is not None:
                n = max((size(v) for v in self.sweep.zip_.values()), default=0)
            else:
                n = len(self.sweep.list_ or [])
        return n * (self.monte_carlo.n if self.monte_carlo else 1) * (self.starts.n if self.starts else 1)


# ---------------------------------------------------------------------------------------
# points
# ---------------------------------------------------------------------------------------
@dataclass
class Point:
    """One solve of the study. ``parent`` is the id whose finished run warm-starts this one
    (continuation), ``tags`` says where the point comes from (sweep/sample/start indices)."""

    id: str
    parameters: dict[str, float] = field(default_factory=dict)
    seed: int | None = None
    parent: str | None = None
    tags: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "parameters": self.parameters, "seed": self.seed,
                "parent": self.parent, "tags": self.tags}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> "Point":
        return cls(d["id"], dict(d.get("parameters") or {}), d.get("seed"), d.get("parent"),
                   dict(d.get("tags") or {}))


def _sweep_points(sweep: Sweep) -> tuple[list[dict[str, float]], list[int | None]]:
    """Sweep points and, for each, the index of its neighbour (continuation parent)."""
    def vals(v: Values) -> list[float]:
        return v.values() if isinstance(v, Range) else [float(x) for x in v]

    if sweep.grid is not None:
        names = list(sweep.grid)
        axes = [vals(sweep.grid[n]) for n in names]
        shape = [len(a) for a in axes]
        idx = list(itertools.product(*[range(s) for s in shape]))
        flat = {ix: k for k, ix in enumerate(idx)}
        points = [{n: axes[j][ix[j]] for j, n in enumerate(names)} for ix in idx]
        parents: list[int | None] = []
        for ix in idx:
            # step back along the last axis that is not at its start: a spanning tree in
            # which every point's parent differs from it by one step along one axis.
            p = None
            for j in reversed(range(len(ix))):
                if ix[j] > 0:
                    q = list(ix)
                    q[j] -= 1
                    p = flat[tuple(q)]
                    break
            parents.append(p)
        return points, parents
    if sweep.zip_ is not None:
        names = list(sweep.zip_)
        cols = [vals(sweep.zip_[n]) for n in names]
        lens = {n: len(c) for n, c in zip(names, cols)}
        if len(set(lens.values())) > 1:
            raise ValueError(f"zip sweep needs lists of equal length (got {lens})")
        n = len(cols[0]) if cols else 0
        return ([{nm: cols[j][i] for j, nm in enumerate(names)} for i in range(n)],
                [i - 1 if i else None for i in range(n)])
    pts = [{k: float(v) for k, v in p.items()} for p in sweep.list_ or []]
    return pts, [i - 1 if i else None for i in range(len(pts))]


def generate_points(spec: StudySpec, nominal: dict[str, float | None] | None = None) -> list[Point]:
    """The study's points, deterministic from the spec (and the nominal values that
    Monte-Carlo perturbations are centred on)."""
    nominal = dict(nominal or {})
    if spec.sweep is not None:
        sweep_pts, sweep_par = _sweep_points(spec.sweep)
    else:
        sweep_pts, sweep_par = [{}], [None]
    n_mc = spec.monte_carlo.n if spec.monte_carlo else 0
    n_st = spec.starts.n if spec.starts else 0
    if spec.starts is not None:
        st_seed = spec.starts.seed if spec.starts.seed is not None else spec.seed
        start_seeds = [int(s) for s in np.random.SeedSequence([st_seed, 1]).generate_state(n_st)]
    else:
        start_seeds = [None]
    mc_draws: list[list[dict[str, float]]] = []  # [sweep index][sample] -> values
    if spec.monte_carlo is not None:
        mc = spec.monte_carlo
        mc_seed = mc.seed if mc.seed is not None else spec.seed
        rng = np.random.default_rng(np.random.SeedSequence([mc_seed, 2]))
        # one draw of the offsets per sample, shared by every sweep point (common random
        # numbers): the same sample index is the same perturbation everywhere.
        unit = [{name: (rng.standard_normal() if pert.dist == "normal" else rng.random())
                 for name, pert in mc.parameters.items()} for _ in range(n_mc)]
        for sp in sweep_pts:
            per_point = []
            for u in unit:
                vals = {}
                for name, pert in mc.parameters.items():
                    nom = sp.get(name, nominal.get(name))
                    vals[name] = _apply(pert, u[name], nom)
                per_point.append(vals)
            mc_draws.append(per_point)
    samples = list(range(n_mc)) if n_mc else [None]
    starts = list(range(n_st)) if n_st else [None]

    width = max(4, len(str(len(sweep_pts) * len(samples) * len(starts) - 1)))
    points: list[Point] = []
    index: dict[tuple, str] = {}
    for i, sp in enumerate(sweep_pts):
        for m in samples:
            for s in starts:
                pid = f"p{len(points):0{width}d}"
                params = dict(sp)
                if m is not None:
                    params.update(mc_draws[i][m])
                tags: dict[str, Any] = {}
                if spec.sweep is not None:
                    tags["sweep"] = i
                if m is not None:
                    tags["sample"] = m
                if s is not None:
                    tags["start"] = s
                parent = None
                if spec.continuation and sweep_par[i] is not None:
                    parent = index[(sweep_par[i], m, s)]
                index[(i, m, s)] = pid
                points.append(Point(pid, params, start_seeds[s] if s is not None else None,
                                    parent, tags))
    return points


def _apply(pert: Perturbation, u: float, nominal: float | None) -> float:
    if pert.dist == "normal":
        mean = pert.mean if pert.mean is not None else nominal
        std = pert.std if pert.std is not None else pert.rel_std * abs(mean)
        return float(mean + std * u)
    if pert.low is not None:
        lo, hi = pert.low, pert.high
    else:
        d = pert.delta if pert.delta is not None else pert.rel_delta * abs(nominal)
        lo, hi = nominal - d, nominal + d
    return float(lo + (hi - lo) * u)


def validate_study(spec: StudySpec, parameters: dict[str, float | None] | list[str],
                   file: str | None = None, lines: dict[tuple, int] | None = None) -> None:
    """Check the study against the problem's parameters (names -> nominal value, or a
    list of names): every swept or perturbed name must be a parameter of the problem, and
    a perturbation centred on the nominal value needs one."""
    known = dict.fromkeys(parameters) if isinstance(parameters, list) else dict(parameters)
    lines = lines or {}
    names_txt = ", ".join(sorted(known)) or "none"

    def unknown(name: str, where: tuple) -> StudyError:
        return StudyError(f"unknown parameter {name!r} in the study's {where[1]} "
                          f"(the problem's parameters: {names_txt})", file,
                          lines.get(where + (name,)) or lines.get(where), name)

    if spec.sweep is not None:
        mode = spec.sweep.mode
        for name in spec.sweep.names():
            if name not in known:
                raise unknown(name, ("study", "sweep", mode) if mode != "list" else ("study", "sweep"))
        if mode == "list" and not spec.sweep.list_:
            raise StudyError("empty sweep: `list` has no points", file,
                             lines.get(("study", "sweep", "list")))
        if mode != "list":
            table = spec.sweep.grid if mode == "grid" else spec.sweep.zip_
            if not table:
                raise StudyError(f"empty sweep: `{mode}` names no parameter", file,
                                 lines.get(("study", "sweep", mode)))
            for name, v in table.items():
                if isinstance(v, list) and not v:
                    raise StudyError(f"empty sweep: no values for {name!r}", file,
                                     lines.get(("study", "sweep", mode, name)), name)
        if mode == "list":
            for k, p in enumerate(spec.sweep.list_):
                if not p:
                    raise StudyError(f"empty sweep point #{k} in `list`", file,
                                     lines.get(("study", "sweep", "list")))
    if spec.monte_carlo is not None:
        for name, pert in spec.monte_carlo.parameters.items():
            if name not in known:
                raise unknown(name, ("study", "monte-carlo", "parameters"))
            swept = spec.sweep is not None and name in spec.sweep.names()
            if pert.needs_nominal() and known.get(name) is None and not swept:
                raise StudyError(f"monte-carlo perturbation of {name!r} is centred on its "
                                 "nominal value, but the problem gives none: give `mean` "
                                 "(normal) or `low`/`high` (uniform)", file,
                                 lines.get(("study", "monte-carlo", "parameters", name)), name)


# ---------------------------------------------------------------------------------------
# loading from files
# ---------------------------------------------------------------------------------------
@dataclass
class LoadedStudy:
    spec: StudySpec
    problem_path: Path           # the problem file the points solve
    study_path: Path             # the file the study block came from
    parameters: dict[str, float | None]
    points: list[Point]

    def fingerprint(self) -> str:
        """Hash of the plan (points) and of the problem file's text."""
        h = hashlib.sha256(self.problem_path.read_bytes())
        h.update(json.dumps([p.to_json() for p in self.points], sort_keys=True).encode())
        return h.hexdigest()[:16]


def _key_lines(node: yaml.Node, path: tuple = ()) -> dict[tuple, int]:
    out: dict[tuple, int] = {}
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            key = path + (str(k.value),)
            out[key] = k.start_mark.line + 1
            out.update(_key_lines(v, key))
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            out[path + (i,)] = v.start_mark.line + 1
            out.update(_key_lines(v, path + (i,)))
    return out


def _read_yaml(path: Path) -> tuple[Any, dict[tuple, int]]:
    from ..spec.loader import load_yaml

    data = load_yaml(path).data     # the problem file's limits (size, nesting, aliases, tags): a SpecError
    try:
        text = path.read_text()
    except OSError as exc:
        raise StudyError(f"cannot read the file ({exc.strerror})", str(path)) from None
    try:
        node = yaml.compose(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise StudyError(f"not valid YAML: {getattr(exc, 'problem', exc)}", str(path),
                         mark.line + 1 if mark else None) from None
    return data, (_key_lines(node) if node is not None else {})


def problem_parameters(problem_path: str | Path) -> dict[str, float | None]:
    """Parameter names of a problem file and their nominal values (None when free or not
    given), read from ``parameters:``, ``model.parameters`` and each phase's."""
    data, _ = _read_yaml(Path(problem_path))
    out: dict[str, float | None] = {}

    def take(block: Any) -> None:
        if isinstance(block, dict):
            for k, v in block.items():
                out[str(k)] = _nominal(v)
        elif isinstance(block, list):  # [{name: .., value: ..}] or [name, ...]
            for item in block:
                if isinstance(item, str):
                    out.setdefault(item, None)
                elif isinstance(item, dict) and "name" in item:
                    out[str(item["name"])] = _nominal(item)

    def scan(d: Any) -> None:
        if not isinstance(d, dict):
            return
        take(d.get("parameters"))
        if isinstance(d.get("model"), dict):
            take(d["model"].get("parameters"))
        if isinstance(d.get("problem"), dict):
            take(d["problem"].get("parameters"))

    scan(data)
    phases = data.get("phases") if isinstance(data, dict) else None
    for ph in (phases.values() if isinstance(phases, dict) else phases or []):
        scan(ph)
    return out


def _nominal(v: Any) -> float | None:
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, dict):
        if v.get("free"):
            return None
        for k in ("value", "nominal", "guess"):
            if isinstance(v.get(k), (int, float)) and not isinstance(v.get(k), bool):
                return float(v[k])
    return None


def _pydantic_error(exc: ValidationError, file: str, lines: dict[tuple, int]) -> StudyError:
    errs = exc.errors()
    # a union (list of values | range) reports every member; our own messages say most
    err = next((e for e in errs if e["type"] in ("value_error", "extra_forbidden")), errs[0])
    loc = tuple("zip" if x == "zip_" else "list" if x == "list_" else x for x in err["loc"]
                if not (isinstance(x, str) and ("[" in x or x in ("Range", "Starts", "int"))))
    full = ("study",) + loc
    line = None
    for k in range(len(full), 0, -1):
        if full[:k] in lines:
            line = lines[full[:k]]
            break
    msg = err["msg"].removeprefix("Value error, ")
    where = ".".join(str(x) for x in loc) or "study"
    if err["type"] == "extra_forbidden":
        msg = f"unknown key {loc[-1]!r} in the study block"
    return StudyError(f"{msg} (at {where})", file, line)


def parse_study(block: Any, file: str = "<study>", lines: dict[tuple, int] | None = None) -> StudySpec:
    """Validate a ``study:`` block (a dict) into a :class:`StudySpec`."""
    lines = lines or {}
    if not isinstance(block, dict):
        raise StudyError("the `study:` block must be a mapping", file, lines.get(("study",)))
    try:
        return StudySpec.model_validate(block)
    except ValidationError as exc:
        raise _pydantic_error(exc, file, lines) from None


def load_study(path: str | Path) -> LoadedStudy:
    """Read a problem file with a ``study:`` block, or a study file with ``problem_file:``
    and ``study:``; validate the block against the problem's parameters and make the
    points. Raises :class:`StudyError` with file and line on any mistake."""
    path = Path(path)
    data, lines = _read_yaml(path)
    if not isinstance(data, dict) or "study" not in data:
        raise StudyError("no `study:` block in this file", str(path))
    if "problem_file" in data:
        extra = set(data) - {"problem_file", "study"}
        if extra:
            raise StudyError(f"a study file holds only `problem_file` and `study` (got "
                             f"{', '.join(sorted(extra))})", str(path),
                             lines.get((sorted(extra)[0],)))
        problem = (path.parent / str(data["problem_file"])).resolve()
        if not problem.is_file():
            raise StudyError("problem file not found", str(path), lines.get(("problem_file",)),
                             str(data["problem_file"]))
    else:
        problem = path.resolve()
    spec = parse_study(data["study"], str(path), lines)
    if spec.continuation:
        method = (_read_yaml(problem)[0] or {}).get("method")
        transcription = method.get("transcription") if isinstance(method, dict) else None
        if transcription == "flat-bspline":
            # unseen22 s04: `check` said ok, and every point after the first failed with
            # "flat-bspline does not take a warm start yet"
            raise StudyError("`continuation: true` starts each point from its neighbour's solution, which "
                             "flat-bspline does not take: drop it (each point is then solved from the "
                             "file's guess)", str(path), lines.get(("study", "continuation")))
    params = problem_parameters(problem)
    validate_study(spec, params, str(path), lines)
    try:
        points = generate_points(spec, params)
    except ValueError as exc:
        raise StudyError(str(exc), str(path), lines.get(("study", "sweep"))) from None
    return LoadedStudy(spec, problem, path.resolve(), params, points)
