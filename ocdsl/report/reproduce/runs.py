"""Running the examples into ``reports/`` (each swapped in when finished), the manifest
``reports/reproduce.json``, and re-making reports from the run folders."""
from __future__ import annotations

import json
import shutil
import subprocess
import time
import traceback
from pathlib import Path
from typing import Sequence

from ocdsl.report.reproduce.examples import CONFIGS, Example, GOOD, Outcome, REPORTS, classify
from ocdsl.report.reproduce.numbers import study_paper_numbers, write_index
from ocdsl.report.reproduce.references import NOT_REPRODUCED


# ================================================================================== runs
def _expect_ok(run_dir: Path) -> bool:
    try:
        data = json.loads((run_dir / "result.json").read_text())
    except (OSError, ValueError):
        return False
    return all(c.get("passed") for c in data.get("expect") or [])


def run_example(ex: Example, out_dir: Path, formats: Sequence[str], *, workers: int | None = None,
                quiet: bool = True, reports: Path = REPORTS) -> Outcome:
    """Solve one example into ``out_dir`` (which must not exist yet) and write its reports."""
    from ocdsl.report.build import make_comparison_report, make_report

    t0 = time.perf_counter()
    status, ok = "error", False
    if ex.kind in ("problem", "controller"):
        from ocdsl.api import run_file

        res = run_file(ex.path, out_dir, quiet=quiet)
        status = res.status
        ok = res.ok
        files = make_report(out_dir, formats) if formats else []
    elif ex.kind == "pareto":
        from ocdsl.study.pareto_run import run_pareto

        results, _ = run_pareto(ex.path, out_dir)
        status = f"{len(results)} solutions"
        ok = bool(results) and _expect_ok(out_dir)
        files = make_report(out_dir, formats) if formats else []
    elif ex.kind == "study":
        from ocdsl.study.run import run_study

        res = run_study(ex.path, out_dir, workers=workers, quiet=quiet)
        status = f"study {res.state}: {res.counts.get('ok', 0)} of {res.counts.get('points', 0)} ok"
        numbers = study_paper_numbers(out_dir, ex.stem)
        ok = res.ok and all(n["verdict"] != NOT_REPRODUCED for n in numbers)
        files = make_comparison_report([out_dir], out_dir, formats, title=ex.name) if formats else []
    else:  # pragma: no cover
        raise ValueError(f"unknown example kind {ex.kind!r}")
    return Outcome(ex.stem, ex.kind, status, ok, time.perf_counter() - t0, list(files))


def reproduce(examples: Sequence[Example], reports: Path = REPORTS, formats: Sequence[str] = ("html", "pdf"),
              *, workers: int | None = None, log=print) -> list[Outcome]:
    """Run ``examples`` into ``reports/<stem>/`` (each swapped in when finished), then write
    ``reports/index.html`` and ``reports/reproduce.json``. Never raises for a failed example."""
    reports = Path(reports)
    reports.mkdir(parents=True, exist_ok=True)
    outcomes: list[Outcome] = []
    for ex in examples:
        final = reports / ex.stem
        scratch = reports / ".new" / ex.stem      # same name: reports show the run folder's name
        shutil.rmtree(scratch, ignore_errors=True)
        scratch.parent.mkdir(exist_ok=True)
        log(f"[reproduce] {ex.stem} ({ex.kind}{', slow' if ex.slow else ''}) ...")
        t0 = time.perf_counter()
        try:
            out = run_example(ex, scratch, formats, workers=workers, reports=reports)
            old = reports / ".new" / f"{ex.stem}.old"
            shutil.rmtree(old, ignore_errors=True)
            if final.exists():
                final.rename(old)
            scratch.rename(final)
            shutil.rmtree(old, ignore_errors=True)
            out.files = [final / f.relative_to(scratch) for f in out.files]
        except Exception as exc:  # noqa: BLE001  (a broken example must not stop the others)
            shutil.rmtree(scratch, ignore_errors=True)
            out = Outcome(ex.stem, ex.kind, "error", False, time.perf_counter() - t0,
                          message=f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=-4)}")
        outcomes.append(out)
        log(f"[reproduce] {ex.stem}: {out.status}, {'ok' if out.ok else 'NOT OK'}, {out.seconds:.1f} s"
            + (f"\n{out.message}" if out.message else ""))
    try:
        (reports / ".new").rmdir()
    except OSError:
        pass
    write_manifest(reports, outcomes)
    index = write_index(reports)
    log(f"[reproduce] wrote {index}")
    return outcomes


def _git_commit() -> str | None:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def write_manifest(reports: Path, outcomes: Sequence[Outcome]) -> Path:
    """``reports/reproduce.json``: per example kind, status, ok, wall time, date, commit
    (entries of examples not re-run this time are kept)."""
    path = Path(reports) / "reproduce.json"
    try:
        data = json.loads(path.read_text())
        if not isinstance(data, dict):
            data = {}
    except (OSError, ValueError):
        data = {}
    when, commit = time.strftime("%Y-%m-%dT%H:%M:%S"), _git_commit()
    for o in outcomes:
        data[o.stem] = {"kind": o.kind, "status": o.status, "ok": o.ok, "wall_time_s": round(o.seconds, 1),
                        "made": when, "commit": commit,
                        **({"message": o.message.splitlines()[0][:300]} if o.message else {})}
    path.write_text(json.dumps(dict(sorted(data.items())), indent=1) + "\n")
    return path


# ======================================================================= reports only
def remake_reports(reports: Path = REPORTS, formats: Sequence[str] = ("html", "pdf"), *,
                   only: Sequence[str] | None = None, configs: Path = CONFIGS, log=print) -> list[Outcome]:
    """Re-make the reports of the run and study folders under ``reports`` from what they
    hold (nothing is solved), then the manifest's verdicts and the index. For a report
    made by a newer ocdsl from the same runs."""
    from ocdsl.report.build import load_run, make_comparison_report, make_report, read_study_table

    outcomes = []
    for d in sorted(p for p in Path(reports).iterdir() if p.is_dir() and not p.name.startswith(".")):
        if only and d.name not in only:
            continue
        t0 = time.perf_counter()
        missing = _missing_run_data(d, load_run)
        if missing:     # a committed folder holds no trajectories: its report stays as it is
            out = Outcome(d.name, "report", "skipped", False, 0.0,
                          message=f"{missing}: the report is kept; re-run it (--only {d.name}) to re-make it")
            outcomes.append(out)
            log(f"[reproduce] report {d.name}: skipped\n{out.message}")
            continue
        try:
            if (d / "result.json").is_file():
                files = make_report(d, formats)
                try:
                    res, _ = load_run(d)
                    status, ok = res.status, res.ok
                except Exception:  # noqa: BLE001
                    status, ok = "unreadable", False
                kind = "run"
            elif (d / "study.csv").is_file() or (d / "study.json").is_file():
                rows, meta = read_study_table(d)
                cfg = Path(configs) / f"{d.name}.yaml"
                title = classify(cfg).name if cfg.is_file() else (meta.get("name") or d.name)
                files = make_comparison_report([d], d, formats, title=title)
                n_ok = sum(str(r.get("status")) in GOOD for r in rows)
                status = f"study: {n_ok} of {len(rows)} ok"
                ok = n_ok == len(rows) and all(n["verdict"] != NOT_REPRODUCED for n in study_paper_numbers(d, d.name))
                kind = "study"
            else:
                continue
            out = Outcome(d.name, kind, status, ok, time.perf_counter() - t0, list(files))
        except Exception as exc:  # noqa: BLE001
            out = Outcome(d.name, "report", "error", False, time.perf_counter() - t0,
                          message=f"{type(exc).__name__}: {exc}")
        outcomes.append(out)
        log(f"[reproduce] report {d.name}: {out.status}, {'ok' if out.ok else 'NOT OK'}, {out.seconds:.1f} s"
            + (f"\n{out.message}" if out.message else ""))
    _update_verdicts(Path(reports), outcomes)
    log(f"[reproduce] wrote {write_index(reports)}")
    return outcomes


def _missing_run_data(folder: Path, load_run) -> str:
    """What a folder lacks for its report to be made again from it (empty: nothing): the
    run data that is not committed (trajectories, tables, a study's per-point runs)."""
    if (folder / "result.json").is_file():
        try:
            _, notes = load_run(folder)
        except Exception as exc:  # noqa: BLE001
            return f"result.json unreadable ({exc})"
        return "the run folder is incomplete (its trajectory or tables are not here)" if notes else ""
    if (folder / "study.csv").is_file() and not any(folder.glob("points/*/result.json")) \
            and not any(folder.glob("*/result.json")):
        return "the study's run folders are not here"
    return ""


def _update_verdicts(reports: Path, outcomes: Sequence[Outcome]) -> None:
    """The manifest keeps when each example was run; its status and ok follow the run
    folder as the current ocdsl reads it."""
    path = Path(reports) / "reproduce.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        data = {}
    for o in outcomes:
        if o.stem in data and o.status not in ("error", "skipped"):
            data[o.stem].update({"ok": o.ok, "report_made": time.strftime("%Y-%m-%dT%H:%M:%S"),
                                 "report_commit": _git_commit()})
            if o.kind == "run":
                data[o.stem]["status"] = o.status
    path.write_text(json.dumps(dict(sorted(data.items())), indent=1) + "\n")
