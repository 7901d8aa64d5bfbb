"""Run a study: many solves of one problem file, streamed into a study folder.

``run_study(problem_path, out_dir, *, workers=None, serial=False, scheduler=None,
resume=False, quiet=False, point_fn=None) -> StudyResult`` is what ``ocdsl study FILE
--out DIR [--workers N] [--serial] [--scheduler ADDR] [--resume] [--quiet]`` calls.
``run_points(...)`` is the same engine for callers that make their own points (Pareto
scans); :class:`ocdsl.study.executor.Executor` is the engine for plain function batches
(PSO swarms).

The study folder::

    DIR/plan.json             the points (ids, parameter values, seeds, parents) + fingerprint
    DIR/points/<id>/          one run folder per point (result.json, trajectory.csv, ...,
                              point.json: the point, host, warm start), renamed into place
                              complete, so a folder that exists is a finished point
    DIR/study.csv             one row per point: id, parameter values, seed, status, objective,
    DIR/study.json            tf, iterations, wall time, host, warm start, message;
                              study.json also has state (running | interrupted | complete),
                              counts and the best point. Both rewritten atomically as points
                              finish.

Only this process writes into DIR: workers solve into their own scratch folders and send
the files back, so a worker on another machine needs no shared file system, and a worker
orphaned by ``kill -9`` of this process cannot write a point behind a resumed study's back.
Resuming (``resume=True``) keeps every finished point folder, re-runs the others, and
rebuilds the table from the folders; a finished point is never solved again.
"""
from __future__ import annotations

import csv
import hashlib
import heapq
import io
import json
import math
import os
import shutil
import socket
import tempfile
import time
import traceback
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from ocdsl import run_folder
from ocdsl.result import Result

from .executor import Executor, WorkerLost, worker_cache, worker_info
from .spec import Point, StudyError, load_study

GOOD = ("optimal", "feasible", "stable")
POINT_FILE = "point.json"
STUDY_ENTRIES = ("plan.json", "study.csv", "study.json", "points")


# --------------------------------------------------------------------------------------
# the default point function: ocdsl's own solve, with the built problem cached per worker
# --------------------------------------------------------------------------------------
def solve_point(path: str, out_dir: str, parameters: dict[str, float] | None = None,
                seed: int | None = None, warm_start: str | None = None, quiet: bool = True,
                reuse: bool = True) -> Any:
    """Solve one point like ``ocdsl.api.run_file`` (the default point function).

    Imports (Pyomo, SymPy, ocdsl) happen once per worker process, which lives for the
    whole study. When the API can re-solve a built problem with new parameter values
    (``ocdsl.load(path)`` whose ``.solve`` takes ``parameters=``), the built problem is
    also cached per worker by (path, mtime, size); otherwise each point calls ``run_file``.
    ``reuse``: re-solve one built model with the swept constants as mutable Params where the
    point's structure allows (the study's ``reuse_model``; ocdsl/solve/reuse.py).
    """
    import ocdsl.api as api
    loaded_cls = getattr(api, "Loaded", None)
    if loaded_cls is not None and _takes(loaded_cls.solve, "parameters"):
        st = os.stat(path)
        handle = worker_cache(("ocdsl.load", str(path), st.st_mtime_ns, st.st_size),
                              lambda: api.load(path))
        kw = {"reuse": reuse} if _takes(loaded_cls.solve, "reuse") else {}
        res = handle.solve(out=out_dir, parameters=parameters, seed=seed, warm_start=warm_start, **kw)
        if not (Path(out_dir) / "result.json").is_file():
            res.write(out_dir)
        return res
    return api.run_file(path, out_dir, parameters=parameters, seed=seed,
                        warm_start=warm_start, quiet=quiet)


def _takes(fn: Callable, name: str) -> bool:
    import inspect
    try:
        return name in inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False


def _check_problem(path: Path) -> None:
    """Parse the problem file once here, so that a bad file is one clear error and not
    one failed point per point."""
    try:
        from ocdsl.api import compile_file
    except ImportError:
        return
    try:
        from ocdsl.spec.errors import SpecError
    except ImportError:  # pragma: no cover
        SpecError = ValueError  # noqa: N806
    try:
        compile_file(path)
    except SpecError as exc:
        raise StudyError(f"the problem file is not valid: {exc}") from None


# --------------------------------------------------------------------------------------
# worker side
# --------------------------------------------------------------------------------------
def _materialize_problem(path: str, text: bytes, sha: str) -> str:
    """The problem file on this worker: the original path when it holds the same text
    (shared file system), else a private copy keyed by the text's hash."""
    try:
        if hashlib.sha256(Path(path).read_bytes()).hexdigest() == sha:
            return path
    except OSError:
        pass
    d = Path(tempfile.gettempdir()) / "ocdsl-study-problems" / sha[:24]
    dest = d / Path(path).name
    if not dest.exists():
        d.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-")
        with os.fdopen(fd, "wb") as fh:
            fh.write(text)
        os.replace(tmp, dest)
    return str(dest)


def _write_files(root: Path, files: dict[str, bytes]) -> None:
    for rel, data in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)


def _read_files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _error_result(name: str, point: Point, message: str, tb: str = "") -> Result:
    return Result(name=name, status="error", message=message, parameters=dict(point.parameters),
                  extra={"traceback": tb} if tb else {})


def _solve_point(task: dict[str, Any]) -> dict[str, Any]:
    """Run one point in a scratch folder on the worker; return its run folder's files."""
    t0 = time.perf_counter()
    point = Point.from_json(task["point"])
    scratch = Path(tempfile.mkdtemp(prefix=f"ocdsl-{point.id}-"))
    try:
        problem = _materialize_problem(task["problem_path"], task["problem_text"],
                                       task["problem_sha"])
        warm = None
        if task.get("warm_files"):
            warm = scratch / "warm"
            _write_files(warm, task["warm_files"])
        run_dir = scratch / "run"
        fn: Callable = task.get("point_fn") or solve_point
        extra = {"reuse": task["reuse_model"]} if fn is solve_point and "reuse_model" in task else {}
        ret = None
        try:
            ret = fn(problem, str(run_dir), parameters=dict(point.parameters), seed=point.seed,
                     warm_start=str(warm) if warm else None, quiet=True, **extra)
        except Exception as exc:  # a failed point never stops the study
            shutil.rmtree(run_dir, ignore_errors=True)
            _error_result(Path(problem).stem, point, f"{type(exc).__name__}: {exc}",
                          traceback.format_exc()).write(run_dir)
        if not (run_dir / "result.json").is_file():
            if isinstance(ret, Result):
                ret.write(run_dir)
            else:
                _error_result(Path(problem).stem, point,
                              "the point function wrote no run folder").write(run_dir)
        return {"files": _read_files(run_dir), **worker_info(),
                "task_s": time.perf_counter() - t0}
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


# --------------------------------------------------------------------------------------
# study folder
# --------------------------------------------------------------------------------------
def _atomic_write(path: Path, text: str) -> None:
    run_folder.atomic_write_text(path, text)


def _install_point(points_dir: Path, point: Point, files: dict[str, bytes], meta: dict) -> None:
    with run_folder.assemble(points_dir / point.id, "run", force=True) as tmp:
        _write_files(tmp, files)
        (tmp / POINT_FILE).write_text(json.dumps(meta, indent=2))


def _summary(run_dir: Path) -> dict[str, Any]:
    data = json.loads((run_dir / "result.json").read_text())
    wall = data.get("wall_time_s") or {}
    sense = ((data.get("problem") or {}).get("objective") or {}).get("sense", "minimize")
    return {"status": data.get("status"), "verification": (data.get("verification") or {}).get("status"),
            "objective": _num(data.get("objective")),
            "tf": data.get("tf"), "iterations": data.get("iterations"),
            "wall_time_s": _num(wall.get("total")) if isinstance(wall, dict) else None,
            "message": (data.get("message") or "").strip().splitlines()[0][:300]
            if data.get("message") else "", "sense": sense}


def _num(v: Any) -> float | None:
    if v is None:
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def _finished(points_dir: Path, point: Point) -> dict | None:
    """The point.json of a complete run folder for this point, or None."""
    d = points_dir / point.id
    try:
        meta = json.loads((d / POINT_FILE).read_text())
    except (OSError, ValueError):
        return None
    if not (d / "result.json").is_file():
        return None
    if meta.get("point", {}).get("parameters") != point.parameters or \
            meta.get("point", {}).get("seed") != point.seed:
        raise StudyError(f"{d} holds a different point than the study's {point.id} "
                         "(the study changed); use a new --out")
    return meta


@dataclass
class StudyResult:
    """What a study produced: ``rows`` (one dict per point, the table), ``counts``
    (``points``, ``done``, ``ok``, ``failed``, ``resumed``: finished before this run),
    ``best`` (row of the best successful point), ``state``, ``out_dir``."""

    out_dir: Path
    rows: list[dict[str, Any]]
    counts: dict[str, int]
    best: dict[str, Any] | None
    state: str
    wall_time_s: float
    executor: str
    parameter_names: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return self.state == "complete"

    @property
    def failed(self) -> int:
        """Number of finished points that did not succeed."""
        return self.counts.get("failed", 0)

    @property
    def ok(self) -> bool:
        """Complete and every point succeeded."""
        return self.complete and self.counts.get("failed", 0) == 0

    def row(self, point_id: str) -> dict[str, Any]:
        for r in self.rows:
            if r["id"] == point_id:
                return r
        raise KeyError(point_id)

    def run_dir(self, point_id: str) -> Path:
        return self.out_dir / "points" / point_id


class _Table:
    FIXED = ["seed", "status", "verification", "objective", "tf", "iterations", "wall_time_s", "host",
             "warm_start", "message"]

    def __init__(self, out_dir: Path, points: list[Point], info: dict[str, Any]):
        self.out_dir, self.info = out_dir, info
        self.pnames: list[str] = []
        for p in points:
            for k in p.parameters:
                if k not in self.pnames:
                    self.pnames.append(k)
        self.tagnames = [t for t in ("sweep", "sample", "start")
                         if any(t in p.tags for p in points)]
        self.rows: dict[str, dict[str, Any]] = {}
        for p in points:
            self.rows[p.id] = {"id": p.id, **{k: p.parameters.get(k) for k in self.pnames},
                               **{t: p.tags.get(t) for t in self.tagnames},
                               "seed": p.seed, "status": "pending", "verification": None,
                               "objective": None, "tf": None,
                               "iterations": None, "wall_time_s": None, "host": None,
                               "warm_start": None, "message": ""}
        self.sense = "minimize"
        self._last_write = 0.0
        self._write_cost = 0.0

    def set(self, pid: str, summary: dict[str, Any], meta: dict[str, Any]) -> None:
        self.sense = summary.pop("sense", self.sense) or self.sense
        self.rows[pid].update(summary)
        self.rows[pid].update(host=meta.get("host"), warm_start=meta.get("warm_start"))

    def counts(self) -> dict[str, int]:
        st = [r["status"] for r in self.rows.values()]
        done = sum(s != "pending" for s in st)
        ok = sum(s in GOOD for s in st)
        return {"points": len(st), "done": done, "ok": ok, "failed": done - ok,
                "pending": len(st) - done}

    def best(self) -> dict[str, Any] | None:
        good = [r for r in self.rows.values() if r["status"] in GOOD
                and r["objective"] is not None and math.isfinite(r["objective"])]
        if not good:
            return None
        sign = -1.0 if self.sense == "maximize" else 1.0
        return min(good, key=lambda r: sign * r["objective"])

    def columns(self) -> list[str]:
        return ["id", *self.pnames, *self.tagnames, *self.FIXED]

    def write(self, state: str, extra: dict[str, Any] | None = None, force: bool = False) -> None:
        """Rewrite study.json and study.csv atomically (throttled to a few % of the run
        time for very large studies; always when ``force``)."""
        now = time.perf_counter()
        if not force and now - self._last_write < 20 * self._write_cost:
            return
        t0 = time.perf_counter()
        cols = self.columns()
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(cols)
        for r in self.rows.values():
            w.writerow([_cell(r.get(c)) for c in cols])
        doc = {**self.info, "state": state, "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
               "counts": self.counts(), "best": self.best(), "columns": cols,
               "points": list(self.rows.values()), **(extra or {})}
        # csv first: a reader that sees state=complete in study.json finds a full csv too
        _atomic_write(self.out_dir / "study.csv", buf.getvalue())
        _atomic_write(self.out_dir / "study.json", json.dumps(_jsonable(doc), indent=1))
        self._last_write = time.perf_counter()
        self._write_cost = self._last_write - t0


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (dict, list)):
        return json.dumps(v)
    return str(v)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    return obj


# --------------------------------------------------------------------------------------
# progress display
# --------------------------------------------------------------------------------------
class _Progress:
    """Points done of the total, elapsed, ETA, counts and the best point (ocdsl/progress.py:
    one live line on a terminal, plain lines in a log)."""

    def __init__(self, title: str, total: int, quiet: bool):
        from ..progress import Stage

        self.bar = Stage(title, total, enabled=not quiet)

    def update(self, counts: dict[str, int], running: int, best: dict | None) -> None:
        b = "-" if best is None else f"{best['objective']:.6g} ({best['id']})"
        self.bar.update(counts["done"], f"ok {counts['ok']}  failed {counts['failed']}  running {running}  best {b}")

    def stop(self) -> None:
        self.bar.close()


def _final_table(res: StudyResult, quiet: bool) -> None:
    if quiet:
        return
    from rich.console import Console
    from rich.table import Table
    console = Console()
    rows = res.rows
    shown = rows
    if len(rows) > 40:
        fails = [r for r in rows if r["status"] not in GOOD][:10]
        good = sorted((r for r in rows if r["status"] in GOOD and r["objective"] is not None),
                      key=lambda r: r["objective"])[:15]
        shown = sorted(good + fails, key=lambda r: r["id"])
    t = Table(title=f"study {res.out_dir}  ({res.counts['ok']} ok, {res.counts['failed']} "
                    f"failed of {res.counts['points']}; {res.executor}; "
                    f"{res.wall_time_s:.1f} s)")
    pn = res.parameter_names[:6]
    for c in ["id", *pn, "status", "verification", "objective", "tf", "iter", "wall s", "host"]:
        t.add_column(c, justify="right" if c not in ("id", "status", "verification", "host") else "left")
    for r in shown:
        style = "" if r["status"] in GOOD else ("yellow" if r["status"] == "pending" else "red")
        tf = r["tf"]
        t.add_row(r["id"], *[_fmt(r.get(k)) for k in pn], r["status"], str(r.get("verification") or ""),
                  _fmt(r["objective"]),
                  _fmt(tf) if not isinstance(tf, dict) else json.dumps(tf),
                  _fmt(r["iterations"]), _fmt(r["wall_time_s"], 3), str(r["host"] or ""),
                  style=style)
    console.print(t)
    if len(shown) < len(rows):
        console.print(f"(best 15 and first failures shown; all {len(rows)} rows in "
                      f"{res.out_dir / 'study.csv'})")
    if res.best:
        console.print(f"best: {res.best['id']} objective {res.best['objective']:.10g}")


def _fmt(v: Any, digits: int = 6) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


# --------------------------------------------------------------------------------------
# the engine
# --------------------------------------------------------------------------------------
def run_study(problem_path: str | os.PathLike, out_dir: str | os.PathLike, *,
              workers: int | None = None, serial: bool = False, scheduler: Any = None,
              resume: bool = False, quiet: bool = False,
              point_fn: Callable | None = None, force: bool = False) -> StudyResult:
    """Run the study of ``problem_path`` (a problem file with a ``study:`` block, or a
    study file naming one with ``problem_file:``) into ``out_dir``.

    - ``workers``: local worker processes (default: as many as cores); ``serial``: in this
      process; ``scheduler``: ``tcp://HOST:PORT`` of a Dask scheduler (or a
      ``distributed.Client``). Unreachable: :class:`StudyError` within a few seconds.
    - ``resume``: continue the study already in ``out_dir`` (finished points are kept,
      the rest re-run). Without it an ``out_dir`` holding a study is an error, unless
      ``force`` (replace it). A folder ocdsl did not write is always refused
      (ocdsl/run_folder.py).
    - ``quiet``: no progress bar and no final table.
    - ``point_fn``: a picklable function with the signature of ``ocdsl.api.run_file``
      (``(path, out_dir, parameters=, seed=, warm_start=, quiet=)``, writes the run folder);
      default :func:`solve_point`.

    Raises :class:`StudyError` (a ``ValueError``, message with file and line) for a bad
    study block, before anything is written. Failed points never raise: they are rows
    with their status and message. Ctrl-C leaves the study resumable and re-raises.
    """
    loaded = load_study(problem_path)
    # connect first: an unreachable scheduler is reported within its timeout
    ex = Executor(workers=workers, serial=serial, scheduler=scheduler)
    try:
        if point_fn is None:
            _check_problem(loaded.problem_path)
        res = run_points(loaded.problem_path, out_dir, loaded.points, resume=resume, force=force,
                         quiet=quiet, point_fn=point_fn, executor=ex,
                         reuse_model=loaded.spec.reuse_model,
                         info={"name": loaded.spec.name or loaded.study_path.stem,
                               "study_file": str(loaded.study_path),
                               "spec": loaded.spec.model_dump(mode="json", by_alias=True,
                                                              exclude_none=True)})
    except BaseException:
        ex.close(kill=True)
        raise
    ex.close()
    return res


def run_points(problem_path: str | os.PathLike, out_dir: str | os.PathLike,
               points: Iterable[Point | dict], *, workers: int | None = None,
               serial: bool = False, scheduler: Any = None, resume: bool = False,
               quiet: bool = False, point_fn: Callable | None = None,
               executor: Executor | None = None, info: dict[str, Any] | None = None,
               reuse_model: bool = True, force: bool = False) -> StudyResult:
    """The study engine for a given list of points (``Point`` or its JSON dict: ``id``,
    ``parameters``, ``seed``, ``parent``, ``tags``). Pareto scans call this with their own
    points; pass ``executor`` to reuse one across calls. ``reuse_model``: the default point
    function re-solves one built model per worker where it can (:func:`solve_point`)."""
    t_start = time.perf_counter()
    problem_path = Path(problem_path).resolve()
    out_dir = Path(out_dir)
    points = [p if isinstance(p, Point) else Point.from_json(p) for p in points]
    _check_points(points)
    problem_text = problem_path.read_bytes()
    sha = hashlib.sha256(problem_text).hexdigest()
    fingerprint = hashlib.sha256(
        sha.encode() + json.dumps([p.to_json() for p in points], sort_keys=True).encode()
    ).hexdigest()[:16]

    # -- refuse before touching anything --------------------------------------------------
    plan_file = out_dir / "plan.json"
    if plan_file.exists() and resume:
        try:
            old = json.loads(plan_file.read_text()).get("fingerprint")
        except ValueError:
            old = None
        if old != fingerprint:
            raise StudyError(f"{out_dir} holds a different study (the study block or the "
                             "problem file changed since it was started); use a new --out")
    elif plan_file.exists() and not force:
        raise StudyError(f"{out_dir} already holds a study: pass --resume to continue "
                         "it, --force to replace it, or choose a new --out")
    else:
        try:
            run_folder.check_destination(out_dir, "study", force=force)
        except run_folder.FolderError as e:
            raise StudyError(str(e)) from None
        if force and out_dir.is_dir() and any(out_dir.iterdir()):
            run_folder.move_aside(out_dir)
        else:
            run_folder.clean_leftovers(out_dir)

    own_executor = executor is None
    ex = executor or Executor(workers=workers, serial=serial, scheduler=scheduler)
    try:
        return _run(ex, problem_path, problem_text, sha, fingerprint, out_dir, points,
                    quiet, point_fn, dict(info or {}), t_start, reuse_model)
    except BaseException:
        if own_executor:
            ex.close(kill=True)
            own_executor = False
        raise
    finally:
        if own_executor:
            ex.close()


def _check_points(points: list[Point]) -> None:
    if not points:
        raise StudyError("the study has no points")
    seen: set[str] = set()
    for p in points:
        if not p.id or p.id.startswith(".") or "/" in p.id or p.id in seen:
            raise StudyError(f"bad or repeated point id {p.id!r}")
        seen.add(p.id)


def _run(ex: Executor, problem_path: Path, problem_text: bytes, sha: str, fingerprint: str,
         out_dir: Path, points: list[Point], quiet: bool, point_fn: Callable | None,
         info: dict[str, Any], t_start: float, reuse_model: bool = True) -> StudyResult:
    points_dir = out_dir / "points"
    points_dir.mkdir(parents=True, exist_ok=True)
    earlier = (run_folder.read_marker(out_dir) or {}).get("entries", [])
    run_folder.write_marker(out_dir, "study", [*earlier, *STUDY_ENTRIES])
    for stale in points_dir.glob(".*.ocdsl-*"):  # half-written folders of a killed run
        run_folder.remove_tree(stale) if stale.is_dir() else stale.unlink()
    for stale in out_dir.glob(".study.*.ocdsl-*"):
        stale.unlink(missing_ok=True)
    _atomic_write(out_dir / "plan.json", json.dumps(
        {"fingerprint": fingerprint, "problem_file": str(problem_path), "problem_sha256": sha,
         "points": [p.to_json() for p in points]}, indent=1))

    info = {**info, "problem_file": str(problem_path), "fingerprint": fingerprint,
            "executor": ex.describe(), "client_host": socket.gethostname()}
    table = _Table(out_dir, points, info)
    by_id = {p.id: p for p in points}
    order = {p.id: k for k, p in enumerate(points)}
    resumed = 0
    for p in points:
        meta = _finished(points_dir, p)
        if meta is not None:
            table.set(p.id, _summary(points_dir / p.id), meta)
            resumed += 1
    finished = {pid for pid, r in table.rows.items() if r["status"] != "pending"}
    extra = {"resumed": resumed}
    table.write("running", extra, force=True)

    children: dict[str, list[str]] = {}
    ready: list[tuple[int, str]] = []
    for p in points:
        if p.id in finished:
            continue
        if p.parent and p.parent in by_id and p.parent not in finished:
            children.setdefault(p.parent, []).append(p.id)
        else:
            heapq.heappush(ready, (order[p.id], p.id))

    progress = _Progress(f"{info.get('name', 'study')} on {ex.describe()}", len(points), quiet)
    inflight: dict[Any, str] = {}
    session = uuid.uuid4().hex[:8]
    state = "interrupted"
    try:
        progress.update(table.counts(), 0, table.best())
        while ready or inflight:
            while ready and len(inflight) < ex.capacity:
                _, pid = heapq.heappop(ready)
                p = by_id[pid]
                warm_id = _warm_source(p, by_id, table)
                task = {"point": p.to_json(), "problem_path": str(problem_path),
                        "problem_text": problem_text, "problem_sha": sha,
                        "warm_files": _read_files(points_dir / warm_id) if warm_id else None,
                        "warm_id": warm_id, "point_fn": point_fn, "reuse_model": reuse_model}
                h = ex.submit(_solve_point, task, key=f"ocdsl-{pid}-{session}")
                inflight[h] = pid
                if ex.kind == "serial":
                    break  # already ran: record it before starting the next
            done, _ = ex.wait(list(inflight), timeout=0.5)
            for h in done:
                pid = inflight.pop(h)
                p = by_id[pid]
                warm_id = h.args[0]["warm_id"]
                try:
                    out = h.result()
                    files = out["files"]
                    meta = {"host": out.get("host"), "pid": out.get("pid"),
                            "task_s": out.get("task_s")}
                except Exception as exc:  # the executor lost it: record, never stop
                    lost = isinstance(exc, WorkerLost)
                    res = _error_result(problem_path.stem, p, f"{type(exc).__name__}: {exc}",
                                        "" if lost else traceback.format_exc())
                    tmp = Path(tempfile.mkdtemp(prefix=run_folder.temp_prefix(pid) + "err-",
                                                dir=points_dir))
                    try:
                        res.write(tmp / "run")
                        files = _read_files(tmp / "run")
                    finally:
                        shutil.rmtree(tmp, ignore_errors=True)
                    meta = {"host": None, "pid": None}
                meta.update(point=p.to_json(), warm_start=warm_id, attempts=h.attempts,
                            study=fingerprint)
                _install_point(points_dir, p, files, meta)
                table.set(pid, _summary(points_dir / pid), meta)
                for child in children.pop(pid, []):
                    heapq.heappush(ready, (order[child], child))
                table.write("running", extra)
            progress.update(table.counts(), min(len(inflight), ex.workers), table.best())
        state = "complete"
    finally:
        if inflight:
            ex.cancel(list(inflight))
        progress.stop()
        wall = time.perf_counter() - t_start
        table.write(state, {**extra, "wall_time_s": wall}, force=True)
    res = StudyResult(out_dir, list(table.rows.values()), {**table.counts(), "resumed": resumed},
                      table.best(), state, wall, ex.describe(), table.pnames)
    _final_table(res, quiet)
    return res


def _warm_source(p: Point, by_id: dict[str, Point], table: _Table) -> str | None:
    """The nearest finished, successful ancestor along the continuation chain."""
    q = p.parent
    while q and q in by_id:
        if table.rows[q]["status"] in GOOD:
            return q
        q = by_id[q].parent
    return None
