"""The worker side of a study: one point solved into its own scratch folder and its files
sent back; the point folders, installed whole and read back on resume."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any, Callable

from ocdsl import run_folder
from ocdsl.result import Result, verification_lets_through

from .executor import worker_cache, worker_info
from .spec import Point, StudyError

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
def _install_point(points_dir: Path, point: Point, files: dict[str, bytes], meta: dict) -> None:
    with run_folder.assemble(points_dir / point.id, "run", force=True) as tmp:
        _write_files(tmp, files)
        (tmp / POINT_FILE).write_text(json.dumps(meta, indent=2))


def _summary(run_dir: Path) -> dict[str, Any]:
    data = json.loads((run_dir / "result.json").read_text())
    wall = data.get("wall_time_s") or {}
    sense = ((data.get("problem") or {}).get("objective") or {}).get("sense", "minimize")
    return {"status": data.get("status"), "ok": data.get("ok"),
            "verification": (data.get("verification") or {}).get("status"),
            "objective": _num(data.get("objective")),
            "tf": data.get("tf"), "iterations": data.get("iterations"),
            "wall_time_s": _num(wall.get("total")) if isinstance(wall, dict) else None,
            "message": _shortened(_why_not_ok(data) + (data.get("message") or "").strip().split("\n", 1)[0]),
            "sense": sense}


def _why_not_ok(data: dict) -> str:
    """Why a point whose solve converged is not ok, ahead of the solver's message (unseen12
    F11: a point that failed only its expect said 'mesh converged: ...')."""
    if data.get("ok") or data.get("status") not in ("optimal", "stable", "feasible"):
        return ""
    reasons = []
    verification = data.get("verification") or {}
    if not verification_lets_through(verification):
        reasons.append(f"verification {verification.get('status') or 'not run'}")
    if data.get("certificate_verdict") == "failed":
        reasons.append("certificate failed")
    failed = [c for c in data.get("expect") or [] if not c.get("passed")]
    if failed:
        from ..result_views import value_and_reference
    for c in failed[:2]:
        value = c.get("value")
        shown, ref = value_and_reference(value, c.get("reference")) if isinstance(value, (int, float)) else \
            ("no value", f"{c.get('reference'):.10g}")
        reasons.append(f"expect {c.get('name')}: {shown} vs {ref} FAIL")
    return "; ".join(reasons) + ". " if reasons else ""


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
    try:
        status = json.loads((d / "result.json").read_text()).get("status")
    except (OSError, ValueError):
        return None
    if status == "interrupted":
        # the point in hand when Ctrl-C or SIGTERM stopped the study: solved again by --resume,
        # not a finished failure (unseen42 F2: "complete", 1 failed, exit 1 at every resume)
        return None
    if meta.get("point", {}).get("parameters") != point.parameters or \
            meta.get("point", {}).get("seed") != point.seed:
        raise StudyError(f"{d} holds a different point than the study's {point.id} "
                         "(the study changed); use a new --out")
    return meta


def _shortened(text: str, limit: int = 300) -> str:
    """``text`` cut to ``limit`` characters at a word, marked: study.csv's messages stopped
    mid-word ("not th", unseen33 F12)."""
    if len(text) <= limit:
        return text
    return text[:limit].rsplit(" ", 1)[0].rstrip(",;:") + " ... (the point's result.json has it all)"
