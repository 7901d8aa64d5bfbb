"""The ``ocdsl`` command. Imports are lazy so that ``ocdsl --help`` starts fast.

Exit codes: 0 solved and every expect check passed; 1 the run failed or a check failed
(the run folder is still written, with the diagnosis); 2 bad problem file or bad usage;
130 interrupted by Ctrl-C (the run folder holds the last iterate, status interrupted; a complete
earlier run in the folder is kept instead).
"""
from __future__ import annotations

import sys
from pathlib import Path

import click


class _SpecFailure(click.ClickException):
    exit_code = 2

    def show(self, file=None):
        click.echo(f"Error: {self.message}", err=True)


def _compile_or_exit(fn, *args, **kwargs):
    """Bad input (the problem file, or an output folder ocdsl may not write): one error, exit 2."""
    from .run_folder import FolderError
    from .spec.errors import SpecError

    try:
        return fn(*args, **kwargs)
    except (SpecError, FolderError) as e:
        raise _SpecFailure(str(e)) from None


def _parse_params(items: tuple[str, ...]) -> dict[str, float]:
    """NAME=VALUE pairs; VALUE a number or a constant expression of the problem language
    (`1/9`, `2*pi`, `sqrt(2)`), as a file's parameters may be written (unseen20)."""
    from .spec.expr import constant_value

    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if sep and name.strip() in out:     # the last one silently won (unseen24)
            raise click.BadParameter(f"'{name.strip()}' is given twice", param_hint="--param")
        try:
            if not sep or not name.strip():
                raise ValueError
            out[name.strip()] = constant_value(value)
        except ValueError:
            raise click.BadParameter(f"'{item}' is not NAME=NUMBER (a finite number or a constant "
                                     "expression such as 1/9 or 2*pi)", param_hint="--param") from None
    return out


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="ocdsl")
def main() -> None:
    """Declarative optimal control: YAML problem files to verified optimal trajectories."""


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--out", "out", type=click.Path(file_okay=False), help="run folder (default runs/<file name>)")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE", help="override a constant parameter")
@click.option("--seed", type=int, default=None, help="seed of random initial guesses")
@click.option("--warm-start", type=click.Path(file_okay=False, exists=True), help="start from a previous run folder")
@click.option("--report", is_flag=True, help="also write the report (report.html and report.pdf, or the "
              "file's `report: {formats}`; `report: {enabled: true}` writes it without this flag)")
@click.option("--verbose", "-v", is_flag=True, help="show Ipopt's own log")
@click.option("--quiet", "-q", is_flag=True, help="no progress line and no summary")
@click.option("--force", is_flag=True, help="replace an earlier ocdsl folder of another kind at --out "
              "(never files ocdsl did not write)")
@click.option("--time-limit", type=click.FloatRange(min=0, min_open=True), default=None, metavar="SECONDS",
              help="wall-clock limit of the solves (default: the file's solver: time_limit, 3600 s)")
@click.option("--no-cache", "no_cache", is_flag=True, help="neither read nor write ocdsl's disk cache of "
              "generated code ($OCDSL_CACHE, default ~/.cache/ocdsl; see docs/architecture.md)")
def run(file, out, params, seed, warm_start, report, verbose, quiet, force, time_limit, no_cache):
    """Solve FILE and write a run folder (result.json, trajectory.csv, ...).

    --out must be a new folder, an empty one or an earlier ocdsl run folder (it is
    replaced in one step); any other folder is refused and left as it is."""
    from .startup import loading

    with loading("cli run"):
        from .api import run_file
        from .solve.ipopt import interrupted_by, interruptible

    _cache_off(no_cache)
    out = Path(out) if out else Path("runs") / Path(file).stem
    if warm_start is not None:
        _check_warm_start(Path(warm_start))
    if _has_block(file, "pareto"):
        sys.exit(_run_pareto(file, out, _parse_params(params), report, quiet, force))
    if _has_block(file, "study"):
        # the file's study block is checked as `ocdsl check` checks it, though `run` solves the
        # nominal problem only (unseen22 b12: check refused it, run said nothing)
        from .study.spec import StudyError, load_study

        try:
            _compile_or_exit(load_study, file)
        except StudyError as e:
            raise _SpecFailure(str(e)) from None
    with interruptible():      # Ctrl-C (SIGTERM): the last iterate is written, status interrupted, exit 130 (143)
        result = _compile_or_exit(run_file, file, out, _parse_params(params), seed=seed, warm_start=warm_start,
                                  quiet=quiet, verbose=verbose, force=force, time_limit=time_limit)
    if result.status == "interrupted":
        if not quiet:
            _summary(result, out)
        sys.exit(143 if interrupted_by() == "SIGTERM" else 130)
    if report or _report_enabled(out):
        _make_reports([out], None)
    if not quiet:
        _summary(result, out)
    sys.exit(0 if result.ok else 1)


def _check_warm_start(folder: Path) -> None:
    """A warm start is a run folder with a trajectory; anything else is a usage error before
    any work (unseen12 F7: a failed run folder was written, exit 1)."""
    from .result import warm_start_refusal

    why = warm_start_refusal(folder)
    if why:
        raise _SpecFailure(f"--warm-start {folder}: {why}")


def _cache_off(no_cache: bool) -> None:
    """--no-cache: through the environment, so that local study workers inherit it."""
    if no_cache:
        import os

        from .cache import ENV_OFF

        os.environ[ENV_OFF] = "1"


def _has_block(file: str, key: str) -> bool:
    from .spec.loader import load_yaml

    located = _compile_or_exit(load_yaml, file)
    return key in located.data


def _run_pareto(file: str, out: Path, params: dict, report: bool, quiet: bool, force: bool) -> int:
    """A ``pareto:`` file is a study of its own: a table of every solution plus a run per point."""
    import json

    from .study.pareto_run import run_pareto

    results, table = _compile_or_exit(run_pareto, file, out, parameters=params, force=force)
    if report:
        _make_reports([out], None)
    summary = json.loads((out / "result.json").read_text()) if (out / "result.json").exists() else {}
    checks = summary.get("expect", [])
    if not quiet:
        flags = table.get("pareto", [])
        click.echo(f"{len(results)} solutions, {sum(bool(f) for f in flags)} Pareto-optimal; study folder {out}")
        for warning in (summary.get("extra") or {}).get("warnings") or []:
            click.echo(f"  note: {warning}")
        verdict = summary.get("verification") or {}
        if verdict.get("summary") and verdict.get("status") != "not_applicable":
            click.echo(f"  verification: {verdict['summary']}")
        for c in checks:
            click.echo(f"  expect {c.get('name')}: {c.get('value')} vs {c.get('reference')} "
                       f"{'pass' if c.get('passed') else 'FAIL'}")
    # the set's result.json ``ok``: solved, expect checks passed, every point verified
    return 0 if results and summary.get("ok") else 1


def _summary(result, out: Path) -> None:
    from rich.markup import escape
    from rich.table import Table
    from rich.text import Text

    from .progress import console
    from .result_views import completed_solution, expect_comparison, numbers_note, shows_a_solution

    con = console()
    ok = "green" if result.status == "optimal" else "red"
    v = result.verification or {}
    vstatus = v.get("status", "not run")
    vcolour = {"verified": "green", "not_applicable": "white"}.get(vstatus, "red")
    warn = " (mode warn: does not fail the run)" if v.get("mode") == "warn" and vstatus != "verified" else ""
    from .result import certificate_failures, certificate_verdict

    # a failed certificate fails the run (Result.ok): the headline says so, not only the last line
    cfail = (f", certificate [red]failed[/red] ({escape(', '.join(certificate_failures(result.certificate)))})"
             if certificate_verdict(result.certificate) == "failed" else "")
    # a failed expectation fails the run too: named in the headline, not only lines below (unseen22 f05b)
    missed = [c["name"] for c in (result.expect or []) if not c.get("passed")]
    efail = f", expect [red]FAIL[/red] ({escape(', '.join(missed))})" if missed else ""
    # the file's own text (a name "test [draft]", a constraint "r[0]") is printed as text, not
    # read as console markup, which swallowed it (unseen37 F4)
    con.print(f"[bold]{escape(result.name)}[/bold]: solver [{ok}]{result.status}[/{ok}], "
              f"verification [{vcolour}]{vstatus.replace('_', ' ')}[/{vcolour}]{warn}{cfail}{efail}")
    unjudged = any(c.get("passed") is None for c in v.get("checks") or [])
    if (vstatus not in ("verified", "not_applicable") or unjudged) and v.get("summary"):
        con.print(f"  {v['summary']}", markup=False)
    if result.status not in ("optimal",) and result.message:
        # "controls [up, um]" is text; an error's reason may take several lines (every set of
        # flat outputs tried), other statuses' first line is their headline
        shown = result.message.splitlines() if result.status == "error" else result.message.splitlines()[:1]
        for line in shown:
            con.print(f"  {line}", markup=False)
    for note in result.extra.get("notes", []) + list(v.get("caveats") or []):
        con.print(f"  note: {note}", markup=False)
    table = Table(show_header=False, box=None, padding=(0, 2))

    def row(*cells: str) -> None:
        table.add_row(*(Text(c) for c in cells))      # plain text, as the headline's name

    # a failed run's objective is its last iterate's (or the guess's): never shown as a result
    if result.objective is not None and result.status in ("optimal", "acceptable"):
        row("objective", f"{result.objective:.10g}")
    elif result.objective is not None and result.status == "mesh_not_converged":
        # a solved mesh that missed the refinement's tolerance: a solution, not a last iterate
        row("objective", f"{result.objective:.10g} (on the reported mesh; refinement not converged)")
    elif result.objective is not None and (kept := completed_solution(result)):
        row("best completed", f"objective {result.objective:.10g}: {kept}")
    elif result.objective is not None and result.status == "feasible":
        # a parametric search's answer: feasible in its control class, no optimality conditions
        row("objective", f"{result.objective:.10g} (feasible: inside the tolerances in the search's "
                  "control class, no optimality conditions behind it)")
    elif result.objective is not None and result.iterations:
        row("last iterate", f"objective {result.objective:.10g} (not a solution)")
    for law in result.extra.get("laws", []):       # a controller file: each law's closed loop
        rec = result.extra.get(law) or {}
        cost = rec.get("cost")
        # each law's trajectory is verified on its own (its rows carry the law as phase)
        own = [c.get("passed") for c in v.get("checks") or [] if c.get("phase") == law]
        judged = ("" if not own else ", verified" if all(p is not False for p in own) else ", not verified")
        row(law, (f"{rec.get('status', '?')}, J = {cost:.10g}" if isinstance(cost, (int, float))
                        else str(rec.get("status", "?"))) + judged)
    robust = _robustness_line(result.tables.get("robustness"))
    if robust:
        row("robustness", robust)
    free = result.extra.get("free_parameters", [])
    if free and result.status in ("optimal", "acceptable", "mesh_not_converged"):
        row("free parameters", ", ".join(f"{n} {result.parameters[n]:.10g}" for n in free
                                               if n in result.parameters))
    # a run that ended without a solution holds its last iterate, or the guess when the
    # solve never started (unseen12 F9: "final time 5.05" was the guess of a refused option)
    qualifier = numbers_note(result)
    if isinstance(result.tf, dict):
        row("final times", ", ".join(f"{k} {v:.8g}" for k, v in result.tf.items()) + qualifier)
    elif result.tf is not None:
        row("final time", f"{result.tf:.10g}{qualifier}")
    # a flat refinement's starts solved its first level, whose objective is not the reported
    # (refined) one (unseen19: seed 2 printed "8: 0 ended at this objective")
    # (and a mesh refinement's, its first mesh: unseen27 FC1 printed "8: 0 ended at this objective")
    levels = (result.extra.get("refinement") or {}).get("levels") or []
    meshes = result.extra.get("mesh_history") or []
    if len(levels) > 1:
        first, said = levels[0].get("objective"), "the first level's objective"
    elif len(meshes) > 1:
        first, said = meshes[0].get("objective"), "the first mesh's objective"
    else:
        first, said = result.objective, "this objective"
    starts = _starts_line(result.extra.get("starts") or [], first, said)
    if starts:
        row("starts", starts)
    if result.nlp:
        row("NLP", f"{result.nlp.get('variables')} variables, {result.nlp.get('constraints')} constraints, "
                  f"{result.nlp.get('nonzeros')} Jacobian nonzeros")
    if result.iterations is not None:
        row("iterations", str(result.iterations))
    w = result.wall_time_s
    if w:
        parts = ", ".join(f"{k} {v:.3f}" for k, v in w.items() if k != "total")
        row("wall time", f"{w.get('total', 0):.3f} s ({parts})")
    kept = result.extra.get("run_folder_kept")
    row("run folder", f"{out} (the earlier run, kept; nothing of this one written)" if kept else str(out))
    if v.get("tolerance") is not None and vstatus in ("verified", "failed"):
        row("verification", f"{sum(c.get('passed') is not None for c in v.get('checks', []))} checks "
                  f"against tolerance {v['tolerance']:g}"
                  f" ({v.get('wall_time_s', 0):.3f} s)")
    con.print(table)
    for c in result.expect:
        mark = "[green]pass[/green]" if c["passed"] else "[red]FAIL[/red]"
        con.print(f"  expect {escape(expect_comparison(c, qualifier))} {mark}")
    verdict = certificate_verdict(result.certificate)
    if verdict is not None:
        from .report.status import certificate_reason

        mark = {"passed": "[green]pass[/green]", "failed": "[red]failed[/red]"}.get(
            verdict, f"[yellow]{'not evaluated' if verdict == 'error' else verdict}[/yellow]")
        if verdict == "passed" and not shows_a_solution(result):
            # conditions that hold at a last iterate say nothing of a solution (unseen43 F10)
            mark = "[yellow]pass on the last iterate (not a solution)[/yellow]"
        why = (", ".join(certificate_failures(result.certificate)) if verdict == "failed"
               else certificate_reason(result.certificate))
        if why.startswith(f"{verdict}: "):      # "inconclusive (inconclusive: ...)" said once
            why = why[len(verdict) + 2:]
        con.print(f"  optimality certificate (necessary conditions): {mark}{f' ({escape(why)})' if why else ''}")
        cert = result.certificate or {}
        for c in ((cert.get("phases") or {}).values() if isinstance(cert.get("phases"), dict) else [cert]):
            for check in ("end_arcs", "flown_control"):
                reason = ((c or {}).get(check) or {}).get("reason")
                if reason:
                    con.print(f"    {reason}", markup=False)


def _robustness_line(table) -> str:
    """Where each law of a robustness sweep regulated the plant (the sweep leaves the run's
    status alone, docs/controllers.md, so its outcome is said here)."""
    if not table or "factor" not in table:
        return ""
    factors = [f"{f:g}" for f in table["factor"]]
    parts = []
    for col, values in table.items():
        if col.endswith(".stable"):
            held = [f for f, v in zip(factors, values) if v == 1]
            parts.append(f"{col[:-len('.stable')]} regulates at {', '.join(held) or 'none'}")
    return f"factors {', '.join(factors)}: " + "; ".join(parts) if parts else ""


def _starts_line(records: list, best: float | None, what: str = "this objective") -> str:
    """How the starts of ``method: {starts: N}`` ended (unseen8: eight starts back in one
    basin read as confirmation, and the summary did not say how they ended); ``best``: the
    objective they are compared with, ``what`` it is."""
    if len(records) < 2 or best is None:
        return ""
    solved = [r["objective"] for r in records if r.get("status") in ("optimal", "acceptable")
              and r.get("objective") is not None]
    near = 1e-6 * max(1.0, abs(best))
    same = sum(abs(j - best) <= near for j in solved)
    others = sorted({round(j, 8) for j in solved if abs(j - best) > near})
    text = f"{len(records)}: {same} ended at {what}"
    if others:
        shown = ", ".join(f"{j:.8g}" for j in others[:4]) + (", ..." if len(others) > 4 else "")
        text += f", {len(solved) - same} elsewhere ({shown})"
    if len(solved) < len(records):
        text += f", {len(records) - len(solved)} did not solve"
    if same == len(records):
        # perturbed starts stay near the guess: eight in one basin read as corroboration of an
        # optimum 30 % above the global one (unseen47 F8, an obstacle passed on the other side)
        text += " (a local optimum: starts perturb the guess and do not show it global)"
    return text


@main.command()
@click.argument("file", type=click.Path(dir_okay=False))
def check(file):
    """Validate FILE without solving it."""
    from .api import compile_file

    if _has_block(file, "pareto"):
        from .spec.pareto import load_pareto

        _compile_or_exit(load_pareto, file)
        click.echo(f"{file}: ok (pareto study)")
        return
    if _has_block(file, "problem_file"):
        # a study file of its own (`problem_file:` and `study:`, docs/studies.md): its block,
        # then the problem it names (unseen42 F4: "missing required key 'name'")
        from .study.spec import StudyError, load_study

        try:
            loaded = _compile_or_exit(load_study, file)
        except StudyError as e:
            raise _SpecFailure(str(e)) from None
        _compile_or_exit(compile_file, str(loaded.problem_path))
        click.echo(f"{file}: ok (study of {loaded.problem_path.name}: {len(loaded.points)} points)")
        return
    f = _compile_or_exit(compile_file, file)
    if "study" in f.located.data:      # the study block too (sweeps, samples, the point limit)
        from .study.spec import StudyError, load_study

        try:
            _compile_or_exit(load_study, file)
        except StudyError as e:
            raise _SpecFailure(str(e)) from None
    if f.problem is not None:
        for ph in f.problem.phases:
            click.echo(f"{file}: phase '{ph.name}': {len(ph.states)} states, {len(ph.controls)} controls, "
                       f"{len(ph.path)} path constraints; {len(f.problem.boundary)} boundary constraints")
    click.echo(f"{file}: ok")


@main.command()
def models():
    """List the registered SymPy models with their states, controls and parameters."""
    from .symbolic.registry import build_model, model_names, registered

    for name in model_names():
        entry = registered(name)
        try:
            m = build_model(name, {})
        except Exception as e:  # a model that needs options still gets listed
            click.echo(f"{name}: {entry.description} (needs options: {e})")
            continue
        click.echo(f"{name}: {entry.description}")
        click.echo(f"  states:     {', '.join(s.name for s in m.states)}")
        click.echo(f"  controls:   {', '.join(c.name for c in m.controls) or '-'}")
        params = ", ".join(f"{p.name}={v:g}" if v is not None else p.name for p, v in m.parameters.items())
        click.echo(f"  parameters: {params or '-'}")
        if entry.options:
            click.echo(f"  options:    {', '.join(f'{k} ({v})' for k, v in entry.options.items())}")


@main.command()
def transforms():
    """List the registered guess transforms (`guess: {from: ..., transform: NAME}`)."""
    from .chain.registry import get_transform, transform_names

    for name in transform_names():
        click.echo(f"{name}: {get_transform(name).description}")


@main.command()
def schema():
    """Print the JSON Schema of the problem language (for editors)."""
    import json

    from .spec.schema import json_schema

    click.echo(json.dumps(json_schema(), indent=2))


@main.command()
@click.argument("file", type=click.Path(dir_okay=False, exists=True))
@click.option("--out", "out", type=click.Path(file_okay=False), required=True)
@click.option("--workers", type=int, default=None, help="local worker processes (default: cores)")
@click.option("--serial", is_flag=True, help="run points one after another in this process")
@click.option("--scheduler", default=None, help="address of a Dask scheduler, tcp://HOST:PORT")
@click.option("--resume", is_flag=True, help="skip finished points of an interrupted study")
@click.option("--force", is_flag=True, help="replace an earlier ocdsl study or run folder at --out "
              "(never files ocdsl did not write)")
@click.option("--quiet", "-q", is_flag=True)
@click.option("--no-cache", "no_cache", is_flag=True, help="neither read nor write ocdsl's disk cache of "
              "generated code ($OCDSL_CACHE, default ~/.cache/ocdsl; see docs/architecture.md)")
def study(file, out, workers, serial, scheduler, resume, force, quiet, no_cache):
    """Run the study: block of FILE (sweep, starts, Monte Carlo) into folder OUT."""
    from .solve.ipopt import interrupted_by, interruptible
    from .study.run import run_study

    _cache_off(no_cache)

    try:
        with interruptible():      # Ctrl-C (SIGTERM): no new point starts; the study is `interrupted`
            res = _compile_or_exit(run_study, file, out, workers=workers, serial=serial, scheduler=scheduler,
                                   resume=resume, quiet=quiet, force=force)
    except (ValueError, ConnectionError, OSError) as e:
        raise _SpecFailure(str(e)) from None
    if getattr(res, "state", None) == "interrupted":
        sys.exit(143 if interrupted_by() == "SIGTERM" else 130)
    failed = getattr(res, "failed", 0)
    sys.exit(0 if not failed else 1)


@main.command()
@click.argument("run_dirs", nargs=-1, required=True, type=click.Path(file_okay=False, exists=True))
@click.option("--out", type=click.Path(file_okay=False), help="folder of a comparison report")
def report(run_dirs, out):
    """Write report.html and report.pdf for a run folder (the formats of its file's `report:`), or
    one comparison report for several."""
    _make_reports([Path(d) for d in run_dirs], Path(out) if out else None)


def _report_enabled(folder: Path) -> bool:
    from .run_folder import requested_report

    return requested_report(folder)[0]


def _make_reports(run_dirs: list[Path], out: Path | None) -> None:
    from .report.build import ReportError, make_comparison_report, make_report
    from .report.build.document import NotARunFolder
    from .run_folder import FolderError, requested_report

    try:
        if len(run_dirs) == 1 and out is None:
            single = run_dirs[0]
            # a study folder (no result.json of its own) gets a comparison report inside it
            files = make_report(single, requested_report(single)[1]) if (single / "result.json").exists() else \
                make_comparison_report([single], single)
        else:
            files = make_comparison_report(run_dirs, out or run_dirs[0].parent / "comparison")
    except (FolderError, NotARunFolder) as e:
        raise _SpecFailure(str(e)) from None
    except ReportError as e:
        raise click.ClickException(str(e)) from None
    except OSError as e:     # a read-only or full folder: one line (unseen24 F39: a traceback)
        where = f" in {Path(e.filename).parent}" if e.filename else ""     # the folder, not ocdsl's scratch name
        raise click.ClickException(f"the report could not be written{where}: {e.strerror or e}") from None
    for f in files:
        click.echo(f"wrote {f}")


@main.group()
def serve() -> None:
    """A server with ocdsl loaded, so that each command skips the imports (opt-in).

    While one runs, the `ocdsl` command hands every other command to it; each runs in a fresh
    fork of the server, in this folder with this environment. A changed ocdsl or
    environment is never served by an older server. See docs/architecture.md.
    """


@serve.command("start")
@click.option("--idle", type=click.FloatRange(min=1), default=1800.0, show_default=True,
              metavar="SECONDS", help="exit after this long without a command")
def serve_start(idle):
    """Start the server of this code (nothing happens if it runs)."""
    from .serve.server import ServeError, start

    try:
        st = start(idle)
    except (ServeError, OSError) as e:      # OSError: the socket folder cannot be made or written
        raise click.ClickException(str(e)) from None
    click.echo(f"ocdsl serve: pid {st['pid']}, socket {st['socket']}")


@serve.command("stop")
@click.option("--all", "every", is_flag=True, help="also servers of other code or environments")
def serve_stop(every):
    """Stop the server of this code."""
    from .serve.server import stop

    pids = stop(every)
    click.echo("ocdsl serve: stopped " + (", ".join(f"pid {p}" for p in pids) if pids else "nothing"))


@serve.command("status")
def serve_status():
    """Whether a server of this code runs (exit 0) or not (exit 1)."""
    from .serve.server import status

    st = status()
    if st["pid"]:
        click.echo(f"ocdsl serve: running, pid {st['pid']}, socket {st['socket']}")
    else:
        click.echo(f"ocdsl serve: no server of this code (socket {st['socket']})")
    for o in st["other_servers"]:
        click.echo(f"  a server of other code or environment: pid {o['pid']} (ocdsl serve stop --all)")
    sys.exit(0 if st["pid"] else 1)


def _register_bench() -> None:
    from .bench.cli import bench  # imports only click at module level

    main.add_command(bench, "bench")


_register_bench()


def entry() -> None:
    """The console script: ``main``, then the process ends without CPython's final garbage
    collection of what the command built. The OS returns the memory at once; the collection
    walked every Pyomo component first (0.9 s of an 18 s run at 100k NLP variables,
    reports/bench/levers.md section 18). Exit handlers still run and files are closed by
    the commands themselves. Not in ``main``, which tests call in-process."""
    import gc

    import warnings

    from .startup import one_command_process

    one_command_process()
    # NumPy's floating-point warnings inside ocdsl's own evaluations (a sqrt at the edge of its
    # domain, a horizon of 1e-300) printed source lines to the user's terminal (unseen40 F4); the
    # checks judge the NaNs they meet and the summary gives the verdicts
    warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"<?ocdsl")
    try:
        main()
    finally:
        gc.freeze()


if __name__ == "__main__":
    entry()
