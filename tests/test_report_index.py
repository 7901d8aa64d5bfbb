"""The reproduction index is honest (issue 24 item 5): its "paper" column holds only values
printed in the papers, other references sit in their own labelled column, every row shows
its comparison and tolerance, and rows count as reproduced / paper value shown wrong (with
its test) / not reproduced."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from ocdsl.report import reproduce as R

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"

#: The values the papers print, as the seed digests (/work/shared/seeds/seed_00*.md) give them.
PRINTED = {
    # seed 0 (Mousavi et al. 2022): main t_f (§5.1) and Table 4's GPM column
    "seed0": [25.8727, 26.1674, 25.9360, 25.6607, 28.7185],
    # seed 1 (Daneshjou & Mohammadi Dehabadi 2023): Table 5 (10 N: present method, the
    # OCR-reconstructed 1.8265, and reference [36] 1.8065), Table 6 (5 N 3.02396, 2 N 6.8730)
    # and the digest's rounding of them in its checks (3.024, 6.873)
    "seed1": [1.8265, 1.8065, 3.02396, 6.8730, 3.024, 6.873],
    # seed 2: Table 2 (time, final mass per altitude) and Table 3 (braking + vertical-descent
    # times, final mass)
    "seed2": [1036.458, 1012.252, 1001.326, 999.288, 997.303, 995.371, 993.586,
              149.932, 152.384, 153.395, 153.575, 153.747, 153.911, 154.053,
              959.520 + 83.436, 963.165 + 72.497, 967.450 + 61.752, 974.204 + 46.391, 983.827 + 27.584,
              147.140, 148.195, 149.130, 150.376, 151.705],
    # seed 3 prints no number; seed 4's results (Table 1) are lost
    "seed3": [], "seed4": [],
}


def _seed(study: str) -> str | None:
    m = re.match(r"(seed\d)", study) or re.match(r"Seed (\d)", study)
    return ("seed" + m.group(1)[-1]) if m else None


@pytest.fixture(scope="module")
def rows() -> list[dict]:
    out = R.paper_numbers(REPORTS)
    assert out, "no index rows: reports/ holds no report folders"
    return out


def test_paper_column_holds_only_printed_values(rows):
    paper_rows = [r for r in rows if r["paper"] is not None]
    assert paper_rows
    for r in paper_rows:
        seed = _seed(r["study"])
        assert seed in PRINTED, (r["study"], r["quantity"], "a paper value outside the reproduced papers")
        assert any(abs(float(r["paper"]) - v) <= 1e-9 * abs(v) for v in PRINTED[seed]), \
            (r["study"], r["quantity"], r["paper"], "not a printed value")
        assert re.search(r"Table \d|eq\. ?\(\d+\)|§\d", r["source"]), (r["study"], r["source"])


def test_other_references_are_labelled_and_not_in_the_paper_column(rows):
    other = [r for r in rows if r["paper"] is None]
    assert other and all(r["other"] is not None and r["source"] and r["kind"] != "paper" for r in other)
    # the digest's synthetic cases and derived values are never "paper"
    for r in rows:
        if r["study"].startswith("seed4") or r["study"] == "seed0_exact_euler":
            assert r["paper"] is None and r["kind"] == "digest", r
    derived = [r for r in rows if r["study"] == "seed2_strategy1" and r["quantity"] == "tf"]
    assert {r["kind"] for r in derived} == {"paper", "computed"}
    assert [r["paper"] for r in derived if r["kind"] == "paper"] == [1036.458]


def test_every_row_has_comparison_tolerance_and_verdict(rows):
    for r in rows:
        assert r["compare"] and r["tolerance"], r
        assert r["verdict"] in (R.REPRODUCED, R.SHOWN_WRONG, R.BETTER, R.NOT_REPRODUCED, R.AGREES, R.DIFFERS)
        if r["verdict"] in (R.SHOWN_WRONG, R.BETTER):
            path, _, name = r["test"].partition("::")
            assert (ROOT / path).is_file() and f"def {name}(" in (ROOT / path).read_text(), r["test"]


def test_a_better_optimum_under_at_most_is_not_called_reproduced():
    """seed 1's optimal mode: 1.5448 under 'at most 1.8065' is a 26 % better optimum, which
    beats the paper's search, not a printed number (it was "paper value shown wrong": unseen51
    F5, the Fourier-series times are a restricted class's optimum)."""
    v = R.verdict_of("paper", True, "at_most", 1.5448, 1.8065, 0.0, "tests/x.py::t")
    assert v == R.BETTER
    assert R.verdict_of("paper", True, "at_most", 1.8065, 1.8065, 1e-4, "tests/x.py::t") == R.REPRODUCED
    assert R.verdict_of("paper", False, "equal", 2.0, 1.0, 0.1, None) == R.NOT_REPRODUCED
    assert R.verdict_of("paper", False, "equal", 2.0, 1.0, 0.1, "tests/x.py::t") == R.SHOWN_WRONG
    assert R.verdict_of("digest", True, "equal", 1.0, 1.0, 0.1, None) == R.AGREES


def test_index_page_counts_and_columns(tmp_path, rows):
    from ocdsl.report.build import make_index

    out = make_index(R.report_folders(REPORTS), tmp_path / "index.html", rows)
    html = out.read_text()
    head = html[:html.index("</header>")]
    n_paper = sum(r["paper"] is not None for r in rows)
    assert f"paper values: {n_paper}" in head
    for k in (R.REPRODUCED, R.SHOWN_WRONG, R.NOT_REPRODUCED):
        n = sum(r["verdict"] == k for r in rows if r["paper"] is not None)
        assert re.search(rf"{k} <span class=\"badge \w+\">{n}</span>", head), k
    assert re.search(r"<th>paper</th><th>other reference</th><th>source</th>.*<th>comparison \(tolerance\)</th>"
                     r"<th>verification</th><th>verdict</th>", html)
    assert html.count("<tr><td class=\"name\">") == len(rows)
    # every report folder is listed with a title and badges (studies too)
    listed = re.findall(r'<li><a href="[^"]+">([^<]+)</a>(.*?)</li>', html)
    assert len(listed) == len(R.report_folders(REPORTS))
    assert all(title.strip() and 'class="badge' in rest for title, rest in listed)


def test_reports_only_keeps_a_report_whose_run_data_is_not_here(tmp_path):
    """A committed run folder holds no trajectory (.gitignore): --reports-only keeps its
    report as it is and says to re-run it, instead of writing one without figures."""
    import numpy as np

    from ocdsl.report import make_report
    from ocdsl.result import PhaseTrajectory, Result

    t = np.linspace(0.0, 1.0, 11)
    res = Result(name="run", status="optimal", problem={"name": "run"},
                 phases=[PhaseTrajectory("main", t, {"x": t})])
    folder = res.write(tmp_path / "reports" / "run")
    make_report(folder, ("html",))
    before = (folder / "report.html").read_bytes()
    for f in folder.glob("trajectory*.csv"):
        f.unlink()
    out = R.remake_reports(tmp_path / "reports", ("html",), log=lambda *_: None)
    assert [(o.stem, o.status) for o in out] == [("run", "skipped")] and "--only run" in out[0].message
    assert (folder / "report.html").read_bytes() == before


def test_a_printed_row_shown_wrong_is_not_reproduced_in_another_column(tmp_path):
    """unseen51 F9: Table 3's 4 km row, time within 0.5 % of the printed one (3.9 s off) but
    mass 0.57 kg off: the time was "reproduced" beside the mass "paper value shown wrong",
    though m_f = m_entry - mdot t ties the two. A row whose printed values are shown wrong as
    a whole is shown wrong in every column."""
    import csv
    import json

    from ocdsl.report.reproduce.numbers import study_paper_numbers
    from ocdsl.report.reproduce.references import SHOWN_WRONG

    with open(tmp_path / "study.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, ["id", "h_v", "status", "objective", "tf"])
        w.writeheader()
        w.writerow({"id": "p0001", "h_v": 4, "status": "optimal", "objective": 148.764,
                    "tf": json.dumps({"braking": 955.942, "descent": 1031.730})})
    rows = study_paper_numbers(tmp_path, "seed2_strategy3")
    four = [r for r in rows if "h_v = 4" in r["quantity"]]
    assert len(four) == 2 and all(r["verdict"] == SHOWN_WRONG for r in four), four
    assert all(r["test"] == "tests/test_lander.py::test_strategy3_printed_descents_cannot_land" for r in four)
