"""`guess: {t0: ..., tf: ...}`: the start of a free initial time is the file's, on every back end."""
import pytest

from ocdsl.api import compile_file
from ocdsl.transcribe.guess import make_guess

# a free start with both ends bounded: without a guess the start is the middle of its bounds (2.5)
_FREE_T0 = """name: free start
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: free, tf: 5}
  constraints:
    - 0 <= t0 <= 5
    - x(t0) == 0
    - v(t0) == 0
    - x(tf) == 1
    - v(tf) == 0
  objective: minimize tf - t0 + integral(u**2)
  guess: {t0: 3.5, tf: 5}
"""


def test_a_guessed_free_t0_is_the_start_of_the_guess(tmp_path):
    path = tmp_path / "f.yaml"
    path.write_text(_FREE_T0)
    problem = compile_file(path).problem
    ph = problem.phases[0]
    assert make_guess(problem, ph).t0 == pytest.approx(3.5)
    path.write_text(_FREE_T0.replace("  guess: {t0: 3.5, tf: 5}\n", ""))
    problem = compile_file(path).problem
    assert make_guess(problem, problem.phases[0]).t0 == pytest.approx(2.5)


@pytest.mark.ipopt
def test_a_guessed_free_t0_solves_to_the_optimum(tmp_path):
    """J = T + 12/T**3 for a duration T (rest to rest over a unit distance: integral(u**2) = 12/T**3),
    least where dJ/dT = 1 - 36/T**4 = 0: T = sqrt(6), so t0 = 5 - sqrt(6)."""
    from ocdsl.api import run_file

    path = tmp_path / "f.yaml"
    path.write_text(_FREE_T0)
    res = run_file(path, out_dir=tmp_path / "run")
    T = 6 ** 0.5
    assert res.status == "optimal", res.message
    assert res.objective == pytest.approx(T + 12 / T ** 3, rel=1e-7)
    assert res.phases[0].time[0] == pytest.approx(5 - T, rel=1e-6)
    # a free start is printed, as a free final time is
    row = next(line for line in res.summary().splitlines() if "initial time" in line)
    assert float(row.split()[-1]) == pytest.approx(5 - T, rel=1e-6)
    # and written to result.json beside tf, read back by ocdsl.read; a fixed start has none
    import json

    import ocdsl

    assert json.loads((tmp_path / "run" / "result.json").read_text())["t0"] == pytest.approx(5 - T, rel=1e-6)
    assert ocdsl.read(tmp_path / "run").t0 == pytest.approx(5 - T, rel=1e-6)
    fixed_start = tmp_path / "g.yaml"
    fixed_start.write_text(_FREE_T0.replace("t0: free", "t0: 1"))
    fixed = run_file(fixed_start, out_dir=tmp_path / "fixed")
    assert fixed.t0 is None and json.loads((tmp_path / "fixed" / "result.json").read_text())["t0"] is None


def test_a_guessed_time_outside_its_bounds_starts_at_the_bound_without_pyomo_warnings(tmp_path, caplog):
    """``guess: {tf: 20}`` with ``0.5 <= tf <= 10`` printed Pyomo's W1002 (unseen6)."""
    import logging

    from ocdsl.api import run_file

    path = tmp_path / "g.yaml"
    path.write_text(_FREE_T0.replace("time: {t0: free, tf: 5}", "time: {t0: 0, tf: free}")
                    .replace("0 <= t0 <= 5", "0.5 <= tf <= 10").replace("tf - t0 +", "tf +")
                    .replace("guess: {t0: 3.5, tf: 5}", "guess: {tf: 20}"))
    problem = compile_file(path).problem
    assert make_guess(problem, problem.phases[0]).tf == 10.0
    with caplog.at_level(logging.WARNING):
        res = run_file(path, None)
    assert res.status == "optimal"
    assert not [r for r in caplog.records if "outside the bounds" in r.getMessage()]
