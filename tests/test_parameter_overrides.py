"""--param and a study's parameters: the report's "overridden" note only where one was really
applied (not a phase's own value), and a free parameter refused as such."""
import re

from click.testing import CliRunner

from ocdsl.api import compile_file
from ocdsl.cli import main
from ocdsl.report.tables import parameters_table
from ocdsl.result import Result

TWO_PHASE = """name: two phases, the actuator halved in the second
model:
  states: [x, v]
  controls: [u]
  parameters: {b: 1.0}
  dynamics: {x: v, v: b*u}
phases:
  full:
    parameters: {b: 1.0}
    time: {t0: 0, tf: 1}
    constraints: [x(t0) == 0, v(t0) == 0]
    objective: integral(u**2)
  half:
    parameters: {b: 0.5}
    time: {t0: 1, tf: 2}
    constraints: [x(tf) == 1, v(tf) == 0]
    objective: integral(u**2)
links:
  - full.x(tf) == half.x(t0)
  - full.v(tf) == half.v(t0)
method: {transcription: LGR, segments: 2, degree: 3}
objective: minimize 0
"""

FREE = """name: free distance
parameters:
  p: {value: 0.5, free: true, bounds: [0, 2]}
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, v(t0) == 0, x(tf) == p, v(tf) == 0]
  objective: minimize integral(u**2) - p
method: {transcription: LGR, segments: 2, degree: 3}
"""


def _notes(tmp_path, text, parameters=None) -> dict:
    p = tmp_path / "f.yaml"
    p.write_text(text)
    file = compile_file(p, parameters)
    res = Result(name="t", status="optimal", parameters=file.parameters, problem=file.problem.description)
    rows = parameters_table(res)["rows"]
    # name (its HTML without tags) -> the note column
    return {re.sub(r"<[^>]+>", "", str(r[0]["html"])): r[3]["text"] for r in rows}


def test_a_phase_own_value_is_no_override(tmp_path):
    """b is 1.0 in the model, 0.5 in phase half: no --param, so no "overridden" (was:
    "b | 1 | overridden (file: 0.5)", half's value taken for the file's b)."""
    notes = _notes(tmp_path, TWO_PHASE)
    assert set(notes) == {"b", "full.b", "half.b"}
    assert not any("overridden" in n for n in notes.values()), notes


def test_an_override_is_noted_against_its_own_file_value(tmp_path):
    notes = _notes(tmp_path, TWO_PHASE, {"half.b": 0.25})
    assert notes["half.b"] == "overridden (file: 0.5)", notes
    assert "overridden" not in notes["b"] + notes["full.b"], notes
    notes = _notes(tmp_path, TWO_PHASE, {"b": 2.0})
    assert notes["b"] == "overridden (file: 1)", notes
    assert "overridden" not in notes["half.b"], notes


def test_param_of_a_free_parameter_says_it_is_free(tmp_path):
    """--param p=... for a free p (was: "... not in the file: ['p']")."""
    p = tmp_path / "free.yaml"
    p.write_text(FREE)
    out = tmp_path / "run"
    r = CliRunner().invoke(main, ["run", str(p), "--out", str(out), "--param", "p=0.3"])
    assert r.exit_code == 2, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit)
    assert "Traceback" not in r.output
    assert "'p' is a free parameter (optimised by the solver)" in r.output, r.output
    assert "--param" in r.output and "constants" in r.output
    assert f"{p}:3:" in r.output, r.output     # at the line declaring p
    assert "not in the file" not in r.output
    assert r.output.count("Error") == 1, r.output
    assert not out.exists()


def test_param_takes_a_constant_expression():
    """unseen20: `--param l=1/9` was refused (only plain numbers), though a file writes its
    parameters as expressions; what is not a constant stays one clear error."""
    import math

    import click
    import pytest

    from ocdsl.cli import _parse_params

    got = _parse_params(("l=1/9", "w=2*pi", "s=sqrt(2)", "x=1e3"))
    assert got == {"l": 1 / 9, "w": 2 * math.pi, "s": math.sqrt(2), "x": 1000.0}
    # inf, nan and 1e400 were taken and then blamed on the file's valid line (unseen40 F3)
    for bad in ("l=x + 1", "l=", "=3", "l=1/0", 'l=__import__("os")', "l=inf", "l=nan", "l=1e400", "l=-Infinity"):
        with pytest.raises(click.BadParameter, match="not NAME=NUMBER"):
            _parse_params((bad,))
    with pytest.raises(click.BadParameter, match="'l' is given twice"):     # the last won (unseen24)
        _parse_params(("l=1", "l=2"))


def test_a_param_that_divides_the_dynamics_by_zero_is_an_input_error(tmp_path):
    """unseen22: `--param l=0` on a pendulum's controller file ended 'solver error' with
    KeyError: 'ComplexInfinity' from the laws' generated code; now one line at the dynamics."""
    path = tmp_path / "pendulum.yaml"
    path.write_text("""name: pendulum
model:
  states: [th, w]
  controls: [u]
  parameters: {g: 9.81, l: 1.0}
  dynamics: {th: w, w: g/l*sin(th) + u}
controller:
  type: [lqr, sdre]
  Q: [1, 1]
  R: [1]
  simulate: {x0: {th: 0.5, w: 0}, horizon: 5, step: 0.01}
""")
    compile_file(path)
    out = tmp_path / "run"
    res = CliRunner().invoke(main, ["run", str(path), "--param", "l=0", "--out", str(out)])
    assert res.exit_code == 2 and "pendulum.yaml:6" in res.output and "not finite" in res.output, res.output
    assert "Traceback" not in res.output and not out.exists()
