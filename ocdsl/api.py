"""The Python API: load a problem file, solve it, get a Result with NumPy arrays by name.

    >>> import ocdsl
    >>> res = ocdsl.load("configs/brachistochrone.yaml").solve()
    >>> res.tf, res["x"][:3]
"""
from __future__ import annotations

import functools
import json
import tempfile
import threading
import time
import traceback
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from . import run_folder
from .chain import stages as chain_stages
from .result import Result
from .spec import compile as spec_compile
from .spec.errors import SpecError
from .spec.loader import load_yaml, load_yaml_text


@dataclass
class Timer:
    stages: dict[str, float] = field(default_factory=dict)
    start: float = field(default_factory=time.perf_counter)

    def add(self, stage: str, seconds: float) -> None:
        self.stages[stage] = self.stages.get(stage, 0.0) + seconds

    def measure(self, stage: str):
        timer = self

        class _Ctx:
            def __enter__(self):
                self.t = time.perf_counter()

            def __exit__(self, *exc):
                timer.add(stage, time.perf_counter() - self.t)
                return False

        return _Ctx()

    def breakdown(self) -> dict[str, float]:
        out = {k: round(v, 6) for k, v in self.stages.items()}
        out["total"] = round(time.perf_counter() - self.start, 6)
        return out


def parameter_values(parameters: dict | None) -> dict[str, float]:
    """``parameters`` as numbers, each a finite number or a constant expression (`"1/9"`), as
    `--param` takes them (unseen52 F7: `{"l": "1/9"}` was a bare "could not convert string to
    float" traceback); a ValueError naming the parameter otherwise."""
    from .spec.expr import constant_value

    out = {}
    for name, value in (parameters or {}).items():
        try:
            out[name] = constant_value(value)
        except ValueError:
            raise ValueError(f"parameters[{name!r}] = {value!r} is not a finite number or a constant expression "
                             "such as 1/9 or 2*pi") from None
    return out


# a solve redirects the process's standard streams and file descriptors (Ipopt's output, the
# progress line) and sets process-wide state (the cache switch, Pyomo's loggers): solves
# from several threads broke each other and left stdout redirected (unseen52 F5), so they
# run one at a time in a process; parallel solves are the executor's processes
_SOLVE_LOCK = threading.RLock()


def _one_at_a_time(fn):
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with _SOLVE_LOCK:
            return fn(*args, **kwargs)
    return wrapper


def _check_warm_start(warm_start) -> None:
    """A ValueError where ``warm_start`` is given and is no usable run folder."""
    if warm_start is None:
        return
    from .result import warm_start_refusal

    why = warm_start_refusal(warm_start)
    if why:
        raise ValueError(f"warm_start {warm_start}: {why}")


def compile_file(path: str | Path, parameters: dict[str, float] | None = None,
                 timer: Timer | None = None, *, text: str | None = None) -> spec_compile.LoadedFile:
    """Parse and compile a problem file; raises SpecError with every problem found.
    ``text`` compiles a document ocdsl generated itself, named ``path`` in its errors."""
    timer = timer or Timer()
    with timer.measure("parse"):
        located = load_yaml(path) if text is None else load_yaml_text(text, str(path))
        spec, issues = spec_compile.validate_all(located)
    with timer.measure("symbolic"):
        return spec_compile.compile_spec(Path(path), located, spec, issues, parameter_values(parameters))


class Loaded:
    """A compiled problem file, ready to solve (``ocdsl.load(path)``)."""

    def __init__(self, path: str | Path, parameters: dict[str, float] | None = None):
        self.path = Path(path)
        self.timer = Timer()
        self.file = compile_file(path, parameters, self.timer)
        self._parameters = parameter_values(parameters)
        self._reuse = None          # ocdsl.solve.reuse.ModelReuse, made on the first reuse=True

    @property
    def problem(self):
        return self.file.problem

    @_one_at_a_time
    def solve(self, out: str | Path | None = None, *, parameters: dict[str, float] | None = None,
              seed: int | None = None, warm_start: str | Path | None = None, verbose: bool = False,
              progress: bool = False, reuse: bool = False, force: bool = False) -> Result:
        """Solve; ``parameters`` re-compiles with other constants without re-reading the file
        (what a study worker does for each of its points). The handle itself is not changed.

        ``reuse``: with ``parameters``, keep one Pyomo model per set of parameter names, with
        those constants as mutable Params, and re-solve it at each call whose problem has the
        same structure (ocdsl/solve/reuse.py); else, and always as a fallback, build afresh.

        ``out``: the run folder, refused before the solve if ocdsl may not write there
        (ocdsl/run_folder.py); ``force`` replaces an ocdsl folder of another kind. A
        ``warm_start`` that is no usable run folder is a ValueError before any work."""
        _check_warm_start(warm_start)
        if out is not None:
            run_folder.check_destination(out, "run", force=force)
        timer, file = Timer(), self.file
        if parameters:
            parameters = parameter_values(parameters)
            with timer.measure("symbolic"):
                merged = {**self._parameters, **parameters}
                file = spec_compile._Compiler(self.path, file.located, file.spec, merged).compile()
        else:
            timer.stages.update(self.timer.stages)
        result = None
        if reuse and parameters:
            if self._reuse is None:
                from .solve.reuse import ModelReuse

                self._reuse = ModelReuse(self)
            from .solve.ipopt import time_limit

            with time_limit(file.spec.solver.time_limit):
                result = self._reuse.solve(file, parameters, timer, seed=seed, warm_start=warm_start,
                                           verbose=verbose, progress=progress)
            if result is not None:
                verify(file, result, timer)
        if result is None:
            with _chain(file, out, warm_start, quiet=not progress, verbose=verbose) as (started, stages):
                result = execute(started, timer, seed=seed, warm_start=warm_start, verbose=verbose,
                                 progress=progress)
                chain_stages.finish(result, file, stages)
                if out is not None:
                    write_run(result, out, self.path, force=force, extra_dirs=chain_stages.entries(stages))
        elif out is not None:
            write_run(result, out, self.path, force=force)
        return result


def load(path: str | Path, parameters: dict[str, float] | None = None) -> Loaded:
    return Loaded(path, parameters)


def execute(file, timer: Timer, time_limit: float | None = None, **kwargs) -> Result:
    """Controller files go to the closed-loop back end; the rest to ``ocdsl.run.execute``,
    whose result is then verified (:func:`verify`). The solves share the wall-clock limit
    ``time_limit`` (default: the file's ``solver: time_limit``)."""
    from .solve.ipopt import time_limit as limited

    with limited(time_limit or file.spec.solver.time_limit):
        return _execute(file, timer, **kwargs)


def _execute(file, timer: Timer, **kwargs) -> Result:
    if file.controller is not None:
        from .control.problem_file import run_controller_file

        result = run_controller_file(file, timer)
        verify_closed_loop(file, result, timer)
        return result
    from .run import execute as run_method
    from .solve.ipopt import interrupted, interrupted_by, solves_cut

    result = run_method(file, timer, **kwargs)
    cut = solves_cut()
    if cut and result.status in ("optimal", "acceptable"):
        # the limit cut later starts or checks (the bisection of a fixed mesh): the best solution
        # stands, but not as if the run had done them (unseen42 F3: optimal, exit 0, two starts
        # and the bisection check never run)
        result.message = (f"the run's time limit cut {cut} of its solves (later starts or checks: "
                          f"extra.starts and the notes say which); the best solution found ({result.status}) "
                          f"is written: raise `solver: time_limit` or --time-limit for the whole run"
                          + (f"; {result.message}" if result.message else ""))
        result.extra["cut_short"] = {"solution_status": result.status, "solves_cut": cut}
        result.status = "time_limit"
    if interrupted():      # Ctrl-C or SIGTERM: the run stops here, its last iterate is the result
        result.status = "interrupted"
        if not result.message.startswith("interrupted"):
            result.message = f"interrupted ({interrupted_by()}); {result.message}"
        result.verification = {"status": "skipped", "checks": [],
                               "summary": f"the run was interrupted ({interrupted_by()})"}
        return result
    verify(file, result, timer)
    return result


def verify_closed_loop(file, result: Result, timer: Timer) -> None:
    """Each law's closed-loop run flown again by the verification's integrator
    (:mod:`ocdsl.verify.closed_loop`): the simulation's fixed step is what is checked."""
    from .control.simulate import saturation_limits
    from .verify import VerifySettings, verify_result
    from .verify.closed_loop import closed_loop_problem

    from .symbolic.sdc import _split_states

    spec = file.controller
    laws = [ph.name for ph in result.phases]
    with timer.measure("verify"):
        xs, _ = _split_states(file.model, spec.auxiliary, spec.states)
        cost = (xs, spec.matrix("Q", len(xs)), spec.matrix("R", len(file.model.controls)))
        result.extra["reported_integrals"] = {f"{law}.cost": float(result.extra[law]["cost"]) for law in laws
                                              if isinstance(result.extra.get(law), dict)
                                              and result.extra[law].get("cost") is not None}
        problem = closed_loop_problem(file.model, result.parameters, laws,
                                      saturation_limits(spec.saturation, len(file.model.controls)),
                                      spec.simulate.horizon, cost)
        result.verification = verify_result(problem, result,
                                            VerifySettings.of(file.spec.verify).closed_loop())


def verify(file, result: Result, timer: Timer) -> None:
    """The independent verification of every back end's trajectory (ocdsl/verify), unless
    the back end already verified this result at the file's settings."""
    from .verify import VerifySettings, attach_verification

    settings = VerifySettings.of(file.spec.verify)
    done = result.verification
    if not (done and done.get("tolerance") == settings.tolerance and done.get("status") in ("verified", "failed")):
        with timer.measure("verify"):
            attach_verification(file.problem, result, settings)
        result.wall_time_s = {**result.wall_time_s, **timer.breakdown()}
    checks = (result.verification or {}).get("checks") or []
    if result.extra.get("notes") and any(c["name"].startswith("dynamics") and c.get("passed") is False
                                         for c in checks):
        from .solve.arcs import qualified_notes

        result.extra["notes"] = qualified_notes(result.extra["notes"],
                                                (result.extra.get("bisection") or {}).get("agrees") is True)


def write_run(result: Result, out: str | Path, source: Path | None, force: bool = False,
              extra_dirs: dict[str, Path] | None = None, logs: Path | None = None) -> Path:
    """The run folder; ``logs``: a scratch folder of Ipopt output files (``confine_output_file``)
    whose files go in beside result.json."""
    from .provenance import source as made_by

    result.extra.setdefault("ocdsl", made_by())
    extra = {}
    if source is not None and source.exists():
        extra["problem.yaml"] = source.read_text()
    for log in sorted(logs.iterdir()) if logs is not None else []:
        if log.is_file() and log.name not in ("problem.yaml", "result.json", "trajectory.csv"):
            extra[log.name] = log.read_text(errors="replace")
    return result.write(out, extra_files=extra, force=force, extra_dirs=extra_dirs)


def confine_output_file(file, path: str | Path, scope: ExitStack) -> Path | None:
    """Ipopt's ``output_file`` (``solver: options``) kept inside the run: Ipopt truncates the
    file it names, and a relative name meant the working folder, so a user's own ipopt.log
    there (and ipopt.2.log, a later solve's numbered copy) were emptied (unseen24 V2). A
    relative name now goes to a scratch folder whose files are written into the run folder;
    an absolute one is the user's explicit choice, refused when that file or a numbered copy
    of it exists (ocdsl overwrites nothing it did not write). Returns the scratch folder."""
    options = file.spec.solver.options or {}
    name = options.get("output_file")
    if not name:
        return None
    target = Path(str(name)).expanduser()
    if target.is_absolute():
        taken = [p for p in [target, *target.parent.glob(f"{target.stem}.*{target.suffix}")] if p.exists()]
        if taken:
            from .spec.errors import Issue

            raise SpecError([Issue(str(path), file.located.line(("solver", "options", "output_file")),
                                   f"solver option output_file: {taken[0]} exists, and Ipopt would empty it "
                                   "(ocdsl never overwrites a file it did not write): name a new file, or a "
                                   "relative name (the log then goes into the run folder)")])
        return None
    scratch = Path(scope.enter_context(tempfile.TemporaryDirectory(prefix="ocdsl-ipopt-")))
    options["output_file"] = str(scratch / target.name)
    return scratch


@contextmanager
def _chain(file, out, warm_start, *, quiet: bool, verbose: bool):
    """``(file to solve, stages)``: a chained file's sources solved first (ocdsl/chain) in a
    scratch folder that lives until the run folder is written; a ``warm_start`` folder
    replaces every guess, the chain's too."""
    if warm_start is not None or not chain_stages.chained(file):
        yield file, []
        return
    with tempfile.TemporaryDirectory(prefix="ocdsl-stages-") as work:
        yield chain_stages.prepare(file, Path(out) if out is not None else None, Path(work),
                                   quiet=quiet, verbose=verbose)


def _complete_run(folder: Path) -> bool:
    """``folder`` holds a run ocdsl finished writing whose run was not interrupted itself."""
    marker = run_folder.read_marker(folder) if folder.is_dir() else None
    if marker is None or marker.get("kind") != "run" or marker.get("partial"):
        return False
    try:
        return json.loads((folder / "result.json").read_text()).get("status") != "interrupted"
    except (OSError, ValueError, AttributeError):
        return False


@_one_at_a_time
def run_file(path: str | Path, out_dir: str | Path | None, parameters: dict[str, float] | None = None,
             seed: int | None = None, warm_start: str | Path | None = None, quiet: bool = True,
             verbose: bool = False, force: bool = False, time_limit: float | None = None) -> Result:
    """Parse, build, solve and write the run folder. Never raises for a failed solve.

    A bad problem file still raises :class:`SpecError`, and an ``out_dir`` ocdsl may not
    write :class:`~ocdsl.run_folder.FolderError` (both before any work, nothing written):
    it is the caller's input that is wrong, not the run. ``force`` replaces an ocdsl
    folder of another kind (never files ocdsl did not write).
    """
    timer = Timer()
    file = compile_file(path, parameters, timer)
    if warm_start is not None and getattr(file.method, "transcription", None) == "flat-bspline":
        # a usage error before any work (unseen22 b21: a failed run folder, exit 1)
        from .spec.errors import Issue

        raise SpecError([Issue(str(path), file.located.line(("method",)),
                               "--warm-start: flat-bspline takes no warm start; run without it (the "
                               "flat NLP starts from the file's guess)")])
    _check_warm_start(warm_start)
    if out_dir is not None:
        run_folder.check_destination(out_dir, "run", force=force)
    with ExitStack() as scope:
        logs = confine_output_file(file, path, scope)
        stages = []
        try:
            started, stages = scope.enter_context(_chain(file, out_dir, warm_start, quiet=quiet, verbose=verbose))
            result = execute(started, timer, time_limit, seed=seed, warm_start=warm_start, verbose=verbose,
                             progress=not quiet)
            chain_stages.finish(result, file, stages)
        except SpecError:
            raise
        except Exception as e:  # a crash in a back end (or a stage) still leaves a diagnosed run folder
            # the message is what went wrong; where in ocdsl it happened is for a bug report
            # (unseen19: a model that is not flat printed the reason, then a traceback)
            result = Result(name=file.spec.name, status="error", message=f"{type(e).__name__}: {e}",
                            wall_time_s=timer.breakdown(), method=dict(file.spec.method),
                            parameters=file.parameters,
                            problem=file.problem.description if file.problem else {},
                            extra={"traceback": traceback.format_exc(limit=6)})
        if out_dir is not None and result.status == "interrupted" and _complete_run(Path(out_dir)):
            # Ctrl-C stops a run; it does not throw away the complete one it would have replaced
            # (unseen24 G4: the earlier result became the interrupted iterate, tables gone)
            result.message += (f"; the earlier complete run in {out_dir} was kept and the interrupted iterate "
                               "not written (run again with another --out to keep an interrupted one)")
            result.extra["run_folder_kept"] = str(out_dir)
        elif out_dir is not None:
            try:
                write_run(result, out_dir, Path(path), force=force, extra_dirs=chain_stages.entries(stages),
                          logs=logs)
            except OSError as e:    # a full disk, a folder made read-only meanwhile: said, not a traceback
                objective = f", objective {result.objective:.10g}" if result.objective is not None else ""
                raise run_folder.FolderError(
                    f"{out_dir}: the run folder could not be written ({e.strerror or e}); nothing of it was "
                    f"left behind (the run ended {result.status}{objective}): free space or choose another "
                    "--out, and run again") from None
    return result
