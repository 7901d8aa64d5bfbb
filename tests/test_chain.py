"""Chains of runs (ocdsl/chain): a phase's guess from another problem file's solution,
through a registered transform; the same result as the manual route (run the source, then
start from its folder); reuse of an unchanged source's run; the errors of `ocdsl check`;
and every file in configs/ reproduced by an `ocdsl` command."""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from ocdsl.api import run_file
from ocdsl.chain.registry import register_transform
from ocdsl.result import PhaseTrajectory, Result, single_phase_result
from ocdsl.spec.compile import load
from ocdsl.spec.errors import SpecError

SOURCE = """name: Double integrator, minimum energy in a fixed time
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: 2.5}
  constraints: [x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, -1 <= u <= 1]
  objective: minimize integral(u**2)
method: {transcription: LGR, segments: 6, degree: 4}
"""


def target(guess: str, states=("x", "v")) -> str:
    p, w = states
    return f"""name: Double integrator, minimum time
model:
  states: [{p}, {w}]
  controls: [u]
  dynamics: {{{p}: {w}, {w}: u}}
problem:
  time: {{t0: 0, tf: free}}
  guess: {guess}
  constraints: [{p}(t0) == 1, {w}(t0) == 0, {p}(tf) == 0, {w}(tf) == 0, -1 <= u <= 1, 0.1 <= tf <= 10]
  objective: minimize tf
method: {{transcription: LGR, segments: 6, degree: 4}}
expect:
  tf: {{value: 2.0, rtol: 1.0e-4}}
"""


def _renamed(source: Result) -> Result:
    """The test transform's conversion: x, v -> p, w, and the time halved."""
    tr = source.phase()
    return single_phase_result("renamed", "feasible", PhaseTrajectory(
        "main", np.asarray(tr.time) * 0.5, states={"p": tr.states["x"], "w": tr.states["v"]},
        controls={"u": tr.controls["u"]}), extra={"halved": True})


def _note(result, source_dir, file):
    result.extra["noted_from"] = Path(source_dir).name


@register_transform("test_rename_xv", description="tests: x, v -> p, w", annotate=_note)
def _rename(source, source_dir, file):
    return _renamed(source)


def _same_solution(a: Result, b: Result) -> None:
    assert a.status == b.status == "optimal"
    assert a.objective == b.objective and a.iterations == b.iterations
    ta, tb = a.phase(), b.phase()
    assert np.array_equal(ta.time, tb.time)
    for n in ta.states:
        assert np.array_equal(ta.states[n], tb.states[n], equal_nan=True), n
    assert np.array_equal(ta.controls["u"], tb.controls["u"], equal_nan=True)   # LGR: no control at t0


@pytest.mark.ipopt
def test_chain_gives_the_manual_routes_result_and_keeps_its_stage(tmp_path):
    (tmp_path / "energy.yaml").write_text(SOURCE)
    (tmp_path / "chain.yaml").write_text(target("{from: energy.yaml, tf: 2.5}"))
    chained = run_file(tmp_path / "chain.yaml", tmp_path / "out")
    # manual: solve the source, then start from its run folder
    run_file(tmp_path / "energy.yaml", tmp_path / "energy_run")
    (tmp_path / "manual.yaml").write_text(target("{from: energy_run, tf: 2.5}"))
    manual = run_file(tmp_path / "manual.yaml", tmp_path / "manual_out")
    _same_solution(chained, manual)
    assert chained.ok and chained.tf == pytest.approx(2.0, rel=1e-4)
    (stage,) = chained.extra["chain"]
    assert stage["from"] == "energy.yaml" and stage["transform"] == "identity"
    assert stage["reused"] is None and stage["source_status"] == "optimal"
    kept = tmp_path / "out" / "stages" / "energy"
    assert (kept / "problem.yaml").read_text() == SOURCE
    assert Result.read(kept).objective == pytest.approx(Result.read(tmp_path / "energy_run").objective)
    w = chained.wall_time_s
    assert 0 < w["stages"] < w["total"] and w["solve"] + w["stages"] < w["total"]


@pytest.mark.ipopt
def test_an_unchanged_source_is_reused_and_a_changed_one_solved_again(tmp_path):
    (tmp_path / "energy.yaml").write_text(SOURCE)
    (tmp_path / "chain.yaml").write_text(target("{from: energy.yaml, tf: 2.5}"))
    first = run_file(tmp_path / "chain.yaml", tmp_path / "out")
    again = run_file(tmp_path / "chain.yaml", tmp_path / "out")
    assert Path(again.extra["chain"][0]["reused"]) == tmp_path / "out" / "stages" / "energy"
    _same_solution(first, again)
    (tmp_path / "energy.yaml").write_text(SOURCE.replace("tf: 2.5", "tf: 2.4"))
    changed = run_file(tmp_path / "chain.yaml", tmp_path / "out")
    assert changed.extra["chain"][0]["reused"] is None
    assert "tf: 2.4" in (tmp_path / "out" / "stages" / "energy" / "problem.yaml").read_text()
    # `reuse:` names an earlier run of the source, used only while it is a run of the file as it is
    run_file(tmp_path / "energy.yaml", tmp_path / "earlier")
    (tmp_path / "reuse.yaml").write_text(target("{from: energy.yaml, reuse: earlier, tf: 2.5}"))
    res = run_file(tmp_path / "reuse.yaml", tmp_path / "out2")
    assert Path(res.extra["chain"][0]["reused"]) == tmp_path / "earlier"
    (tmp_path / "energy.yaml").write_text(SOURCE)
    res = run_file(tmp_path / "reuse.yaml", tmp_path / "out3")
    assert res.extra["chain"][0]["reused"] is None and res.ok


@pytest.mark.ipopt
def test_a_registered_transform_converts_the_guess_as_done_by_hand(tmp_path):
    (tmp_path / "energy.yaml").write_text(SOURCE)
    (tmp_path / "chain.yaml").write_text(
        target("{from: energy.yaml, transform: test_rename_xv, tf: 1.25}", ("p", "w")))
    chained = run_file(tmp_path / "chain.yaml", tmp_path / "out")
    guess = Result.read(tmp_path / "out" / "stages" / "energy.guess")
    assert list(guess.phase().states) == ["p", "w"] and guess.phase().time[-1] == pytest.approx(1.25)
    assert chained.extra["noted_from"] == "energy" or chained.extra["noted_from"].endswith("energy")
    assert chained.extra["chain"][0]["conversion"] == {"halved": True}
    # by hand: solve the source, convert its run, start from the converted folder
    run_file(tmp_path / "energy.yaml", tmp_path / "energy_run")
    _renamed(Result.read(tmp_path / "energy_run")).write(tmp_path / "converted")
    (tmp_path / "manual.yaml").write_text(target("{from: converted, tf: 1.25}", ("p", "w")))
    _same_solution(chained, run_file(tmp_path / "manual.yaml", tmp_path / "manual_out"))


def _errors(tmp_path, guess: str) -> str:
    (tmp_path / "chain.yaml").write_text(target(guess))
    with pytest.raises(SpecError) as e:
        load(tmp_path / "chain.yaml")
    return str(e.value)


def test_check_names_file_and_line_of_a_bad_chain(tmp_path):
    (tmp_path / "energy.yaml").write_text(SOURCE)
    msg = _errors(tmp_path, "{from: energy.yaml, transform: identty}")
    assert re.search(r"chain\.yaml:8: unknown transform 'identty' \(did you mean 'identity'\?\)", msg), msg
    msg = _errors(tmp_path, "{from: nothere.yaml}")
    assert "chain.yaml:8: guess from 'nothere.yaml': no such problem file" in msg, msg
    msg = _errors(tmp_path, "{transform: identity}")
    assert "chain.yaml:8: a transform needs `from:`" in msg, msg
    (tmp_path / "run").mkdir()
    msg = _errors(tmp_path, "{from: run, reuse: elsewhere}")
    assert "`reuse:` names an earlier run of a problem file" in msg and "no run folder there" in msg, msg
    # a cycle: chain.yaml -> b.yaml -> chain.yaml, both errors of one file in one pass
    (tmp_path / "b.yaml").write_text(SOURCE.replace("  objective:", "  guess: {from: chain.yaml}\n  objective:"))
    msg = _errors(tmp_path, "{from: b.yaml, transform: nope}")
    assert "chain.yaml:8: guess from 'b.yaml': the chain of files comes back to chain.yaml: " \
           "chain.yaml -> b.yaml -> chain.yaml" in msg, msg
    assert "unknown transform 'nope'" in msg, msg


def test_ocdsl_check_reports_a_cycle_without_a_traceback(tmp_path):
    (tmp_path / "b.yaml").write_text(SOURCE.replace("  objective:", "  guess: {from: chain.yaml}\n  objective:"))
    (tmp_path / "chain.yaml").write_text(target("{from: b.yaml}"))
    p = subprocess.run([sys.executable, "-m", "ocdsl.cli", "check", str(tmp_path / "b.yaml")],
                       capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 2, p.stderr
    assert "b.yaml:9: guess from 'chain.yaml': the chain of files comes back to b.yaml" in p.stderr, p.stderr
    assert "Traceback" not in p.stderr


def test_a_bad_source_file_is_reported_with_its_own_file_and_line(tmp_path):
    (tmp_path / "energy.yaml").write_text(SOURCE.replace("x(tf) == 0", "xx(tf) == 0"))
    (tmp_path / "chain.yaml").write_text(target("{from: energy.yaml}"))
    with pytest.raises(SpecError, match=r"energy\.yaml:8: .*xx"):
        run_file(tmp_path / "chain.yaml", tmp_path / "out")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------------------
# configs/: one `ocdsl` command each
RECIPE = re.compile(r"^#\s*reproduce:\s*(.*)$", re.M)


def test_every_config_is_reproduced_by_one_ocdsl_command():
    """A `# reproduce:` header is the `slow` mark or an `ocdsl` command; no file asks for
    another command (a Python module or script); every file is of a kind `ocdsl run` or
    `ocdsl study` runs, and every chain's source is another configs/ file."""
    from ocdsl.chain.check import sources_of
    from ocdsl.report.reproduce import classify

    files = sorted((ROOT / "configs").glob("*.yaml"))
    assert len(files) > 40
    for f in files:
        text = f.read_text()
        for recipe in RECIPE.findall(text):
            assert recipe.strip() == "slow" or recipe.startswith("ocdsl "), (f.name, recipe)
        comments = "\n".join(line for line in text.splitlines() if line.lstrip().startswith("#"))
        assert not re.search(r"python\s+-m|\.venv/bin/python|scripts/", comments), f.name
        assert classify(f).kind in ("problem", "controller", "pareto", "study"), f.name
        for src in sources_of(f):
            assert src.parent.resolve() == (ROOT / "configs").resolve() and src.is_file(), (f.name, src)
    chained = [f.stem for f in files if sources_of(f)]
    assert {"seed1_2N_optimal", "seed1_5N_optimal", "seed1_10N_optimal"} <= set(chained)


def test_the_seed1_optimal_files_declare_their_chain():
    for n in (2, 5, 10):
        f = load(ROOT / "configs" / f"seed1_{n}N_optimal.yaml")
        chain = f.problem.phases[0].guess["chain"]
        assert chain["from"] == f"seed1_{n}N_paper.yaml" and chain["transform"] == "cr3bp_polar_to_sundman"
        assert chain["reuse"] == f"../reports/seed1_{n}N_paper"


def test_a_previous_runs_values_outside_the_bounds_are_clipped_into_them(tmp_path):
    """A solution ends 1e-8 outside its bounds (Ipopt's bound relaxation); started from it,
    the guess lies inside them, as the file's own guess does (Pyomo warned per variable)."""
    from ocdsl.transcribe.guess import make_guess

    t = np.linspace(0.0, 2.0, 9)
    u = np.where(t < 1.0, -1.0 - 1e-8, 1.0 + 1e-8)
    prev = PhaseTrajectory("main", t, states={"x": 1.0 - t, "v": 0.0 * t}, controls={"u": u})
    (tmp_path / "f.yaml").write_text(target("{tf: 2.0}"))
    file = load(tmp_path / "f.yaml")
    ph = file.problem.phases[0]
    g = make_guess(file.problem, ph, prev)
    assert np.all(np.abs(g.v_table["u"]) <= 1.0) and np.isclose(np.abs(g.v_table["u"]), 1.0).all()
    assert np.array_equal(g.v_table["x"], 1.0 - t)       # inside its bounds: as it was


def test_a_guess_from_a_source_that_failed_is_noted_where_the_user_reads(tmp_path):
    """unseen23 w12: a chained source that ended infeasible was used as the guess with no word
    outside result.json (`extra.chain[0].source_status`). The run's notes say so now."""
    bad = SOURCE.replace("x(t0) == 1", "x(t0) == 0").replace("x(tf) == 0", "x(tf) == 50")    # beyond |u| <= 1
    (tmp_path / "source.yaml").write_text(bad)
    (tmp_path / "target.yaml").write_text(target("{from: source.yaml, tf: 2.5}"))
    res = run_file(tmp_path / "target.yaml", None)
    assert res.extra["chain"][0]["source_ok"] is False
    assert any("comes from source.yaml, whose run ended" in n for n in res.extra.get("notes", [])), res.extra
