"""A free final time that runs away (ocdsl/runaway.py): J improving as t_f grows without
bound is no optimum, however small J's slope when Ipopt stops (unseen47 F1)."""
import pytest

from ocdsl.api import run_file

ENERGY = """\
name: minimum energy, t_f free and unbounded (J = 1/t_f)
model: {states: [x], controls: [u], dynamics: {x: u}}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 0, x(tf) == 1]
  objective: minimize integral(u**2)
  guess: {tf: 1}
method: METHOD
"""

REST_TO_REST = """\
name: rest to rest, t_f free and unbounded (J = 6/t_f^3)
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0]
  objective: minimize integral(u**2/2)
  guess: {tf: 2}
method: {transcription: LGR, segments: 10, degree: 4}
"""


@pytest.mark.parametrize("text", [
    ENERGY.replace("METHOD", "{transcription: LGR, segments: 10, degree: 4}"),
    ENERGY.replace("METHOD", "{transcription: LGR, segments: 4, degree: 3, mesh: {tolerance: 1.0e-6}}"),
    REST_TO_REST])
def test_a_final_time_that_runs_away_is_no_optimum(text, tmp_path):
    """Ipopt stopped at t_f = 1e8 (J = 1e-8) and 1e5 (J = 6e-15): `optimal`, verified, exit 0
    (a certificate pass on the second); with `mesh:` `mesh_not_converged` "tighten the
    tolerance". With t_f fixed at twice that, J is lower: `diverged`, and the message says
    to bound t_f."""
    path = tmp_path / "runaway.yaml"
    path.write_text(text)
    res = run_file(path, None)
    assert res.status == "diverged" and not res.ok, (res.status, res.message)
    rec = res.extra["runaway_final_time"]
    assert rec["final_time"] > 1e4 and rec["stretched_objective"] < rec["objective"]
    assert "J keeps improving as t_f grows" in res.message and "Bound t_f" in res.message


def test_a_final_time_far_beyond_its_guess_that_is_optimal_stays_optimal(tmp_path):
    """Minimum time, x'' = u with |u| <= 0.001 from rest at 0 to rest at 1000: t_f* = 2000,
    2000 times its guess. The stretched solve (t_f fixed at 4000) is worse: optimal."""
    path = tmp_path / "far.yaml"
    path.write_text("""\
name: slow rest-to-rest, minimum time
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: free}
  constraints: [-0.001 <= u <= 0.001, x(t0) == 0, v(t0) == 0, x(tf) == 1000, v(tf) == 0]
  objective: minimize tf
  guess: {tf: 1}
method: {transcription: LGR, segments: 2, degree: 4}
""")
    res = run_file(path, None)
    assert res.status == "optimal" and res.ok and res.tf == pytest.approx(2000.0, rel=1e-6), res.message
    rec = res.extra["runaway_final_time"]
    assert rec["stretched_objective"] == pytest.approx(4000.0) and rec["gain"] < 0

