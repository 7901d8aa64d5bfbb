"""The report comparing several runs or whole studies (sweeps, Pareto sets)."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ocdsl.result import Result
from ocdsl.report import figures as F
from ocdsl.report import status as S
from ocdsl.report import tables as T
from ocdsl.report.build.document import Doc, NotARunFolder, ReportError, _append
from ocdsl.report.build.loading import GOOD, _find_runs, _is_run, load_run, read_study_table
from ocdsl.report.build.output import _render, _write_outputs
from ocdsl.report.build.pareto import STUDY_OUTPUT_COLS, pareto_criteria, pareto_senses
from ocdsl.report.build.run import _problem_section


def build_comparison_html(run_dirs: Sequence[str | os.PathLike], title: str | None = None) -> str:
    return _build_comparison(run_dirs, title)[0]


def _build_comparison(run_dirs: Sequence[str | os.PathLike], title: str | None = None) -> tuple[str, dict[str, bytes]]:
    entries: list[tuple[str, Path]] = []       # (label, run folder)
    studies: list[tuple[Path, list[dict], dict]] = []
    for d in [Path(x) for x in ([run_dirs] if isinstance(run_dirs, (str, os.PathLike)) else run_dirs)]:
        if _is_run(d):
            entries.append((d.name, d))
        elif d.is_dir():
            rows, meta = read_study_table(d)
            runs = _find_runs(d)
            if not runs and not rows:
                raise NotARunFolder(f"{d}: neither a run folder nor a study folder (no result.json, no run folders)")
            studies.append((d, rows, meta))
            entries += [(str(r.relative_to(d)) if len(run_dirs) == 1 else f"{d.name}/{r.relative_to(d)}", r)
                        for r in runs]
        else:
            raise ReportError(f"{d}: no such folder")
    results, labels, notes = [], [], []
    for lab, d in entries:
        try:
            r, n = load_run(d)
        except ReportError as exc:
            notes.append(str(exc))
            continue
        results.append(r)
        labels.append(lab)
        notes += [f"{lab}: {x}" for x in n]
    doc = Doc()
    doc.warnings += notes
    for folder, rows, meta in studies:
        _study_section(doc, folder, rows, meta, results)
    if results:
        b = doc.section("runs", "Runs compared")
        doc.table(b, doc.guard("runs table", lambda: T.runs_table(results, labels)))
        doc.table(b, doc.guard("expect table", lambda: T.expect_comparison_table(results, labels)))
        for lab, r in zip(labels, results):
            if r.status not in GOOD and r.message:
                b.append({"type": "note", "text": f"{lab} ({r.status}): {r.message}"})
            elif not r.ok:
                # why it is not ok (a failed expect check, the verification, the certificate), not
                # the verification's summary whatever the reason (unseen43 F12)
                summary = (r.verification or {}).get("summary") if not r.verification_ok else None
                b.append({"type": "note", "text": f"{lab} ({r.status}, not ok): {S.overall(r).title}"
                                                  + (f" ({summary})" if summary else "")})
        # a controller file's phases are its laws' closed loops: drawn in the closed-loop
        # comparison, each law named (unseen35 F8: legends "r02, r02, r02b, r02b")
        shown = [(lab, r) for lab, r in zip(labels, results)
                 if r.phases and not isinstance((r.extra or {}).get("laws"), list)][:40]
        if shown:
            for lab, r in shown:
                # the legend says which lines are no solution (unseen33 F4: a max_iter run's last
                # iterate drawn like the solutions)
                r.name = lab + ("" if r.ok else " (last iterate)" if r.status not in GOOD else " (not ok)")
            doc.guard("comparison figures", lambda: doc.figures(b, F.fig_compare_runs([r for _, r in shown])))
            if len(shown) < sum(bool(r.phases) for r in results):
                b.append({"type": "note", "text": f"Figures show the first {len(shown)} runs with a trajectory."})
        merged: dict[str, dict[str, np.ndarray]] = {}
        for lab, r in zip(labels, results):
            for k, v in F.closed_loop_tables(r.tables).items():
                merged[f"closed_loop_{k if len(results) == 1 else lab + ':' + k}"] = v
        if merged:
            prob = next((r.problem for r in results if r.problem), {})
            b2 = doc.section("closed-loop", "Closed-loop comparison")
            doc.table(b2, doc.guard("closed-loop table", lambda: T.closed_loop_table(merged, prob)))
            doc.guard("closed-loop figures", lambda: doc.figures(b2, F.fig_closed_loop(merged, prob)))
        names = {(r.problem or {}).get("name") for r in results}
        if len(names) == 1 and results[0].problem:
            sub = Doc()
            _problem_section(sub, results[0])
            _append(doc, sub, "Problem (common to the runs; values of the first run)")
    if not title:
        inputs = [Path(x).name for x in ([run_dirs] if isinstance(run_dirs, (str, os.PathLike)) else run_dirs)]
        if studies and len(inputs) == 1:
            title = f"Study {studies[0][0].name}"
        else:
            title = "Comparison of " + ", ".join(inputs[:5]) + (f" and {len(inputs) - 5} more" if len(inputs) > 5 else "")
    return _render(doc, title, "", [("runs", str(len(results)))], study_badges(results)), doc.files


def study_badges(results: Sequence[Result]) -> list[S.Badge]:
    """A comparison's badges: how many runs converged, were verified and are ok."""
    n = len(results)
    if not n:
        return [S.Badge("runs", "none", "fail")]
    conv = sum(r.status in GOOD for r in results)
    ver = sum(r.verified or (r.verification or {}).get("status") == "not_applicable" for r in results)
    ok = sum(r.ok for r in results)
    out = [S.Badge("solver", f"{conv} of {n} converged", "pass" if conv == n else "fail"),
           S.Badge("verification", f"{ver} of {n} verified", "pass" if ver == n else "fail")]
    certs = [S.certificate_passed(r.certificate) for r in results if r.certificate]
    if certs:
        out.append(S.Badge("certificate", f"{sum(c is True for c in certs)} of {len(certs)} pass",
                           "pass" if all(c is True for c in certs) else "fail"))
    out.append(S.Badge("overall", f"{ok} of {n} ok", "pass" if ok == n else "fail"))
    return out

def swept_parameters(meta: dict) -> tuple[list[str], str]:
    """The parameters a study sweeps, from ``study.json``'s spec (``sweep: {grid | zip |
    list | random ...: {name: ...}}``), and how: ``zip`` moves its parameters together (a
    one-dimensional sweep along the first). Empty when the spec names none."""
    spec = meta.get("spec")
    if isinstance(spec, str):
        return [], ""
    sweep = (spec or {}).get("sweep") if isinstance(spec, dict) else None
    if not isinstance(sweep, dict):
        return [], ""
    for how, body in sweep.items():
        if isinstance(body, dict) and body:
            return [str(k) for k in body], str(how)
    return [], ""


#: study.csv columns that are bookkeeping, not results: left out of the study table
STUDY_BOOKKEEPING = ("sweep", "host", "warm_start", "seed", "message", "worker", "client_host")


def study_columns(rows: list[dict], swept: Sequence[str]) -> dict[str, list]:
    """study.csv as columns for reading: the swept parameters first, a per-phase ``tf``
    (a JSON object per row) as one column per phase, bookkeeping columns and empty ones
    left out (messages go to notes for the rows that failed)."""
    if not rows:
        return {}
    names = [k for k in rows[0] if k not in STUDY_BOOKKEEPING]
    order = [k for k in swept if k in names] + [k for k in names if k not in swept]
    cols: dict[str, list] = {}
    for k in order:
        vals = [r.get(k) for r in rows]
        parsed = [_json_obj(v) for v in vals]
        if any(isinstance(v, dict) for v in parsed):
            keys: list[str] = []
            for v in parsed:
                keys += [x for x in (v or {}) if x not in keys]
            for x in keys:
                cols[f"{k} ({x})"] = [(v or {}).get(x) for v in parsed]
        elif any(v not in (None, "") for v in vals):
            cols[k] = vals
    return cols


def _json_obj(v: Any) -> Any:
    if isinstance(v, dict):
        return v
    if isinstance(v, str) and v.startswith("{"):
        try:
            return json.loads(v)
        except ValueError:
            return None
    return None


def _study_meta_rows(folder: Path, meta: dict) -> list[list[dict]]:
    """The study definition without machine details: file names, not paths; no host names."""
    rows = []
    for k, v in meta.items():
        if k in ("points", "best", "columns", "client_host", "host", "spec") or isinstance(v, list) and len(v) > 8:
            continue
        if k.endswith("_file") and isinstance(v, str):
            v = Path(v).name
        if isinstance(v, dict):
            v = ", ".join(f"{a} {T.fmt(b)}" for a, b in v.items())
        rows.append([T.cell(k.replace("_", " "), "name"), T.cell(v)])
    swept, how = swept_parameters(meta)
    if swept:
        rows.append([T.cell("swept", "name"), T.cell(f"{', '.join(swept)} ({how})")])
    return rows


def _study_section(doc: Doc, folder: Path, rows: list[dict], meta: dict, results: list[Result]) -> None:
    b = doc.section(f"study-{folder.name}", f"Study {meta.get('name') or folder.name}")
    mrows = _study_meta_rows(folder, meta)
    if mrows:
        doc.table(b, T.table("study-meta", "Study definition (study.json).", ["item", "value"], mrows))
    swept, how = swept_parameters(meta)
    if rows:
        cols = study_columns(rows, swept)
        if "objective" in cols and "status" in cols:
            # a failed solve's J is its last iterate's (unseen33 F4: printed like a solution's)
            cols["objective"] = [v if str(st) in GOOD or T.finite_or_none(v) is None
                                 else f"{T.fmt(float(v), 8)} (last iterate)"
                                 for v, st in zip(cols["objective"], cols["status"])]
        doc.table(b, doc.guard("study table", lambda: T.column_table(
            f"study-{folder.name}", "Study table (study.csv), one row per point; the message is given "
            "below for the points that are not ok.", cols, max_rows=60, drop_constant=True)))
        for r in rows:
            if (str(r.get("status")) not in GOOD or not T.truthy(r.get("ok", True))) and r.get("message"):
                b.append({"type": "note", "text": f"{r.get('id', '?')} ({r.get('status')}): "
                                                  f"{str(r['message']).splitlines()[0][:300]}"})
        if any("pareto" in r for r in rows):
            crit = pareto_criteria(rows, meta)
            if crit:
                units = next((r.problem.get("units") for r in results if r.problem), {})
                doc.guard("Pareto figure", lambda: doc.figures(b, F.fig_pareto(
                    rows, crit, units, senses=pareto_senses(crit, meta))))
            else:
                b.append({"type": "note", "text": "The study has Pareto flags but its two criteria could "
                                                  "not be identified (name them in study.json: criteria)."})
            return
        units = next((r.problem.get("units") for r in results if r.problem), {})
        maximize = next((((r.problem or {}).get("objective") or {}).get("sense") == "maximize"
                         for r in results if r.problem), False)
        outputs = [c for c in cols if c == "objective" or c == "tf" or c.startswith("tf (")]
        one_d = bool(swept) and (len(swept) == 1 or how == "zip")
        if not swept:   # no declared sweep: a single varying input column is one
            varying = [k for k in cols if k not in STUDY_OUTPUT_COLS and k not in outputs
                       and all(isinstance(r.get(k), (int, float)) for r in rows) and len({r.get(k) for r in rows}) > 1]
            if len(varying) == 1:
                swept, one_d = varying, True
        if one_d:
            doc.guard("sweep figure", lambda: doc.figures(b, F.fig_sweep(
                [dict(zip(cols, vals)) for vals in zip(*cols.values())], swept[0], outputs, units,
                objective_label="objective (maximize)" if maximize else "objective")))
        elif len(rows) >= 8:
            doc.guard("histograms", lambda: doc.figures(b, F.fig_histograms(rows, [o for o in outputs if o in rows[0]][:2])))


def make_comparison_report(run_dirs: Sequence[str | os.PathLike] | str | os.PathLike,
                           out_dir: str | os.PathLike, formats: Sequence[str] = ("html", "pdf"), *,
                           title: str | None = None, engine: str = "auto") -> list[Path]:
    """Write one report comparing several runs and/or whole studies.

    ``run_dirs``: run folders, study folders (``study.csv``/``study.json`` with one run
    folder per point, or any folder holding run folders), or a single such folder. Writes
    ``out_dir/report.html`` and ``out_dir/report.pdf`` (per ``formats``) and returns the
    written paths. Contents: the study tables (with the Pareto front or the sweep figure
    when the study has one), a per-run comparison table, every run's expect checks, states
    and controls of all runs overlaid, closed-loop comparisons, and the common problem.
    """
    html, files = _build_comparison(run_dirs, title)
    return _write_outputs(html, Path(out_dir), formats, engine, files=files)
