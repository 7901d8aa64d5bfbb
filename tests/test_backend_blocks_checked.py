"""Blocks of the other back ends are checked against the model when the file is compiled
(`ocdsl check`, exit 2 with file and line), not found wrong in the run (unseen9 F4: four
such files passed `ocdsl check`; their runs ended 'error', one with a traceback)."""
from pathlib import Path

import pytest

from ocdsl.api import compile_file
from ocdsl.spec.errors import SpecError

CONTROLLER = """name: LQR double integrator
model:
  states: [x1, x2]
  controls: [u]
  dynamics: {x1: x2, x2: u}
controller:
  type: lqr
  Q: [1, 1]
  R: [1]
  simulate:
    x0: {x1: 1, x2: 0}
    horizon: 5
    step: 0.01
"""

FLAT = (Path(__file__).parent / "data" / "flat_min_time_bang_bang.yaml").read_text()
FLAT_LINE = FLAT[:FLAT.index("flat_outputs: [x]")].count("\n") + 1

PARAMETRIC = """name: brachistochrone by PSO
model:
  states: [x, y, v]
  controls: [theta]
  dynamics: {x: v*sin(theta), y: -v*cos(theta), v: 9.81*cos(theta)}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 0, y(t0) == 10, v(t0) == 0, x(tf) == 10, y(tf) == 5, 0.5 <= tf <= 5]
  objective: minimize tf
method:
  transcription: parametric
  controls:
    theta: {series: polynomial, order: 1, bounds: [-3.0, 3.0]}
  tolerances: {x: 1.0e-4, y: 1.0e-4}
"""


@pytest.mark.parametrize("good,bad,line,fragment", [
    (CONTROLLER, CONTROLLER.replace("Q: [1, 1]", "Q: [1]"), 8, "controller.Q is 1x1, expected 2x2"),
    (CONTROLLER, CONTROLLER.replace("x2: 0}", "x3: 0}"), 11, "unknown states ['x3']"),
    (CONTROLLER, CONTROLLER.replace("R: [1]", "R: [1, 2]"), 9, "controller.R is 2x2, expected 1x1"),
    (FLAT, FLAT.replace("flat_outputs: [x]", "flat_outputs: [z]"), FLAT_LINE, "flat output(s) z not states of the model"),
    (PARAMETRIC, PARAMETRIC.replace("    theta: {", "    thetta: {"), 13, "'thetta' is not a control of the model (did you mean 'theta'?)"),
    (PARAMETRIC, PARAMETRIC.replace("{x: 1.0e-4, y", "{xx: 1.0e-4, y"), 14, "'xx' is not a state of the model"),
    (CONTROLLER, CONTROLLER.replace("  R: [1]\n", "  R: [1]\n  saturation: [10, 11]\n"), 10, "saturation needs 1 positive limits"),
    (CONTROLLER, CONTROLLER + "  robustness: {parameters: [mass], factors: [0.9, 1.1]}\n", 14, "'mass' is not a parameter of the model"),
    (CONTROLLER, CONTROLLER + "expect:\n  objective: 0.866\n", 14, "expect: is not checked in a controller file"),
    (CONTROLLER, CONTROLLER + "problem:\n  time: {t0: 0, tf: 1}\n  objective: minimize integral(u**2)\n", 6,
     "either a controller: block (a closed-loop study) or problem:/phases:"),
], ids=["Q size", "x0 state", "R size", "flat output", "series control", "tolerance state", "saturation shape",
        "robustness parameter", "expect in a controller file", "controller and problem"])
def test_a_back_end_block_that_does_not_fit_the_model_is_refused_at_its_line(tmp_path, good, bad, line, fragment):
    ok = tmp_path / "good.yaml"
    ok.write_text(good)
    compile_file(ok)
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    with pytest.raises(SpecError) as e:
        compile_file(path)
    assert f"bad.yaml:{line}: " in str(e.value) and fragment in str(e.value), str(e.value)


def test_a_controller_blocks_mistakes_come_in_one_pass(tmp_path):
    """unseen12 F6: a controller block's mistakes came one `check` run at a time (terms, then
    a, then A without sdc: given, then ...). The entries a mistake names are set aside and the
    rest validated again, so the independent ones are reported together."""
    path = tmp_path / "c.yaml"
    path.write_text("""name: pendulum on a cart
model:
  states: [x, th, xd, thd]
  controls: [F]
  dynamics: {x: xd, th: thd, xd: F, thd: 9.81*sin(th) - F*cos(th)}
controller:
  type: theta-d
  A: {"1,3": 1}
  theta_d: {terms: 12, a: -1}
  Q: [1, 10, 1, 1]
  R: [0.1]
  simulate: {x0: {th: 0.05}, horizon: 5, step: 0.01}
""")
    with pytest.raises(SpecError) as e:
        compile_file(path)
    msgs = [(i.line, i.message) for i in e.value.issues]
    assert any("A/B are only read with sdc: given" in m for _, m in msgs), msgs
    assert any(line == 9 and "terms" in m for line, m in msgs) and any("theta_d.a must be >= 0" in m for _, m in msgs)
    assert not any("missing required key" in m for _, m in msgs)
