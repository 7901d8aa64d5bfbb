"""``python -m ocdsl.report.reproduce`` on a tiny example set (the double integrator, an
infeasible variant with tf <= 1 and a variant stopped after 3 Ipopt iterations), into a
temporary folder: run folders, reports, the index with its expect rows; and the reports of
the two real failed runs show their diagnosis."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from ocdsl import run_folder
from ocdsl.report import build as B
from ocdsl.report import reproduce as R

ROOT = Path(__file__).resolve().parents[1]
DI = ROOT / "configs" / "double_integrator.yaml"
PDFTOTEXT = shutil.which("pdftotext")


def _pdf_engine() -> bool:
    try:
        import weasyprint  # noqa: F401
        return True
    except (ImportError, OSError):
        return B.chromium_binary() is not None


pytestmark = [pytest.mark.ipopt,
              pytest.mark.skipif(not _pdf_engine(), reason="no PDF engine (weasyprint or chromium)")]


def _variant(src: str, name: str, bound: str | None = None, extra: str = "") -> str:
    text = re.sub(r"(?m)^name: .*$", f"name: {name}", src)
    if bound is not None:
        assert "0.1 <= tf <= 10" in text
        text = text.replace("0.1 <= tf <= 10", bound)
    return text + extra


@pytest.fixture(scope="module")
def repro(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("repro")
    cfg = tmp / "configs"
    cfg.mkdir()
    src = DI.read_text()
    (cfg / "double_integrator.yaml").write_text(src)
    (cfg / "di_infeasible.yaml").write_text(_variant(src, "Infeasible double integrator", "0.1 <= tf <= 1"))
    (cfg / "di_max_iter.yaml").write_text(_variant(src, "Double integrator, 3 iterations",
                                                   extra="solver:\n  options: {max_iter: 3}\n"))
    (cfg / "slow_one.yaml").write_text("# reproduce: slow\n" + _variant(src, "Marked slow"))
    out = tmp / "reports"
    (out / "old_example").mkdir(parents=True)      # a report folder from an earlier run
    (out / "old_example" / "report.html").write_text("<html></html>")
    code = R.main(["--configs", str(cfg), "--out", str(out), "--skip-slow", "--formats", "html,pdf"])
    return {"out": out, "code": code, "cfg": cfg}


def test_examples_found_and_classified(repro):
    ex = {e.stem: e for e in R.find_examples(repro["cfg"])}
    assert set(ex) == {"double_integrator", "di_infeasible", "di_max_iter", "slow_one"}
    assert ex["slow_one"].slow and not ex["double_integrator"].slow
    assert {e.kind for e in ex.values()} == {"problem"}
    assert "slow_one" not in {e.stem for e in R.find_examples(repro["cfg"], skip_slow=True)}
    assert [e.stem for e in R.find_examples(repro["cfg"], only=["double_integrator.yaml"])] == ["double_integrator"]
    with pytest.raises(SystemExit):
        R.find_examples(repro["cfg"], only=["nope"])
    real = {e.stem: e for e in R.find_examples(ROOT / "configs")}
    assert real["seed4_case_A"].kind == "pareto" and real["seed0_table4"].kind == "study"
    assert real["seed3_attitude"].kind == "controller" and real["seed1_2N_paper"].slow


def test_run_folders_and_reports(repro):
    out = repro["out"]
    assert repro["code"] == 1                      # two examples fail, on purpose
    assert not (out / "slow_one").exists()          # skipped as slow
    assert not (out / ".new").exists()              # scratch folders cleaned up
    for stem, status in (("double_integrator", "optimal"), ("di_infeasible", "infeasible"),
                         ("di_max_iter", "max_iter")):
        d = out / stem
        data = json.loads((d / "result.json").read_text())
        assert data["status"] == status
        assert (d / "trajectory.csv").is_file() and (d / "problem.yaml").is_file()
        html = (d / "report.html").read_text()
        assert f"<span>run: {stem}</span>" in html
        assert ".new" not in html
        assert (d / "report.pdf").read_bytes()[:5] == b"%PDF-"
    html = (out / "double_integrator" / "report.html").read_text()
    assert len(re.findall(r'<img[^>]+src="data:image/svg\+xml;base64,', html)) >= 6
    # the Hamiltonian and the re-integration, computed from problem.yaml for the report
    assert "Hamiltonian H along the solution" in html and "Re-integrated trajectory" in html
    manifest = json.loads((out / "reproduce.json").read_text())
    assert manifest["double_integrator"]["ok"] is True
    assert manifest["di_infeasible"]["ok"] is False and manifest["di_infeasible"]["status"] == "infeasible"


def _index_rows(html: str) -> list[list[str]]:
    """Cells of the index's number table: study, quantity, paper, other reference, source,
    ocdsl, error, comparison (tolerance), verification, verdict, report."""
    return [re.findall(r"<td[^>]*>(.*?)</td>", r, re.S)
            for r in re.findall(r'<tr><td class="name">.*?</tr>', html, re.S)]


def test_index_has_every_expect_row(repro):
    out = repro["out"]
    html = (out / "index.html").read_text()
    by_study = {r[0]: r for r in _index_rows(html)}
    assert set(by_study) == {"double_integrator", "di_infeasible", "di_max_iter"}
    di = by_study["double_integrator"]
    # an analytic value is not a paper's: it sits in the "other reference" column, labelled
    assert di[1] == "tf" and di[2] == "" and float(di[3]) == 2.0 and "analytic" in di[4]
    assert abs(float(di[5]) - 2.0) < 1e-5 and di[7] == "|error| ≤ tol (rtol 1e−06)"
    assert di[8] == "verified" and di[9] == "agrees" and 'href="double_integrator/report.html"' in di[10]
    inf = by_study["di_infeasible"]
    assert inf[9] == "differs" and float(inf[5]) <= 1.0 + 1e-6 and inf[8] == "skipped"
    assert by_study["di_max_iter"][9] == "differs"
    head = html[:html.index("</header>")]
    assert "other references: 3" in head and re.search(r'agree <span class="badge pass">1</span>', head)
    # reports of earlier runs stay listed
    assert 'href="old_example/report.html"' in html
    for link in re.findall(r'href="([^"]+)"', html):
        assert (out / link).is_file(), link


@pytest.mark.parametrize("stem,status,words", [
    ("di_infeasible", "infeasible", ["local infeasibility", "check bounds"]),
    ("di_max_iter", "max_iter", ["Maximum number of iterations exceeded", "iteration limit"]),
])
def test_failed_run_report_shows_diagnosis(repro, stem, status, words):
    d = repro["out"] / stem
    html = (d / "report.html").read_text()
    diag = re.search(r'<div class="diagnosis">(.*?)</div>', html, re.S)
    assert diag, "no diagnosis block"
    assert status in diag.group(1)
    for w in words:
        assert w.lower() in html.lower(), w
    # the diagnosis comes before the problem, the last iterate is still drawn and flagged
    assert html.index('class="diagnosis"') < html.index('id="problem"')
    assert "last iterate" in html
    assert len(re.findall(r'src="data:image/svg\+xml;base64,', html)) >= 3
    if PDFTOTEXT:
        text = subprocess.run([PDFTOTEXT, "-layout", str(d / "report.pdf"), "-"], capture_output=True,
                              text=True, check=True).stdout
        assert "Diagnosis" in text and status in text


def test_index_only_and_paper_tables(tmp_path):
    """A study folder's paper table (Table 4 of seed 0) against a synthetic study.csv."""
    d = tmp_path / "seed0_table4"
    d.mkdir()
    (d / "study.csv").write_text(
        "id,x0,y0,z0,seed,status,objective,tf\n"
        "p0,20,0,0,0,optimal,25.8729,25.8729\n"
        "p1,20,4,0,0,optimal,25.7892,25.7892\n"
        "p2,20,4,4,0,optimal,25.9380,25.9380\n"
        "p3,20,4,-5,0,infeasible,,\n")
    (d / "report.html").write_text("<html></html>")
    rows = R.study_paper_numbers(d, "seed0_table4")
    assert [r["passed"] for r in rows] == [True, True, False, False, False]
    assert rows[1]["compare"] == "ocdsl ≤ ref + tol" and rows[2]["error"] == pytest.approx(0.002)
    # 25.7892 under "at most 26.1674": a better optimum than the paper's search found, by its test
    assert [r["verdict"] for r in rows] == [R.REPRODUCED, R.BETTER] + [R.NOT_REPRODUCED] * 3
    assert rows[1]["test"] == "tests/test_seed0_pipeline.py::test_table4_row"
    assert R.main(["--out", str(tmp_path), "--index-only"]) == 0
    html = (tmp_path / "index.html").read_text()
    assert html.count("Seed 0 Table 4") == 5
    assert re.search(r'not reproduced <span class="badge fail">3</span>', html)


def test_optimal_mode_files_run_after_their_paper_run():
    """The seed-1 optimal-mode files take their guess from the paper-mode file (``guess:
    {from: seed1_<n>N_paper.yaml}``, ocdsl/chain): they are plain problem files run after
    it (so they reuse its fresh run folder), and slow as it is."""
    examples = R.find_examples(ROOT / "configs")
    order = [e.stem for e in examples]
    for n in (10, 5, 2):
        opt = examples[order.index(f"seed1_{n}N_optimal")]
        assert opt.kind == "problem" and opt.slow and opt.after == (f"seed1_{n}N_paper",)
        assert order.index(f"seed1_{n}N_optimal") > order.index(f"seed1_{n}N_paper")
    assert "seed1_10N_optimal" not in {e.stem for e in R.find_examples(ROOT / "configs", skip_slow=True)}


CHAIN_SOURCE = """name: Double integrator, minimum energy
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: 2.5}
  constraints: [x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, -1 <= u <= 1]
  objective: minimize integral(u**2)
method: {transcription: LGR, segments: 6, degree: 4}
"""
CHAIN_TARGET = """name: Double integrator, minimum time from the minimum-energy run
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: free}
  guess: {from: a_energy.yaml, reuse: ../reports/a_energy, tf: 2.5}
  constraints: [x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, -1 <= u <= 1, 0.1 <= tf <= 10]
  objective: minimize tf
method: {transcription: LGR, segments: 6, degree: 4}
expect:
  tf: {value: 2.0, rtol: 1.0e-4}
"""


@pytest.mark.ipopt
def test_a_chain_runs_after_its_source_and_reuses_its_report_folder(tmp_path):
    """A file whose guess comes from another example (named so that it sorts first) runs
    after it and reuses that example's fresh run folder instead of solving it again."""
    cfg = tmp_path / "configs"
    cfg.mkdir()
    (cfg / "0_mintime.yaml").write_text(CHAIN_TARGET)
    (cfg / "a_energy.yaml").write_text(CHAIN_SOURCE)
    examples = R.find_examples(cfg)
    assert [e.stem for e in examples] == ["a_energy", "0_mintime"]
    outs = R.reproduce(examples, tmp_path / "reports", formats=(), log=lambda *_: None)
    assert [o.ok for o in outs] == [True, True], [o.message for o in outs]
    data = json.loads((tmp_path / "reports" / "0_mintime" / "result.json").read_text())
    (stage,) = data["extra"]["chain"]
    assert Path(stage["reused"]).resolve() == (tmp_path / "reports" / "a_energy").resolve()
    assert (tmp_path / "reports" / "0_mintime" / "stages" / "a_energy" / "result.json").is_file()


def test_reports_only_remakes_reports_from_the_run_folders(repro):
    """``--reports-only`` re-makes every report from its run folder without solving: the
    trajectory stays the same file, the report is new, the manifest's verdict is the run's."""
    out = repro["out"]
    traj = (out / "double_integrator" / "trajectory.csv").stat().st_mtime_ns
    # a report ocdsl wrote from an earlier run (its digest recorded as ocdsl's); one the user
    # edited is refused (test_run_folder: a_report_the_user_edited_is_theirs)
    (out / "double_integrator" / "report.html").write_text("<html>stale</html>")
    run_folder.record_digests(out / "double_integrator", ["report.html"])
    assert R.main(["--out", str(out), "--reports-only", "--formats", "html", "--configs", str(repro["cfg"])]) == 0
    assert (out / "double_integrator" / "trajectory.csv").stat().st_mtime_ns == traj
    html = (out / "double_integrator" / "report.html").read_text()
    assert "stale" not in html and "Solution summary" in html
    manifest = json.loads((out / "reproduce.json").read_text())
    assert manifest["double_integrator"]["ok"] is True and manifest["di_infeasible"]["ok"] is False
    assert "report_made" in manifest["double_integrator"]
