"""Run every example in ``configs/`` and write its reports under ``reports/``.

``python -m ocdsl.report.reproduce [--only NAME ...] [--skip-slow] [--formats html,pdf]
[--configs DIR] [--out DIR]`` (``make reproduce`` runs it after the slow tests).

For every configuration file ``configs/<stem>.yaml`` (by kind):

* problem files and controller files (``controller:`` block): ``ocdsl.api.run_file`` (what
  ``ocdsl run`` does) into the run folder ``reports/<stem>/``, then ``report.html``/``report.pdf``
  in it (:func:`ocdsl.report.make_report`); a file whose guess comes from another example's
  file (``guess: {from: other.yaml, reuse: ../reports/other}``, ocdsl/chain) runs after it,
  and reuses its fresh run folder;
* ``pareto:`` files: ``ocdsl.study.pareto_run.run_pareto`` into the study folder
  ``reports/<stem>/`` (its own ``result.json`` with the set, one run folder per solution),
  then its report;
* study files (``study:`` block): ``ocdsl.study.run.run_study`` into ``reports/<stem>/``,
  then one comparison report over the study (:func:`ocdsl.report.make_comparison_report`).

Each example is made in a scratch folder ``reports/.new/<stem>`` and swapped in only when
its reports are written, so an interrupted reproduction leaves the previous reports. Last,
``reports/index.html`` (:func:`ocdsl.report.make_index`) is made from *every* report folder
under ``reports/`` (also those not re-run this time, e.g. the slow ones with
``--skip-slow``): one row per paper number (each ``expect`` check of the run folders, and
the reference tables of :data:`PAPER_TABLES` for studies) with reference, ocdsl value,
error, pass/fail and a link to the report. ``reports/reproduce.json`` records, per
example, its kind, status, wall time and the date and commit it was made at.

Slow examples (minutes each) are those in :data:`SLOW`, named ``seed0_*``, or whose file has a top-level
comment line ``# reproduce: slow``; ``--skip-slow`` leaves them out.

Exit code: 0 when every example ran, its reports were written and its ``expect`` checks
passed; 1 otherwise (the reports are still written); 2 for bad options.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from ocdsl.chain.check import sources_of

CONFIGS = Path("configs")      # relative to the working directory (the repository root under make)
REPORTS = Path("reports")

#: Examples that take minutes (multi-start 6-DOF collocation, PSO paper runs, Table 4 study).
SLOW = frozenset({"seed0_rendezvous", "seed0_exact_euler", "seed0_table4",
                  "seed1_2N_paper", "seed1_5N_paper", "seed1_10N_paper"})
#: Every seed-0 file is a multi-start 6-DOF collocation (minutes), whatever its name.
SLOW_PREFIXES = ("seed0_",)
SLOW_MARK = re.compile(r"^#\s*reproduce:\s*slow\b", re.M | re.I)
GOOD = ("optimal", "acceptable", "feasible", "stable")

#: Where each reference value of the index comes from, per (report folder, expect check).
#: ``paper``: printed in the paper (the table or equation is named) - only these go to the
#: index's "paper" column; every other kind (``digest``: the seed digest's own synthetic
#: case or re-implementation; ``published``: a benchmark's published or analytic value;
#: ``computed``: a converged reference computed here) goes to the "other reference" column
#: with its label. ``wrong``: the test that shows the printed value cannot be right (the
#: row then counts as "paper value shown wrong" when ocdsl does not meet it, or meets an
#: ``at_most`` bound with room to spare: a better optimum).
REFERENCES: dict[tuple[str, str], dict[str, str]] = {
    ("brachistochrone", "tf"): {"kind": "published", "source": "dymos benchmark; the cycloid gives 1.8016031"},
    ("bryson_denham", "objective"): {"kind": "published", "source": "analytic, Bryson & Ho (1975): 4/(9 l)"},
    ("mesh_bryson_denham", "objective"): {"kind": "published", "source": "analytic, Bryson & Ho (1975): 4/(9 l)"},
    ("double_integrator", "tf"): {"kind": "published", "source": "analytic (bang-bang, one switch)"},
    ("minimal_double_integrator", "tf"): {"kind": "published", "source": "analytic (bang-bang, one switch)"},
    ("mesh_double_integrator", "tf"): {"kind": "published", "source": "analytic (bang-bang, one switch)"},
    ("two_phase_double_integrator", "brake.tf"): {"kind": "published", "source": "analytic"},
    ("two_phase_double_integrator", "accelerate.tf"): {"kind": "published", "source": "analytic"},
    ("goddard", "r(tf)"): {"kind": "published", "source": "control-toolbox indirect solution"},
    ("mesh_goddard", "r(tf)"): {"kind": "published", "source": "control-toolbox indirect solution"},
    **{(stem, q): {"kind": "published", "source": "exact bang-bang solution, Meditch (1964)"}
       for stem in ("moon_landing", "mesh_moon_landing") for q in ("objective", "tf", "m(tf)")},
    ("seed0_rendezvous", "tf"): {"kind": "paper", "source": "seed 0, §5.1 and Table 4 row [20, 0, 0] (GPM)"},
    ("seed0_fine", "tf"): {"kind": "digest", "source": "seed 0 issue's band [25.868, 25.873] (finer mesh)"},
    ("seed0_exact_euler", "tf"): {"kind": "digest", "source": "digest's re-implementation with the exact "
                                  "Euler equation (seed_000.md §7.3); the paper prints 25.8727 for eq. (13)"},
    ("seed1_10N_paper", "tf"): {"kind": "paper", "source": "seed 1, Table 5, present method (OCR-reconstructed)"},
    ("seed1_5N_paper", "tf"): {"kind": "paper", "source": "seed 1, Table 6, 5 N"},
    ("seed1_2N_paper", "tf"): {"kind": "paper", "source": "seed 1, Table 6, 2 N"},
    ("seed1_10N_optimal", "time(tf)"): {"kind": "paper", "source": "seed 1, Table 5, indirect reference [36]",
                                        "wrong": "tests/test_seed1_optimal.py::test_optimal_10N"},
    ("seed1_5N_optimal", "time(tf)"): {"kind": "paper", "source": "seed 1, Table 6, 5 N (Fourier-DPSO)",
                                       "wrong": "tests/test_seed1_optimal.py::test_optimal_5N_2N"},
    ("seed1_2N_optimal", "time(tf)"): {"kind": "paper", "source": "seed 1, Table 6, 2 N (Fourier-DPSO)",
                                       "wrong": "tests/test_seed1_optimal.py::test_optimal_5N_2N"},
    ("seed2_strategy1", "m(tf)"): {"kind": "paper", "source": "seed 2, Table 2 row 1 (strategy 1)"},
    ("seed2_strategy1", "tf"): {"kind": "computed", "source": "the time the printed mass implies, "
                                "(M − 149.932)/ṁ (the printed 1036.458 s is inconsistent with it)"},
    **{(stem, q): {"kind": "digest", "source": "digest's synthetic case (seed_004.md §5.3; the paper's "
                   "Table 1 is lost)"}
       for stem in ("seed4_case_A", "seed4_case_B", "seed4_two_burn_nlp") for q in ("n_solutions", "pareto_labels")},
}

#: Printed values a run folder is compared with beyond its expect block (the file's
#: expect holds another reference): report folder -> rows ``{quantity, column, paper,
#: source, tol | rtol, wrong}``, ``column`` a key of result.json (``tf``, ``objective``).
PRINTED_EXTRA: dict[str, list[dict[str, Any]]] = {
    "seed2_strategy1": [{"quantity": "tf", "column": "tf", "paper": 1036.458, "rtol": 5.0e-3,
                         "source": "seed 2, Table 2 row 1 (strategy 1)",
                         "wrong": "tests/test_lander.py::test_strategy1_printed_pair_is_inconsistent"}],
}

#: Paper numbers of study files, compared row by row with ``study.csv``: the study stem ->
#: per row (matched on its parameters) the printed values of ``study.csv`` columns
#: (``tf.<phase>``: that phase's entry of a per-phase ``tf``) and the accepted band per
#: column: ``tol`` (|ocdsl - paper| <= tol), ``rtol`` (relative), ``at_most`` (ocdsl <=
#: paper + tol: the problem is multi-modal and better optima exist). ``wrong``: the test
#: that shows the printed value cannot be right.
_T2 = "tests/test_lander.py::test_strategy1_printed_pair_is_inconsistent"
_T3 = "tests/test_lander.py::test_strategy3_printed_descents_cannot_land"
PAPER_TABLES: dict[str, dict[str, Any]] = {
    "seed0_table4": {
        "label": "Seed 0 Table 4 (GPM)",
        "match": ("x0", "y0", "z0"),
        "columns": {"tf": {"label": "tf", "tol": 5.0e-4}},
        "rows": [
            {"x0": 20, "y0": 0, "z0": 0, "paper": {"tf": 25.8727}, "source": "Table 4"},
            {"x0": 20, "y0": 4, "z0": 0, "paper": {"tf": 26.1674}, "at_most": True, "source": "Table 4",
             "wrong": "tests/test_seed0_pipeline.py::test_table4_row"},
            {"x0": 20, "y0": 4, "z0": 4, "paper": {"tf": 25.9360}, "source": "Table 4"},
            {"x0": 20, "y0": 4, "z0": -5, "paper": {"tf": 25.6607}, "source": "Table 4"},
            {"x0": 25, "y0": -5, "z0": -5, "paper": {"tf": 28.7185}, "at_most": True, "source": "Table 4",
             "wrong": "tests/test_seed0_pipeline.py::test_table4_row"},
        ],
    },
    "seed2_strategy2": {
        "label": "seed2_strategy2",
        "match": ("h_i",),
        "columns": {"tf": {"label": "tf", "rtol": 5.0e-3}, "objective": {"label": "m(tf)", "tol": 0.1}},
        "rows": [{"h_i": h, "paper": {"tf": t, "objective": m}, "source": "seed 2, Table 2",
                  **({"wrong": _T2, "wrong_columns": ["tf"]} if h == 100 else {})}
                 for h, t, m in ((100, 1036.458, 149.932), (50, 1012.252, 152.384), (25, 1001.326, 153.395),
                                 (20, 999.288, 153.575), (15, 997.303, 153.747), (10, 995.371, 153.911),
                                 (5, 993.586, 154.053))],
    },
    "seed2_strategy3": {
        "label": "seed2_strategy3",
        "match": ("h_v",),
        "columns": {"tf.descent": {"label": "tf (braking + vertical descent)", "rtol": 5.0e-3},
                    "objective": {"label": "m(tf)", "tol": 0.1}},
        "rows": [{"h_v": h, "paper": {"tf.descent": round(tb + tv, 3), "objective": m},
                  "source": "seed 2, Table 3 (braking + vertical-descent time)",
                  **({"wrong": _T3} if h != 2 else {})}
                 for h, tb, tv, m in ((5, 959.520, 83.436, 147.140), (4, 963.165, 72.497, 148.195),
                                      (3, 967.450, 61.752, 149.130), (2, 974.204, 46.391, 150.376),
                                      (1, 983.827, 27.584, 151.705))],
    },
}

#: The index's verdicts of a row with a paper value, and of a row with another reference.
REPRODUCED, SHOWN_WRONG, NOT_REPRODUCED = "reproduced", "paper value shown wrong", "not reproduced"
AGREES, DIFFERS = "agrees", "differs"


# ================================================================================ configs
@dataclass
class Example:
    path: Path
    kind: str            # "problem" | "controller" | "pareto" | "study"
    slow: bool
    name: str = ""
    after: tuple[str, ...] = ()   # the examples whose solutions its guess comes from (ocdsl/chain)

    @property
    def stem(self) -> str:
        return self.path.stem


@dataclass
class Outcome:
    stem: str
    kind: str
    status: str                         # status of the run, "study", or "error"
    ok: bool
    seconds: float
    files: list[Path] = field(default_factory=list)
    message: str = ""


def classify(path: Path, _seen: tuple[str, ...] = ()) -> Example:
    """Kind of a configuration file (from its top-level blocks) and whether it is slow."""
    from ocdsl.spec.loader import load_yaml

    text = path.read_text()
    data = load_yaml(path).data
    if "pareto" in data:
        kind = "pareto"
    elif "study" in data:
        kind = "study"
    elif "controller" in data:
        kind = "controller"
    else:
        kind = "problem"
    slow = path.stem in SLOW or path.stem.startswith(SLOW_PREFIXES) or bool(SLOW_MARK.search(text))
    after = tuple(p.stem for p in sources_of(path) if p.resolve().parent == path.resolve().parent)
    # a chain runs its sources first when their runs under reports/ are not current
    slow = slow or any(classify(path.with_name(a + ".yaml"), _seen + (path.stem,)).slow for a in after
                       if path.with_name(a + ".yaml").is_file() and a not in _seen)
    return Example(path, kind, slow, str(data.get("name") or path.stem), after)


def find_examples(configs: Path = CONFIGS, only: Sequence[str] | None = None,
                  skip_slow: bool = False) -> list[Example]:
    """The examples of ``configs`` (``*.yaml``, sorted), restricted to ``only`` (stems or
    file names) and without the slow ones when ``skip_slow``."""
    files = sorted(Path(configs).glob("*.yaml"))
    if only:
        wanted = {Path(o).stem for o in only}
        unknown = wanted - {f.stem for f in files}
        if unknown:
            raise SystemExit(f"reproduce: no such example in {configs}: {', '.join(sorted(unknown))}")
        files = [f for f in files if f.stem in wanted]
    out = _sources_first([classify(f) for f in files])
    return [e for e in out if not (skip_slow and e.slow)]


def _sources_first(examples: list[Example]) -> list[Example]:
    """``examples`` in their order, each moved after the examples its guess comes from (so
    a chain reuses their fresh run folders instead of solving them again)."""
    by_stem = {e.stem: e for e in examples}
    done: dict[str, Example] = {}

    def place(e: Example, seen: tuple = ()) -> None:
        if e.stem in done or e.stem in seen:      # cycles are refused by `ocdsl check`
            return
        for a in e.after:
            if a in by_stem:
                place(by_stem[a], seen + (e.stem,))
        done[e.stem] = e
    for e in examples:
        place(e)
    return list(done.values())


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


def _update_verdicts(reports: Path, outcomes: Sequence[Outcome]) -> None:
    """The manifest keeps when each example was run; its status and ok follow the run
    folder as the current ocdsl reads it."""
    path = Path(reports) / "reproduce.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        data = {}
    for o in outcomes:
        if o.stem in data and o.status != "error":
            data[o.stem].update({"ok": o.ok, "report_made": time.strftime("%Y-%m-%dT%H:%M:%S"),
                                 "report_commit": _git_commit()})
            if o.kind == "run":
                data[o.stem]["status"] = o.status
    path.write_text(json.dumps(dict(sorted(data.items())), indent=1) + "\n")


# ================================================================================= index
def _band(c: dict) -> float:
    ref = c.get("reference")
    try:
        ref = abs(float(ref))
    except (TypeError, ValueError):
        return 0.0
    return max((c.get("rtol") or 0.0) * ref, c.get("atol") or 0.0)


def verdict_of(kind: str, passed: bool | None, compare: str, value: Any, reference: Any, band: float,
               wrong: str | None) -> str:
    """The index's verdict of one row (see :data:`REFERENCES`)."""
    if kind != "paper":
        return AGREES if passed else DIFFERS
    beyond = False      # an at_most/at_least bound met with room to spare: a better optimum
    try:
        v, r = float(value), float(reference)
        beyond = (compare == "at_most" and v < r - band) or (compare == "at_least" and v > r + band)
    except (TypeError, ValueError):
        pass
    if wrong and value is not None and (not passed or beyond):     # no value: nothing shown
        return SHOWN_WRONG
    return REPRODUCED if passed else NOT_REPRODUCED


def _row(study: str, quantity: str, ref: dict[str, str], reference: Any, value: Any, error: Any, passed: Any,
         compare: str, tolerance: str, verification: str | None, link: Path, band: float = 0.0,
         mode: str = "equal") -> dict[str, Any]:
    kind = ref.get("kind", "other")
    wrong = ref.get("wrong")
    verdict = verdict_of(kind, passed, mode, value, reference, band, wrong)
    return {"study": study, "quantity": quantity, "kind": kind, "source": ref.get("source", ""),
            "paper": reference if kind == "paper" else None, "other": reference if kind != "paper" else None,
            "ocdsl": value, "error": error, "passed": passed, "compare": compare, "tolerance": tolerance,
            "verification": verification, "verdict": verdict, "test": wrong if verdict == SHOWN_WRONG else None,
            "report_link": link}


def expect_numbers(run_dir: Path, study: str, link: Path) -> list[dict[str, Any]]:
    """Rows of the index for the ``expect`` checks of one run folder (and its
    :data:`PRINTED_EXTRA` values)."""
    from ocdsl.report.tables import compare_text, tolerance_text

    try:
        data = json.loads((Path(run_dir) / "result.json").read_text())
    except (OSError, ValueError):
        return []
    ver = (data.get("verification") or {}).get("status") if isinstance(data.get("verification"), dict) else None
    if ver is None:             # a Pareto set: its points' verdict
        from ocdsl.report.build import points_verification
        ver = (points_verification(Path(run_dir)) or {}).get("status")
    rows = []
    for c in data.get("expect") or []:
        paper, value = c.get("reference"), c.get("value")
        if isinstance(paper, (list, tuple)):
            paper = ", ".join(map(str, paper))
        if isinstance(value, (list, tuple)):
            value = ", ".join(map(str, value))
        name = str(c.get("name", ""))
        ref = REFERENCES.get((study, name), {"kind": "other", "source": "the file's expect value"})
        exact = not (c.get("rtol") or c.get("atol")) and (c.get("compare") or "equal") == "equal"
        rows.append(_row(study, name, ref, paper, value, c.get("error"), c.get("passed"),
                         "exact" if exact else compare_text(c), "—" if exact else tolerance_text(c), ver, link,
                         _band(c), c.get("compare") or "equal"))
    for extra in PRINTED_EXTRA.get(study, []):
        value = data.get(extra["column"])
        value = value if isinstance(value, (int, float)) else None
        paper = float(extra["paper"])
        band = extra.get("tol", 0.0) or extra.get("rtol", 0.0) * abs(paper)
        err = None if value is None else abs(value - paper)
        passed = err is not None and err <= band
        tol = f"rtol {extra['rtol']:g}" if "rtol" in extra else f"atol {extra['tol']:g}"
        rows.append(_row(study, extra["quantity"], {"kind": "paper", "source": extra["source"],
                                                    "wrong": extra.get("wrong")},
                         paper, value, err, passed, "|error| ≤ tol", tol, ver, link, band))
    return rows


def _column(row: dict[str, Any], col: str) -> float | None:
    """``col`` of a study row; ``tf.<phase>`` reads that phase's entry of a per-phase tf."""
    from ocdsl.report.tables import finite_or_none

    if "." in col:
        base, key = col.split(".", 1)
        v = row.get(base)
        if isinstance(v, str):
            try:
                v = json.loads(v)
            except ValueError:
                return None
        return finite_or_none(v.get(key)) if isinstance(v, dict) else None
    return finite_or_none(row.get(col))


def study_paper_numbers(folder: Path, stem: str, link: Path | None = None) -> list[dict[str, Any]]:
    """Rows of the index for a study folder: its :data:`PAPER_TABLES` entry against
    ``study.csv`` (a paper row without a study row counts as not reproduced)."""
    from ocdsl.report.build import read_study_table
    from ocdsl.report.tables import finite_or_none

    spec = PAPER_TABLES.get(stem)
    if not spec:
        return []
    rows, _ = read_study_table(Path(folder))
    out = []
    for ref in spec["rows"]:
        key = tuple(ref[k] for k in spec["match"])
        hit = next((r for r in rows if all(finite_or_none(r.get(k)) == float(v) for k, v in zip(spec["match"], key))), None)
        where = ", ".join(f"{k} = {v:g}" for k, v in zip(spec["match"], key))
        ver = str(hit.get("verification")) if hit and hit.get("verification") not in (None, "") else None
        for col, printed in ref["paper"].items():
            cs = spec["columns"][col]
            value = _column(hit, col) if hit and hit.get("status") in GOOD else None
            paper = float(printed)
            tol = cs.get("tol", 0.0) or cs.get("rtol", 0.0) * abs(paper)
            if value is None:
                err, passed = None, False
            else:
                err = value - paper
                passed = err <= tol if ref.get("at_most") else abs(err) <= tol
            wrong = ref.get("wrong") if col in ref.get("wrong_columns", [col]) else None
            out.append(_row(spec.get("label", stem), f"{cs['label']} at {where}",
                            {"kind": "paper", "source": ref.get("source", ""), "wrong": wrong},
                            paper, value, None if err is None else abs(err), passed,
                            "ocdsl ≤ ref + tol" if ref.get("at_most") else "|error| ≤ tol",
                            f"rtol {cs['rtol']:g}" if "rtol" in cs else f"atol {cs.get('tol', 0):g}", ver,
                            link or Path(folder) / "report.html", tol, "at_most" if ref.get("at_most") else "equal"))
    return out


def report_folders(reports: Path) -> list[Path]:
    """Report folders directly under ``reports`` (run, Pareto and study folders with a report)."""
    return sorted(d for d in Path(reports).iterdir()
                  if d.is_dir() and not d.name.startswith(".")
                  and ((d / "report.html").is_file() or (d / "report.pdf").is_file()))


def paper_numbers(reports: Path) -> list[dict[str, Any]]:
    """Every paper number of every report folder under ``reports``."""
    out: list[dict[str, Any]] = []
    for d in report_folders(reports):
        link = d / "report.html" if (d / "report.html").is_file() else d / "report.pdf"
        if (d / "result.json").is_file():
            out += expect_numbers(d, d.name, link)
        elif (d / "study.csv").is_file() or (d / "study.json").is_file():
            out += study_paper_numbers(d, d.name, link)
            points = d / "points"
            if points.is_dir() and d.name not in PAPER_TABLES:   # else the table's rows stand for them
                for p in sorted(points.iterdir()):
                    if (p / "result.json").is_file():
                        out += expect_numbers(p, f"{d.name}/{p.name}", link)
    return out


def write_index(reports: Path = REPORTS) -> Path:
    from ocdsl.report.build import make_index

    reports = Path(reports)
    return make_index(report_folders(reports), reports / "index.html", paper_numbers(reports),
                      title="ocdsl: reproductions of the examples and papers")


# =================================================================================== CLI
def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ocdsl.report.reproduce",
                                 description="Run every example of configs/ and write its reports under reports/.")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="only these examples (file stems)")
    ap.add_argument("--skip-slow", action="store_true", help="leave out the examples that take minutes")
    ap.add_argument("--formats", default="html,pdf", help="comma-separated: html, pdf (default html,pdf)")
    ap.add_argument("--configs", type=Path, default=CONFIGS, help="folder of the examples (default configs/)")
    ap.add_argument("--out", type=Path, default=REPORTS, help="reports folder (default reports/)")
    ap.add_argument("--workers", type=int, default=None, help="worker processes of study files")
    ap.add_argument("--index-only", action="store_true", help="only rewrite reports/index.html")
    ap.add_argument("--reports-only", action="store_true",
                    help="re-make the reports of the run folders under --out from what they hold (no solving)")
    ap.add_argument("--list", action="store_true", help="list the examples and exit")
    args = ap.parse_args(argv)
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in ("html", "pdf")]
    if bad:
        ap.error(f"unknown format(s) {bad}; choose from html, pdf")
    if args.index_only:
        print(f"[reproduce] wrote {write_index(args.out)}")
        return 0
    if args.reports_only:
        outcomes = remake_reports(args.out, formats, only=args.only, configs=args.configs)
        bad_runs = [o.stem for o in outcomes if not o.ok]
        print(f"[reproduce] {len(outcomes) - len(bad_runs)} of {len(outcomes)} reports of ok runs"
              + (f"; not ok: {', '.join(bad_runs)}" if bad_runs else ""))
        return 1 if any(o.status == "error" for o in outcomes) else 0
    examples = find_examples(args.configs, args.only, args.skip_slow)
    if args.list:
        for e in examples:
            print(f"{e.stem:28s} {e.kind:10s} {'slow' if e.slow else ''}")
        return 0
    os.environ.setdefault("MPLBACKEND", "Agg")
    outcomes = reproduce(examples, args.out, formats, workers=args.workers)
    bad_runs = [o.stem for o in outcomes if not o.ok]
    print(f"[reproduce] {len(outcomes) - len(bad_runs)} of {len(outcomes)} examples ok"
          + (f"; not ok: {', '.join(bad_runs)}" if bad_runs else ""))
    return 1 if bad_runs else 0


if __name__ == "__main__":
    sys.exit(main())
