"""``reports/index.html``: every reference number against ocdsl's, and every report with
its badges."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Sequence

from ocdsl.report import status as S
from ocdsl.report import tables as T
from ocdsl.report.build.loading import GOOD, _is_run, load_run, read_study_table
from ocdsl.report.build.output import _atomic_write, _env


def make_index(report_dirs: Sequence[str | os.PathLike], out_path: str | os.PathLike,
               paper_numbers: Sequence[dict[str, Any]], *, title: str = "ocdsl reproductions") -> Path:
    """Write ``out_path`` (e.g. ``reports/index.html``): a table of every reference number
    against ocdsl's and a list of links to the reports in ``report_dirs`` with their badges.

    ``paper_numbers``: dicts as :func:`ocdsl.report.reproduce.expect_numbers` makes them
    (``study, quantity, paper`` (printed in the paper) or ``other`` (another reference, with
    ``source``), ``ocdsl, error, compare, tolerance, verification, verdict, test,
    report_link``); ``report_link`` (a path to a report file or folder) is made relative to
    the index. Links are relative, so the folder can be moved or published as is.
    """
    from ocdsl.report import reproduce as R

    out_path = Path(out_path)
    base = out_path.parent.resolve()

    def rel(p: Any) -> str | None:
        if not p:
            return None
        p = Path(p)
        if p.is_dir() or (not p.suffix and not p.exists()):
            p = p / "report.html"
        p = p if p.is_absolute() else (Path.cwd() / p)
        return os.path.relpath(p.resolve(), base).replace(os.sep, "/")

    vcls = {"verified": "pass", "failed": "fail", "error": "fail"}
    dcls = {R.REPRODUCED: "pass", R.AGREES: "pass", R.SHOWN_WRONG: "warn", R.BETTER: "warn", R.NOT_REPRODUCED: "fail",
            R.DIFFERS: "fail"}
    numbers = []
    for r in paper_numbers:
        verdict = r.get("verdict") or (R.REPRODUCED if r.get("passed") else R.NOT_REPRODUCED)
        ver = r.get("verification")
        numbers.append({"study": r.get("study", ""), "quantity": r.get("quantity", ""),
                        "paper": T.fmt(r.get("paper"), 8) if r.get("paper") is not None else "",
                        "other": T.fmt(r.get("other"), 8) if r.get("other") is not None else "",
                        "source": r.get("source", ""), "kind": r.get("kind", ""),
                        "ocdsl": T.fmt(r.get("ocdsl"), 8), "error": T.fmt(r.get("error"), 3),
                        "list": any(isinstance(r.get(k), str) and "," in r.get(k) for k in ("ocdsl", "paper", "other")),
                        "compare": r.get("compare", ""), "tolerance": r.get("tolerance", ""),
                        "verification": S.VERIFICATION_TEXT.get(ver, str(ver)), "vcls": vcls.get(ver, ""),
                        "verdict": verdict, "cls": dcls.get(verdict, ""), "test": r.get("test"),
                        "link": rel(r.get("report_link"))})
    reports = []
    for d in report_dirs:
        d = Path(d)
        title_r, marks = d.name, []
        if _is_run(d):
            try:
                res, _ = load_run(d)
                title_r = (res.problem or {}).get("name") or res.name or d.name
                marks = S.badges(res)
            except Exception:  # noqa: BLE001
                marks = [S.Badge("result.json", "unreadable", "fail")]
        elif (d / "study.csv").is_file() or (d / "study.json").is_file():
            rows, meta = read_study_table(d)
            title_r = _study_title(d, meta)
            marks = _study_row_badges(rows)
        reports.append({"title": f"{title_r} ({d.name})" if title_r != d.name else title_r,
                        "link": rel(d), "badges": marks})
    paper_rows = [n for n in numbers if n["paper"]]
    other_rows = [n for n in numbers if not n["paper"]]
    counts = {k: sum(n["verdict"] == k for n in paper_rows)
              for k in (R.REPRODUCED, R.SHOWN_WRONG, R.BETTER, R.NOT_REPRODUCED)}
    counts_other = {k: sum(n["verdict"] == k for n in other_rows) for k in (R.AGREES, R.DIFFERS)}
    verified = sum(n["verdict"] == R.REPRODUCED and n["verification"] == "verified" for n in paper_rows)
    html = _env().get_template("index.html.j2").render(
        title=title, numbers=numbers, reports=reports, counts=counts, counts_other=counts_other,
        n_paper=len(paper_rows), n_other=len(other_rows), n_verified=verified, build=S.ocdsl_build())
    _atomic_write(out_path, html)
    return out_path


def _study_title(folder: Path, meta: dict) -> str:
    for key in ("title", "name"):
        if isinstance(meta.get(key), str) and meta[key]:
            return meta[key]
    plan = folder / "plan.json"
    if plan.is_file():
        try:
            p = json.loads(plan.read_text())
            if isinstance(p, dict) and isinstance(p.get("name"), str):
                return p["name"]
        except ValueError:
            pass
    return folder.name


def _study_row_badges(rows: list[dict]) -> list[S.Badge]:
    """A study's badges from study.csv: points converged, verified, and ok."""
    n = len(rows)
    if not n:
        return [S.Badge("points", "none", "fail")]
    conv = sum(str(r.get("status")) in GOOD for r in rows)
    out = [S.Badge("solver", f"{conv} of {n} converged", "pass" if conv == n else "fail")]
    if any("verification" in r for r in rows):
        ver = sum(str(r.get("verification")) in ("verified", "not_applicable") for r in rows)
        out.append(S.Badge("verification", f"{ver} of {n} verified", "pass" if ver == n else "fail"))
    else:
        out.append(S.Badge("verification", "not recorded", "neutral"))
    return out
