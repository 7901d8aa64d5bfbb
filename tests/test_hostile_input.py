"""Hostile and careless input (issue 27): meaningless numbers refused, bounds intersected,
input limits checked before expensive work, every error one SpecError with a line."""
from __future__ import annotations

import pytest

from ocdsl.api import compile_file
from ocdsl.spec.errors import SpecError

GOOD = """name: t
model:
  states: [x, v]
  controls: [u]
  parameters:
    k: {value: 1.0, free: true, bounds: [0.5, 2]}
  dynamics:
    x: v
    v: k*u
problem:
  time: {t0: 0, tf: free}
  constraints:
    - -1 <= u <= 1
    - x(t0) == 1
    - v(t0) == 0
    - x(tf) == 0
    - v(tf) == 0
    - 0.1 <= tf <= 10
  objective: minimize tf
method: {transcription: LGR, segments: 4, degree: 3}
"""


def variant(tmp_path, old: str, new: str, text: str = GOOD):
    assert old in text, old
    p = tmp_path / "problem.yaml"
    p.write_text(text.replace(old, new, 1))
    return p


def error_of(path) -> SpecError:
    with pytest.raises(SpecError) as e:
        compile_file(path)
    return e.value


def line_of(text: str, fragment: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if fragment in line)


# (old -> new, fragment of the line the error names, fragment of its message)
MEANINGLESS = [
    ("t0: 0, tf: free", "t0: .nan, tf: free", "time:", "finite"),
    ("t0: 0, tf: free", "t0: 0, tf: .inf", "time:", "finite"),
    ("t0: 0, tf: free", "t0: -.inf, tf: free", "time:", "finite"),
    ("bounds: [0.5, 2]", "bounds: [.nan, .nan]", "bounds:", "finite"),
    ("bounds: [0.5, 2]", "bounds: [0.5, .inf]", "bounds:", "finite"),
    ("value: 1.0, free", "value: .nan, free", "value:", "finite"),
    ("  objective: minimize tf", "  objective: minimize tf\n  guess: {tf: .nan}", "guess:", "finite"),
    ("  objective: minimize tf", "  objective: minimize tf\n  guess: {x: [0, .inf]}", "guess:", "finite"),
    ("    v: k*u", "    v: k*u*sqrt(-1)", "v: k*u", "complex"),
    ("- x(t0) == 1", "- x(t0) == sqrt(-1)", "x(t0) ==", "complex"),
    ("- x(t0) == 1", "- x(t0) == log(-2)", "x(t0) ==", "complex"),
    ("- x(t0) == 1", "- x(t0) == acos(2)", "x(t0) ==", "complex"),
]


@pytest.mark.parametrize("old,new,where,message", MEANINGLESS, ids=[c[1] for c in MEANINGLESS])
def test_meaningless_numbers_are_refused_at_their_line(tmp_path, old, new, where, message):
    p = variant(tmp_path, old, new)
    err = error_of(p)
    text = p.read_text()
    assert any(message in i.message for i in err.issues), str(err)
    assert err.issues[0].line == line_of(text, where), str(err)


def test_later_bound_on_tf_narrows_never_replaces(tmp_path):
    p = variant(tmp_path, "    - 0.1 <= tf <= 10", "    - 2.5 <= tf <= 10\n    - tf <= 20")
    ph = compile_file(p).problem.phases[0]
    assert ph.tf_bounds == (2.5, 10.0)


def test_later_bound_on_a_state_narrows(tmp_path):
    p = variant(tmp_path, "    - -1 <= u <= 1", "    - -1 <= u <= 1\n    - u <= 5\n    - -0.5 <= u")
    ph = compile_file(p).problem.phases[0]
    assert ph.control_bounds[ph.controls[0]] == (-0.5, 1.0)


@pytest.mark.parametrize("old,new,first,second", [
    ("    - 0.1 <= tf <= 10", "    - 2.5 <= tf <= 10\n    - tf >= 12", "2.5 <= tf", "tf >= 12"),
    ("    - -1 <= u <= 1", "    - -1 <= u <= 1\n    - u >= 3", "-1 <= u", "u >= 3"),
])
def test_contradictory_bounds_name_both_constraints(tmp_path, old, new, first, second):
    p = variant(tmp_path, old, new)
    err = error_of(p)
    issue = err.issues[0]
    assert issue.line == line_of(p.read_text(), second)
    assert first in issue.message and "contradict" in issue.message, str(err)


@pytest.mark.parametrize("bound", ["tf <= 0", "tf <= -3", "-5 <= tf <= 0"])
def test_final_time_at_or_before_a_fixed_start_is_refused(tmp_path, bound):
    p = variant(tmp_path, "    - 0.1 <= tf <= 10", f"    - {bound}")
    err = error_of(p)
    assert err.issues[0].line == line_of(p.read_text(), bound)
    assert "t0 = 0" in err.issues[0].message, str(err)


# -- Pareto files: the sections outside pareto: are compiled like a problem file's ---------
from conftest import CONFIGS  # noqa: E402
from ocdsl.spec.pareto import load_pareto  # noqa: E402

INLINE = """model:
  states: [r_av, L_av, l_x, l_y]
  controls: [delta]
  dynamics: {r_av: delta, L_av: -3/2*r_av, l_x: -l_y - delta, l_y: 1/0}
"""


@pytest.mark.parametrize("config,old,new,where,message", [
    ("seed4_case_A.yaml", "    - burn2.l_y(tf) == 0", "    - __import__('os').system('true') == 0",
     "__import__", "not allowed"),
    ("seed4_case_A.yaml", "model:\n  use: relative_motion_secular\n", INLINE, "l_y: 1/0", "division by zero"),
    ("seed4_case_A.yaml", "fix: {delta: s1}", "fix: {delta: sqrt(-1)}", "burn1:", "complex"),
    ("seed4_case_A.yaml", "  r0: -0.5 ", "  r0: .nan ", "r0:", "finite"),
    ("seed4_two_burn_nlp.yaml", "      - delta == s1", "      - __import__('os') == 0", "__import__", "unknown function"),
    ("seed4_unrestricted.yaml", "    r_av: dp - dm", "    r_av: dp - dm + 1/0", "r_av: dp - dm", "division by zero"),
])
def test_pareto_files_are_compiled_whole(tmp_path, config, old, new, where, message):
    p = variant(tmp_path, old, new, (CONFIGS / config).read_text())
    with pytest.raises(SpecError) as e:
        load_pareto(p)
    issue = e.value.issues[0]
    assert message in issue.message and issue.line == line_of(p.read_text(), where), str(e.value)
