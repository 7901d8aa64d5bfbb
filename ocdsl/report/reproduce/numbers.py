"""The rows of ``reports/index.html``: each reference number against ocdsl's value, with
its comparison, tolerance, the run's verification and the verdict."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ocdsl.report.reproduce.examples import GOOD, REPORTS
from ocdsl.report.reproduce.references import (
    AGREES, BETTER, DIFFERS, NOT_REPRODUCED, PAPER_TABLES, PRINTED_EXTRA, REFERENCES, REPRODUCED, SHOWN_WRONG)


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
    if wrong and value is not None and beyond:
        return BETTER
    if wrong and value is not None and not passed:     # no value: nothing shown
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
            "verification": verification, "verdict": verdict,
            "test": wrong if verdict in (SHOWN_WRONG, BETTER) else None,
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
        first = len(out)
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
        row = out[first:]
        if "wrong_columns" not in ref and any(n["verdict"] == SHOWN_WRONG for n in row):
            # a printed row shown wrong as a whole is not reproduced in one of its columns: Table
            # 3's times within 0.5 % were "reproduced" beside their masses "shown wrong", though
            # the mass identity ties the two (a 3.9 s miss is the 0.57 kg one; unseen51 F9)
            for n in row:
                if n["verdict"] == REPRODUCED:
                    n.update(verdict=SHOWN_WRONG, test=n.get("test") or ref.get("wrong"))
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
