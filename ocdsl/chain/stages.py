"""Running a chain: each chained phase's source solved (or an earlier run of it reused),
converted by its transform, and the phase started from the converted trajectory.

The source's run folder and the converted guess go into the run folder as
``stages/<stem>/`` and ``stages/<stem>.guess/`` (run folders of their own), so a run is
self-contained and the next run of the same file into the same folder reuses its stage
when the source file has not changed (its ``problem.yaml`` is compared byte for byte).
"""
from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..result import Result
from .check import is_problem_file, resolve
from .registry import IDENTITY, get_transform

STAGES = "stages"


class ChainError(RuntimeError):
    """A stage that gives no guess (its source ended without a trajectory)."""


@dataclass
class Stage:
    phases: list[str]
    source: str                    # as written in the file
    transform: str
    folder: Path                   # the source's run folder
    guess: Path                    # the folder the phases start from
    reused: str | None = None      # the earlier run folder used instead of solving
    seconds: dict[str, float] = field(default_factory=dict)
    record: dict = field(default_factory=dict)

    def entries(self) -> dict[str, Path]:
        """Run-folder entries (relative name -> folder to copy there)."""
        stem = Path(self.source).stem if is_problem_file(self.source) else Path(self.source).name
        out = {f"{STAGES}/{stem}": self.folder} if is_problem_file(self.source) else {}
        if self.guess != self.folder:
            out[f"{STAGES}/{stem}.guess"] = self.guess
        return out


def chained(file) -> bool:
    return file.problem is not None and any(ph.guess.get("chain") for ph in file.problem.phases)


def same_problem(folder: Path, source: Path) -> bool:
    """``folder`` is a complete run folder of ``source`` as that file is now."""
    try:
        return ((folder / "result.json").is_file()
                and (folder / "problem.yaml").read_bytes() == source.read_bytes()
                and bool(Result.read(folder).phases))
    except (OSError, ValueError, KeyError):
        return False


def prepare(file, out: Path | None, work: Path, *, quiet: bool = True, verbose: bool = False):
    """The stages of ``file``'s chained phases, run in ``work`` (a scratch folder), and a copy
    of ``file`` whose phases start from their converted guesses."""
    from ..api import run_file

    stages: dict[tuple, Stage] = {}
    starts: dict[str, Path] = {}
    for ph in file.problem.phases:
        chain = ph.guess.get("chain")
        if not chain:
            continue
        key = (chain["from"], chain["transform"] or IDENTITY)
        if key not in stages:
            stages[key] = _stage(file, chain, out, work, len(stages), run_file, quiet, verbose)
        stages[key].phases.append(ph.name)
        starts[ph.name] = stages[key].guess
    phases = []
    for ph in file.problem.phases:
        if ph.name in starts:
            ph = copy.copy(ph)
            ph.guess = {**ph.guess, "from": str(starts[ph.name].resolve())}
        phases.append(ph)
    problem = copy.copy(file.problem)
    problem.phases = phases
    started = copy.copy(file)
    started.problem = problem
    return started, list(stages.values())


def _stage(file, chain: dict, out, work: Path, index: int, run_file, quiet, verbose) -> Stage:
    source, name = chain["from"], chain["transform"] or IDENTITY
    transform = get_transform(name)
    where = resolve(Path(chain["file"]), source)
    seconds, reused = {}, None
    t0 = time.perf_counter()
    if is_problem_file(source):
        candidates = [resolve(Path(chain["file"]), chain["reuse"])] if chain.get("reuse") else []
        if out is not None:
            candidates.append(Path(out) / STAGES / where.stem)
        folder = next((c for c in candidates if same_problem(c, where)), None)
        if folder is not None:
            reused = str(folder)
        else:
            folder = work / f"{index}-{where.stem}"
            if not quiet:
                print(f"[stage] {file.path.name}: solving {where} first (its solution is the guess)")
            res = run_file(where, folder, quiet=quiet, verbose=verbose)
            if not res.phases:
                raise ChainError(f"{file.path}: guess from '{source}': that run ended {res.status} without "
                                 f"a trajectory: {res.message.splitlines()[0] if res.message else ''}")
        seconds["stages"] = round(time.perf_counter() - t0, 6)
    else:
        folder = where
    source_result = Result.read(folder)
    guess = folder
    extra = {}
    if transform.convert is not None:
        t1 = time.perf_counter()
        converted = transform.convert(source_result, folder, file)
        guess = work / f"{index}-{where.stem}.guess"
        converted.write(guess)
        extra = dict(converted.extra)
        seconds["convert_guess"] = round(time.perf_counter() - t1, 6)
    record = {"from": source, "transform": name, "reused": reused, "source_status": source_result.status,
              "source_ok": source_result.ok, **({"conversion": extra} if extra else {})}
    return Stage([], source, name, folder, guess, reused, seconds, record)


def finish(result: Result, file, stages: list[Stage]) -> None:
    """Record the stages in ``result`` and let each transform annotate it."""
    if not stages:
        return
    for st in stages:     # inside the run's timer: "total" already counts them
        for k, v in st.seconds.items():
            result.wall_time_s[k] = round(result.wall_time_s.get(k, 0.0) + v, 6)
    result.extra["chain"] = [{"phases": st.phases, **st.record,
                              "folders": sorted(st.entries())} for st in stages]
    for st in stages:
        if not st.record.get("source_ok", True):
            # said where the user reads, not only in result.json (unseen23 w12)
            result.extra.setdefault("notes", []).append(
                f"the guess of {', '.join(st.phases)} comes from {st.source}, whose run ended "
                f"{st.record.get('source_status')}: a start, not a solution")
    for st in stages:
        transform = get_transform(st.transform)
        if transform.annotate is not None:
            transform.annotate(result, st.folder, file)


def entries(stages: list[Stage]) -> dict[str, Path]:
    out: dict[str, Path] = {}
    for st in stages:
        out.update(st.entries())
    return out
