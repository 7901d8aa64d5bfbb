"""The run summary's lines say what the numbers are: a free parameter's optimum is shown, and
a mesh that missed the refinement's tolerance is a solution, not a 'last iterate'."""
from ocdsl.api import run_file
from ocdsl.cli import _summary
from ocdsl.result import Result

PROJECTILE = """name: projectile, launch angle free
model:
  states: [x, y, vx, vy]
  controls: []
  parameters: {g: 9.81, V: 10, gamma: {value: 0.5, free: true, bounds: [0.1, 1.5]}}
  dynamics: {x: vx, y: vy, vx: 0, vy: -g}
problem:
  time: {t0: 0, tf: free}
  constraints:
    - x(t0) == 0
    - y(t0) == 0
    - vx(t0) == V*cos(gamma)
    - vy(t0) == V*sin(gamma)
    - y(tf) == 0
    - 0.1 <= tf <= 5
  objective: maximize x(tf)
method: {transcription: LGR, segments: 2, degree: 3}
"""


def test_a_free_parameters_optimum_is_in_the_summary(tmp_path, capsys):
    p = tmp_path / "projectile.yaml"
    p.write_text(PROJECTILE)
    res = run_file(p, tmp_path / "run")
    assert res.status == "optimal" and abs(res.parameters["gamma"] - 0.7853981634) < 1e-7
    assert res.extra["free_parameters"] == ["gamma"]
    capsys.readouterr()
    _summary(res, tmp_path / "run")
    out = capsys.readouterr().out
    assert "free parameters" in out and "gamma 0.78539816" in out, out


def test_a_mesh_not_converged_objective_is_not_called_a_last_iterate(tmp_path, capsys):
    res = Result(name="t", status="mesh_not_converged", message="mesh refinement did not reach it",
                 objective=1.25, tf=2.0, iterations=12, nlp={}, method={}, parameters={}, phases=[])
    _summary(res, tmp_path)
    out = capsys.readouterr().out
    assert "last iterate" not in out and "1.25 (on the reported mesh; refinement not converged)" in out, out


def test_an_expectation_without_a_value_says_so_not_nan(tmp_path, capsys):
    """A run interrupted before its first iterate has no objective: the expect line said
    'nan vs 2.867261 (relative error nan ...) FAIL' (unseen4)."""
    check = {"name": "objective", "value": float("nan"), "reference": 2.867261, "rtol": 1e-6, "atol": None,
             "error": float("nan"), "relative_error": float("nan"), "passed": False}
    res = Result("r", "interrupted", expect=[check])
    line = next(ln for ln in res.summary().splitlines() if "expect" in ln)
    assert line.strip() == "expect objective: no value vs 2.867261 (the run ended before it had one) FAIL"
    _summary(res, tmp_path)
    out = capsys.readouterr().out
    assert "no value vs 2.867261" in out and "nan" not in out
    ok = {**check, "value": 2.8672611, "error": 1e-7, "relative_error": 3.5e-8, "passed": True}
    assert "expect objective: 2.8672611 vs 2.867261 (relative error 3.50e-08, rtol 1.0e-06) pass" in \
        Result("r", "optimal", expect=[ok]).summary()


def test_a_failed_solves_numbers_are_not_shown_as_results(tmp_path, capsys):
    """unseen12 F9: a run whose solve never started printed its guess as 'final time 5.05'
    and 'expect tf: 5.05 vs 2 FAIL'; an infeasible run's report header said 'objective: 1'."""
    check = {"name": "tf", "value": 5.05, "reference": 2.0, "rtol": 1e-6, "atol": None,
             "error": 3.05, "relative_error": 1.525, "passed": False}
    never = Result("r", "error", tf=5.05, iterations=0, expect=[check])
    assert "final time   5.05 (the guess: the solve did not start)" in never.summary()
    _summary(never, tmp_path)
    out = capsys.readouterr().out
    assert "5.05 (the guess: the solve did not start)" in out
    assert "expect tf: 5.05 vs 2 (relative error 1.52e+00, rtol 1.0e-06) (the guess: the solve did not start) FAIL" in out
    last = Result("r", "infeasible", objective=1.0, tf=1.0, iterations=22)
    assert "objective    1 (last iterate, not a solution)" in last.summary()
    from ocdsl.report.build.run import _build_run

    html, _ = _build_run(last.write(tmp_path / "inf"))
    assert "last iterate (not a solution)" in html
    solved = Result("r", "optimal", objective=1.0, tf=1.0, iterations=5)
    assert "final time   1\n" in solved.summary() + "\n" and "not a solution" not in solved.summary()


def test_a_guess_outside_its_bounds_is_noted(tmp_path):
    """unseen12 F11: `tf: 50` with tf <= 10 and `u: 7` with |u| <= 1 were taken silently."""
    p = tmp_path / "g.yaml"
    p.write_text("""name: guess outside bounds
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: free}
  constraints: [-1 <= u <= 1, x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, 0.1 <= tf <= 10]
  objective: minimize tf
  guess: {tf: 50, u: 7}
""")
    res = run_file(p, None)
    assert res.status == "optimal"
    notes = res.extra["notes"]
    assert "the guess tf = 50 is outside its bounds [0.1, 10]: the solve starts from 10" in notes
    assert "the guess of u (7) is outside its bounds [-1, 1]: it is moved onto them" in notes


def test_an_expectation_of_zero_shows_its_absolute_error():
    """unseen19 e1: `x(tf): 0 vs 0 (relative error inf, rtol 1.0e-06) pass` for an exact zero."""
    from ocdsl.result_views import expect_comparison
    from ocdsl.run import expect_check

    text = expect_comparison(expect_check("x(tf)", 0.0, 0.0, 1e-6, None))
    assert "inf" not in text and "error 0.00e+00" in text
    assert "relative error 1.00e-02" in expect_comparison(expect_check("J", 1.01, 1.0, 1e-6, None))


def test_the_starts_of_a_refined_flat_run_are_compared_with_its_first_level(tmp_path, capsys):
    """unseen19: seed 2 printed "starts 8: 0 ended at this objective": its starts solve the
    first level, whose J is not the refined one reported."""
    from ocdsl.cli import _summary
    from ocdsl.result import Result

    res = Result(name="flat", status="optimal", objective=150.39,
                 extra={"starts": [{"status": "optimal", "objective": 149.0}] * 3
                        + [{"status": "optimal", "objective": 151.0}],
                        "refinement": {"levels": [{"objective": 149.0}, {"objective": 150.39}]}})
    capsys.readouterr()
    _summary(res, tmp_path / "run")
    shown = capsys.readouterr().out
    assert "4: 3 ended at the first level's objective, 1 elsewhere (151)" in shown, shown



def test_an_expectation_of_zero_without_tolerances_can_pass():
    """unseen20: `expect: {objective: 0.0}` of an exact-tracking problem (J = 4e-18) could never
    pass: the default rtol asks for exactly 0. A zero reference takes atol 1e-6 by default."""
    from ocdsl.run import expect_check

    near = expect_check("objective", 4e-18, 0.0, None, None)
    assert near["passed"] and near["atol"] == 1e-6 and near["rtol"] is None
    assert not expect_check("objective", 2e-6, 0.0, None, None)["passed"]
    # a tolerance the file gives is the file's
    assert not expect_check("objective", 4e-18, 0.0, 1e-6, None)["passed"]
    assert expect_check("J", 1.0 + 5e-7, 1.0, None, None)["passed"]


def test_a_bound_expectation_is_printed_as_a_bound():
    """unseen22 m09: `compare: at_most` printed "12 vs 12.5 (relative error 4.00e-02, rtol
    1.0e-06) pass", a miss that passed; a bound is shown as one, with its slack."""
    from ocdsl.result_views import expect_comparison
    from ocdsl.run import expect_check

    below = expect_check("J", 12.0, 12.5, 1e-6, None, "at_most")
    assert below["passed"] and expect_comparison(below) == "J: 12 <= 12.5 + 1.2e-05 (at_most)"
    above = expect_check("J", 13.0, 12.5, None, 0.1, "at_least")
    assert above["passed"] and expect_comparison(above) == "J: 13 >= 12.5 - 0.1 (at_least)"
    assert "relative error" in expect_comparison(expect_check("J", 13.0, 12.5, None, None))


def test_a_failed_expectation_is_named_in_the_headline(tmp_path, capsys):
    """unseen22 f05b: "solver optimal, verification verified" headed a run that failed (exit 1)
    on its expect, named only lines below."""
    from ocdsl.run import expect_check

    res = Result(name="t", status="optimal", message="", objective=12.0, tf=1.0, iterations=3, nlp={},
                 method={}, parameters={}, phases=[],
                 expect=[expect_check("objective", 12.0, 12.1, 1e-6, None), expect_check("tf", 1.0, 1.0, 1e-6, None)])
    _summary(res, tmp_path)
    head = capsys.readouterr().out.splitlines()[0]
    assert "expect FAIL (objective)" in head and "tf" not in head.split("expect")[1], head


def test_the_files_text_is_printed_as_text_not_console_markup(tmp_path, capsys):
    """unseen37 F4: `name: bracket test [draft]` printed "bracket test : solver optimal" (the
    console library read [draft] as a style tag); a law named `lqr[fast]`, an expectation on
    `r[0]` and a run folder `runs/[x]` went the same way."""
    check = {"name": "r[0](tf)", "value": 1.0, "reference": 1.0, "rtol": 1e-6, "atol": None,
             "error": 0.0, "relative_error": 0.0, "passed": True}
    res = Result(name="bracket test [draft] [bold]", status="optimal", message="", objective=1.5, tf=2.0,
                 iterations=3, nlp={}, method={}, parameters={}, phases=[], expect=[check],
                 extra={"laws": ["lqr[fast]"], "lqr[fast]": {"status": "stable", "cost": 1.0}})
    _summary(res, tmp_path / "[x]")
    out = capsys.readouterr().out
    assert "bracket test [draft] [bold]: solver optimal" in out, out
    assert "lqr[fast]" in out and "r[0](tf)" in out and "[x]" in out, out


def test_numpys_floating_point_warnings_do_not_reach_the_terminal(tmp_path):
    """unseen40 F4: `tf: 1e-300` (and a sqrt at the edge of its domain in a named expression)
    printed NumPy RuntimeWarnings with ocdsl's source paths and code lines before the
    summary. The console script keeps them out; the verdicts are the checks'."""
    import os
    import subprocess
    import sys

    p = tmp_path / "tiny.yaml"
    p.write_text("""name: tiny horizon
model: {states: [x, v], controls: [u], expressions: {s: sqrt(1 - x)}, dynamics: {x: v, v: u + 0*s}}
problem:
  time: {t0: 0, tf: 1e-300}
  constraints: [-1 <= u <= 1, x(t0) == 1, v(t0) == 0, x(tf) == 1]
  objective: minimize integral(u**2)
method: {transcription: LGR, segments: 10, degree: 5}
""")
    proc = subprocess.run([sys.executable, "-c", "from ocdsl.cli import entry; entry()", "run", str(p),
                           "--out", str(tmp_path / "run")], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "OCDSL_NO_SERVE": "1"})
    assert "tiny horizon: solver" in proc.stdout, proc.stdout + proc.stderr
    assert "Warning" not in proc.stdout + proc.stderr, proc.stderr


def test_a_control_nothing_depends_on_is_named(tmp_path):
    """unseen40 F5: `controls: [u, w]` with w in no dynamics, constraint or objective was
    accepted without a word; its values are arbitrary (any is optimal)."""
    text = """name: double integrator with an idle control
model: {states: [x, v], controls: [u, w], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: free}
  constraints: [-1 <= u <= 1, -1 <= w <= 1, x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, 0.1 <= tf <= 10]
  objective: minimize tf
method: {transcription: LGR, segments: 4, degree: 4}
"""
    p = tmp_path / "idle.yaml"
    p.write_text(text)
    notes = run_file(p, tmp_path / "run").extra.get("notes") or []
    assert any(n.startswith("control w appears in no dynamics") for n in notes), notes
    p.write_text(text.replace("v: u}", "v: u + 0.1*w}"))
    assert not any("appears in no dynamics" in n for n in run_file(p, tmp_path / "run2").extra.get("notes") or [])


def test_an_expectation_that_misses_below_ten_digits_shows_the_digits():
    """unseen54 F3: 1.9999999999999996 against 2 with rtol 0, at_least, read "2 >= 2
    (at_least) FAIL"; the values are shown in full where ten digits read alike."""
    from ocdsl.result_views import expect_comparison
    from ocdsl.run import expect_check

    miss = expect_check("objective", 1.9999999999999996, 2.0, 0.0, None, "at_least")
    assert not miss["passed"]
    assert expect_comparison(miss) == "objective: 1.9999999999999996 >= 2.0 (at_least)"
    assert expect_comparison(expect_check("J", 2.0, 2.0, 0.0, None, "at_least")) == "J: 2 >= 2 (at_least)"


def test_an_expectation_with_both_tolerances_shows_both():
    """unseen54 F4: with rtol 1e-4 and atol 1e-3 the check passes on either, and printed
    "relative error 1.26e-03, rtol 1.0e-04 pass" without the atol that passed it."""
    from ocdsl.result_views import expect_comparison
    from ocdsl.run import expect_check

    check = expect_check("tf", 0.70710678, 0.708, 1e-4, 1e-3)
    assert check["passed"]
    assert "atol 1.0e-03 or rtol 1.0e-04" in expect_comparison(check) and "error 8.93e-04" in expect_comparison(check)
