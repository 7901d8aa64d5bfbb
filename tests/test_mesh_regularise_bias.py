"""``mesh: {regularise: w}`` moves the optimum, not only the reported value: Jackson's
reactor with w = 1.5e-7 converged at J 1.1e-5 below the maximum 0.19181435632516 and said
optimal, verified, certificate pass, exit 0 (unseen6). The final mesh is solved once more
without the term; J must agree to the verification's tolerance."""
from __future__ import annotations

import pytest

from ocdsl.api import run_file

JACKSON = """name: Jackson's catalyst problem
model:
  states: [x1, x2]
  controls: [u]
  parameters: {k1: 1, k2: 10, k3: 1}
  dynamics:
    x1: -u*(k1*x1 - k2*x2)
    x2: u*(k1*x1 - k2*x2) - (1 - u)*k3*x2
problem:
  time: {t0: 0, tf: 4}
  constraints: [x1(t0) == 1, x2(t0) == 0, 0 <= u <= 1]
  objective: maximize 1 - x1(tf) - x2(tf)
method:
  transcription: LGR
  segments: 4
  degree: 3
  mesh: {tolerance: 1.0e-7, max_iterations: 12, regularise: WEIGHT}
"""
OPTIMUM = 0.19181435632516      # unseen6/refs/ref_jackson.py


def _run(tmp_path, weight: str):
    p = tmp_path / "jackson.yaml"
    p.write_text(JACKSON.replace("WEIGHT", weight))
    return run_file(p, None)


def test_a_regularisation_that_moves_j_past_the_tolerance_is_not_optimal(tmp_path):
    res = _run(tmp_path, "1.5e-7")
    assert (OPTIMUM - res.objective) / OPTIMUM > 1e-5          # the regularised problem's optimum
    assert res.verification["status"] == "verified"           # feasible: the verification cannot tell
    assert res.status == "mesh_not_converged" and not res.ok
    check = res.extra["unregularised"]
    assert check["agrees"] is False and check["weight"] == pytest.approx(1.5e-7)
    assert abs(check["unregularised_objective"] / OPTIMUM - 1) < 1e-6
    assert "regularisation moves the optimum" in res.message and "regularise" in res.message


def test_a_regularisation_whose_j_moves_within_the_tolerance_is_kept_and_said(tmp_path):
    # w = 1e-7: the term is 2.4e-5 of J, but J without it on the final mesh only 8.0e-6 away
    res = _run(tmp_path, "1.0e-7")
    assert 1e-6 < (OPTIMUM - res.objective) / OPTIMUM < 1e-5
    assert res.status == "optimal" and res.ok, res.message
    check = res.extra["unregularised"]
    assert check["relative_term"] > 1e-5 and check["agrees"] is True and check["relative_difference"] <= 1e-5
    assert any("solved without it gives J" in n for n in res.extra.get("notes", []))


def test_a_small_regularisation_term_needs_no_second_solve(tmp_path):
    res = _run(tmp_path, "1.0e-9")
    assert res.status == "optimal" and res.ok, res.message
    check = res.extra["unregularised"]
    assert check["relative_term"] <= 1e-5 and check["agrees"] is True
    assert check["unregularised_objective"] is None
    assert abs(res.objective / OPTIMUM - 1) < 1e-5


def test_no_regularisation_no_check(tmp_path):
    res = _run(tmp_path, "0.0")
    assert res.status == "optimal" and "unregularised" not in res.extra
    assert abs(res.objective / OPTIMUM - 1) < 1e-7
