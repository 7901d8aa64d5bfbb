"""Malformed problem files: one clear error naming file, line and text; no run folder."""
import subprocess
import sys

import pytest

from ocdsl.api import compile_file
from ocdsl.spec.errors import SpecError

GOOD = """name: t
model:
  states: [x, v]
  controls: [u]
  dynamics:
    x: v
    v: u
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

# (description, replace old -> new, expected line, fragment of the message)
CASES = [
    ("unknown name", ("v: u", "v: w"), 7, "unknown name 'w'"),
    ("missing dynamics", ("    v: u\n", ""), 3, "state 'v' has no dynamics"),
    ("dynamics of a non-state", ("    v: u\n", "    v: u\n    q: x\n"), 8, "'q', which is not a state"),
    ("bad relation", ("- -1 <= u <= 1", "- -1 < u"), 11, "only <=, >= and =="),
    ("not a relation", ("- -1 <= u <= 1", "- u + 1"), 11, "must be a relation"),
    ("import", ("v: u", "v: __import__('os').system('true')"), 7, "not allowed"),
    ("attribute escape", ("v: u", "v: u.__class__"), 7, "not allowed"),
    ("huge exponent", ("v: u", "v: u**10**10"), 7, "too large"),
    ("non-finite number", ("v: u", "v: u*1e999"), 7, "non-finite"),
    ("wrong YAML type", ("segments: 4", "segments: [a, b]"), 18, "segments"),
    ("states not a list", ("states: [x, v]", "states: {x: 1}"), 3, "states"),
    ("unknown key", ("objective: minimize tf", "objectiv: minimize tf"), 17, "did you mean 'objective'"),
    ("unknown function", ("v: u", "v: sinn(u)"), 7, "did you mean 'sin'"),
    ("boundary of a control", ("x(tf) == 0", "u(tf) == 0"), 14, "'u' is not a state"),
    ("bare state in objective", ("minimize tf", "minimize x"), 17, "without a time"),
    ("YAML syntax", ("    v: u\n", "    v: [u\n"), None, "YAML syntax error"),
    ("empty range", ("0.1 <= tf <= 10", "10 <= tf <= 0.1"), 16, "empty range"),
    ("unknown transcription", ("transcription: LGR", "transcription: LGRR"), 18, "did you mean 'LGR'"),
    ("reserved name", ("states: [x, v]", "states: [x, sin]"), 3, "not a valid state name"),
    ("guess from a missing run", ("objective: minimize tf", "objective: minimize tf\n  guess: {from: no/such/run}"),
     18, "no run folder there"),
    ("bad method value", ("segments: 4, degree: 3", "segments: 4, degree: 0"), 18, "degree must be between"),
    ("misspelt Ipopt option", ("method: {", "solver: {options: {max_itr: 5}}\nmethod: {"), 18,
     "did you mean 'max_iter'"),
    ("bad mesh warm start", ("degree: 3}", "degree: 3, mesh: {tolerance: 1.0e-6, warm_start: multiplier}}"), 18,
     "warm_start: Input should be 'multipliers' or 'primal'"),
    # an integral is one number for the phase, a path constraint holds at each t (was: ok, then a
    # ValueError at the build)
    ("integral in a path constraint", ("- -1 <= u <= 1", "- -1 <= u <= 1\n    - integral(x) <= x"), 12,
     "cannot mix an integral"),
    ("constant link of a chain", ("- -1 <= u <= 1", "- u <= 1 <= 2"), 11, "the link `1 <= 2` of this chain"),
    # `-1 <= u >= 1` means u >= 1 (was: accepted silently)
    ("chain pointing both ways", ("- -1 <= u <= 1", "- -1 <= u >= 1"), 11, "must point one way"),
    # a bare state or control has no one value (was: accepted, nan at the run)
    ("expect of a bare state", ("method: {", "expect: {x: {value: 1, rtol: 1.0e-6}}\nmethod: {"), 18,
     "`x` varies along the phase, so `x` is no single number: expect a value at an end, e.g. x(tf)"),
    ("expect of a bare control", ("method: {", "expect: {u: {value: 1, rtol: 1.0e-6}}\nmethod: {"), 18,
     "expect an integral such as integral(u)"),
    ("strict link of a chain", ("- 0.1 <= tf <= 10", "- 0.1 <= tf < 10"), 16, "only <=, >= and =="),
    ("boundary value outside the state's bound", ("- -1 <= u <= 1", "- -1 <= u <= 1\n    - x >= 2"), 13,
     "contradicts the bound `x >= 2` (line 12)"),
    ("boundary range outside the state's bound", ("- -1 <= u <= 1", "- -1 <= u <= 1\n    - x <= 0.5"), 13,
     "contradicts the bound `x <= 0.5` (line 12)"),
    ("misspelt mesh key", ("degree: 3}", "degree: 3, mesh: {tolerence: 1.0e-6}}"), 18, "did you mean 'tolerance'"),
    ("misspelt method key", ("segments: 4", "segmnts: 4"), 18, "did you mean 'segments'"),
    ("time not a constant", ("tf: free}", "tf: 2*pix}"), 9, "`2*pix`: unknown name 'pix'; a time is a number, `free`"),
    ("time from a parameter", ("tf: free}", "tf: T}"), 9, "`T`: unknown name 'T'; a time is a number, `free`, or an expression of the file's constant parameters"),
    ("unit of an undeclared name", ("    v: u\n", "    v: u\n  units: {x: m, vv: m/s}\n"), 8,
     "a unit for 'vv', which the model does not declare (did you mean 'v'?)"),
    # a prime reads to Python as an unclosed string (was: "unterminated string literal")
    ("prime in a constraint", ("- -1 <= u <= 1", "- x' <= 1"), 11,
     "`'` is not allowed in an expression (`x'`): derivatives are written in `dynamics:`"),
    ("British spelling of minimize", ("objective: minimize tf", "objective: minimise tf"), 17,
     "`minimize EXPR` or `maximize EXPR` (did you mean 'minimize'?)"),
    # unseen24: each passed `check` or gave a misleading message
    ("integral inside an integral", ("objective: minimize tf", "objective: minimize integral(integral(u**2))"),
     17, "an integral inside an integral is not allowed"),
    ("a Python keyword as a name", ("states: [x, v]", "states: [x, lambda]"), 3, "not a valid state name"),
    ("a YAML boolean as a name", ("states: [x, v]", "states: [x, true]"), 3, "quote the name"),
    # unseen40 F1: pydantic read an unquoted true/false as 1/0 where a number or an expression
    # belongs (y' = 1, optimal and verified)
    ("a boolean as a right-hand side", ("v: u", "v: true"), 7, "unquoted true as a boolean"),
    ("a boolean as a time", ("tf: free}", "tf: false}"), 9, "unquoted false as a boolean"),
    ("a boolean as a parameter", ("method:", "parameters: {k: false}\nmethod:"), 18, "unquoted false"),
    # yes/no/on/off are text (YAML 1.2): an undeclared one is an unknown name, not 1 or 0
    ("a YAML 1.1 boolean word", ("v: u", "v: off"), 7, "unknown name 'off'"),
    # unseen41 F4: "unknown function 'z'"
    ("a boundary value of no state", ("- x(tf) == 0", "- xx(tf) == 0"), 14, "unknown name 'xx' (a boundary value "
                                                                          "is a state's or a control's"),
    # unseen41 F6: "... numbers and pi, e: boundary value 'np.float64(0.0866)' is not allowed here"
    ("a Python call as a parameter value", ("method:", "parameters: {k: np.float64(0.0866)}\nmethod:"), 18,
     "'np.float64(0.0866)' is not allowed: write the number"),
    # unseen40 F5: taken as it came
    ("guess times not increasing", ("objective: minimize tf", "objective: minimize tf\n  guess: {x: {t: [0, 2, 1], "
                                    "values: [1, 0, 0.5]}}"), 18, "its times t must increase"),
    ("a linear solver not installed", ("method: {", "solver: {options: {linear_solver: ma57}}\nmethod: {"), 18,
     "linear_solver ma57: its library"),
    ("not-equal relation", ("- -1 <= u <= 1", "- u != 1"), 11, "`!=` is not a constraint"),
    ("a file parameter named like a state", ("method: {", "parameters: {x: 1}\nmethod: {"), 18,
     "'x' is a state of the model and a parameter of the file"),
    ("a mesh beyond any machine", ("segments: 4, degree: 3", "segments: 100000000, degree: 3"), 18,
     "segments must be at most"),
]


@pytest.mark.parametrize("desc,change,line,fragment", CASES, ids=[c[0] for c in CASES])
def test_clear_error(tmp_path, desc, change, line, fragment):
    old, new = change
    assert old in GOOD
    p = tmp_path / "bad.yaml"
    p.write_text(GOOD.replace(old, new, 1))
    with pytest.raises(SpecError) as info:
        compile_file(p)
    text = str(info.value)
    assert fragment in text
    assert str(p) in text
    if line is not None:
        assert f"{p}:{line}:" in text, text


def test_good_file_compiles(tmp_path):
    p = tmp_path / "good.yaml"
    p.write_text(GOOD)
    assert compile_file(p).problem is not None


@pytest.mark.parametrize("desc,change,line,fragment", CASES[:6], ids=[c[0] for c in CASES[:6]])
def test_cli_exit_code_and_no_run_folder(tmp_path, desc, change, line, fragment):
    p = tmp_path / "bad.yaml"
    p.write_text(GOOD.replace(*change, 1))
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(p), "--out", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr + proc.stdout
    assert fragment in proc.stderr
    assert not out.exists()
    assert not any(tmp_path.glob(".run*")), "no half-written folder left beside it"


def test_check_command(tmp_path):
    p = tmp_path / "good.yaml"
    p.write_text(GOOD)
    proc = subprocess.run([sys.executable, "-m", "ocdsl.cli", "check", str(p)], capture_output=True, text=True)
    assert proc.returncode == 0 and "ok" in proc.stdout


def _issues(tmp_path, text: str) -> list:
    p = tmp_path / "f.yaml"
    p.write_text(text)
    with pytest.raises(SpecError) as e:
        compile_file(p)
    return e.value.issues


def test_a_broken_named_expression_is_reported_once_not_at_each_use(tmp_path):
    """`E` does not compile: F (which uses E) and the dynamics (which use E and F) get no
    "unknown name 'E'" of their own; an independent mistake is still reported in the same pass."""
    text = GOOD.replace("  dynamics:\n    x: v\n    v: u\n",
                        "  expressions:\n    E: v**2 + sqrtt(x)\n    F: 2*E\n    G: cosh(u, v)\n"
                        "  dynamics:\n    x: v + F\n    v: u + E + G + w\n")
    issues = _issues(tmp_path, text)
    assert [(i.line, i.message.split(" (")[0]) for i in issues] == [
        (6, "unknown function 'sqrtt'"), (8, issues[1].message.split(" (")[0]), (11, "unknown name 'w'")], issues
    assert "cosh" in issues[1].message
    assert not any("'E'" in i.message or "'F'" in i.message or "'G'" in i.message for i in issues), issues


def test_a_broken_table_is_reported_once_not_at_each_use(tmp_path):
    text = GOOD.replace("  dynamics:\n    x: v\n    v: u\n",
                        "  dynamics:\n    x: v + T(x)\n    v: u + T(v)\n").replace(
        "problem:", "tables:\n  T: {x: [0, 1, 2], values: [1, 2]}\nproblem:")
    issues = _issues(tmp_path, text)
    assert len(issues) == 1 and issues[0].line is not None and "T" in str(issues[0]), issues
    assert "has an error" not in str(issues[0])


@pytest.mark.parametrize("objective, line", [("minimize integral(abs(u))", 17),
                                             ("minimize tf + integral(2*L)", 17)])
def test_an_l1_integral_is_refused_with_the_split_as_hint(tmp_path, objective, line):
    """integral(abs(u)) makes Ipopt stop with "error" (abs has no derivative at 0, where an
    L1 optimum sits): `check` refuses it at the objective's line, also through a named
    expression, and says how to write it smoothly."""
    text = GOOD.replace("minimize tf", objective).replace("  dynamics:", "  expressions: {L: abs(u) + 1}\n  dynamics:")
    issues = _issues(tmp_path, text)
    assert len(issues) == 1, issues
    assert issues[0].line == line + 1 and "abs() in an integral" in issues[0].message, issues
    assert "integral(up + um)" in issues[0].message
    p = subprocess.run([sys.executable, "-m", "ocdsl.cli", "check", str(tmp_path / "f.yaml")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr and "abs() in an integral" in p.stderr


def test_a_time_may_be_a_constant_expression(tmp_path):
    """`tf: 2*pi` (the safe parser, constants only) is the number it stands for."""
    import math

    p = tmp_path / "f.yaml"
    p.write_text(GOOD.replace("tf: free}", "tf: 2*pi}").replace(
        "objective: minimize tf", "objective: minimize integral(u**2)\n  guess: {tf: sqrt(2)}"))
    ph = compile_file(p).problem.phases[0]
    assert ph.tf == pytest.approx(2 * math.pi, rel=1e-15) and ph.t0 == 0.0
    assert ph.guess["tf"] == pytest.approx(math.sqrt(2), rel=1e-15)


def test_a_misspelt_phase_time_is_taken_for_a_misspelt_tf():
    """`brake.tff` (an expect key, a link): did you mean tf, not "use brake.tff(t0)" alone."""
    import sympy as sp

    from ocdsl.spec.errors import ExprError
    from ocdsl.spec.expr import Scope, parse_expression

    scope = Scope({}, phases={"brake": {"t0": sp.Symbol("brake.t0"), "tf": sp.Symbol("brake.tf")}})
    assert parse_expression("brake.tf", scope) == sp.Symbol("brake.tf")
    with pytest.raises(ExprError) as e:
        parse_expression("brake.tff", scope)
    assert "did you mean 'tf'" in e.value.message and "brake.tff(tf)" in e.value.message


def test_reversed_bounds_of_a_free_parameter_say_so(tmp_path):
    """`p: {free: true, bounds: [2, -2]}` is a ParameterSpec with empty bounds, not a number
    that failed to parse: the validator's message, not the float member's (unseen3 e07)."""
    text = ("name: t\nparameters:\n  p: {value: 0.5, free: true, bounds: [2, -2]}\n"
            "model:\n  states: [x]\n  controls: [u]\n  dynamics: {x: u}\n"
            "problem:\n  time: {t0: 0, tf: 1}\n  constraints:\n    - x(t0) == 0\n    - x(tf) == p\n"
            "  objective: minimize integral(u**2)\n")
    issues = _issues(tmp_path, text)
    first = issues[0]
    assert first.line == 3 and "bounds reversed" in first.message, issues
    assert not any("valid number" in i.message for i in issues), issues


_FIXED_TIME = ("name: t\nmodel:\n  states: [x, v]\n  controls: [u]\n  dynamics: {x: v, v: u}\n"
               "problem:\n  time: {t0: 0, tf: 2}\n  constraints:\n    - -1 <= u <= 1\n"
               "    - x(t0) == 1\n    - v(t0) == 0\n    - x(tf) == 0\n    - v(tf) == 0\n"
               "  objective: minimize tf\n")


def test_an_objective_fixed_to_a_constant_is_refused(tmp_path):
    """`minimize tf` with `tf: 2` optimises nothing: it was accepted, and the run failed with a
    mesh hint and an arbitrary control (unseen3 e17). Check refuses it at the objective's line."""
    issues = _issues(tmp_path, _FIXED_TIME)
    assert len(issues) == 1, issues
    assert issues[0].line == 14 and "constant (tf = 2, fixed)" in issues[0].message, issues


def test_a_bare_number_objective_and_a_free_time_are_accepted(tmp_path):
    """The refusal is for an objective that names something fixed: `minimize 0` (a
    feasibility problem) and `minimize tf` with tf free still load."""
    for text in (_FIXED_TIME.replace("minimize tf", "minimize 0"),
                 _FIXED_TIME.replace("tf: 2}", "tf: free}")):
        path = tmp_path / "ok.yaml"
        path.write_text(text)
        compile_file(path)


def test_an_unknown_phase_in_an_expect_key_is_named(tmp_path):
    """`rech.tf` in `expect:` of a multi-phase file said "'rech.tf' is not allowed"; a misspelt
    phase is now named as such, with the phase it most likely means (unseen3)."""
    from pathlib import Path

    text = (Path(__file__).parents[1] / "configs" / "lit_bryson_denham_three_phase.yaml").read_text()
    assert "\nexpect:\n" in text
    issues = _issues(tmp_path, text.replace("\nexpect:\n", "\nexpect:\n  rech.tf: {value: 1.0}\n"))
    assert len(issues) == 1 and "unknown phase 'rech' (did you mean 'reach'?)" in issues[0].message, issues


def test_a_bare_number_in_expect_is_the_value_with_the_default_tolerance(tmp_path):
    """`expect: {tf: 2.0}` said "Input should be a valid dictionary or instance of ExpectItem"
    (unseen2): it is the value, checked with the documented default rtol 1e-6."""
    from pathlib import Path

    text = (Path(__file__).parents[1] / "configs" / "minimal_double_integrator.yaml").read_text()
    assert "  tf: {value: 2.0, rtol: 1.0e-4}\n" in text
    path = tmp_path / "f.yaml"
    path.write_text(text.replace("  tf: {value: 2.0, rtol: 1.0e-4}\n", "  tf: 2.0\n"))
    item = compile_file(path).spec.expect["tf"]
    assert (item.value, item.rtol, item.atol, item.compare) == (2.0, None, None, "equal")
    path.write_text(text.replace("  tf: {value: 2.0, rtol: 1.0e-4}\n", "  tf: true\n"))
    with pytest.raises(SpecError):
        compile_file(path)


def test_a_name_declared_as_a_scalar_is_one_error_not_a_knock_on(tmp_path):
    """`controls: u` (not a list) is one error with the list it meant; the dynamics' use of
    `u` is not reported as an unknown name, while an independent mistake still is."""
    text = GOOD.replace("controls: [u]", "controls: u")
    assert text != GOOD
    issues = _issues(tmp_path, text)
    assert [i.message for i in issues] == ["model.controls: a list of names is expected, e.g. controls: [u]"], issues
    issues = _issues(tmp_path, text.replace("v: u\n", "v: u + q\n"))
    assert [i.message.split(" (")[0] for i in issues] == [
        "model.controls: a list of names is expected, e.g. controls: [u]", "unknown name 'q'"], issues


def test_a_dynamics_mistake_does_not_hide_the_objectives(tmp_path):
    """An unknown name in the dynamics and an unknown function in the objective: both are
    reported in one pass (the objective used to go unchecked until the dynamics were fixed),
    and nothing else."""
    text = ("name: two\nmodel:\n  states: [x]\n  controls: [u]\n  dynamics: {x: u + yy}\n"
            "problem:\n  time: {t0: 0, tf: 1}\n  constraints: [x(t0) == 0, x(tf) == 1]\n"
            "  objective: minimize integral(u**2 + sinn(x))\n")
    issues = _issues(tmp_path, text)
    assert [(i.line, i.message.split(" (")[0]) for i in issues] == [
        (5, "unknown name 'yy'"), (9, "unknown function 'sinn'")], issues


def test_an_unclosed_bracket_is_reported_where_it_opens(tmp_path):
    """`time: {t0: 0, tf: 1` (no `}`): PyYAML stops at the next line's token; the error names
    the line of the bracket, where the fix goes (unseen4 reported the line after it)."""
    text = GOOD.replace("time: {t0: 0, tf: free}", "time: {t0: 0, tf: free")
    assert text != GOOD
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "time: {t0: 0, tf: free" in ln)
    (issue,) = _issues(tmp_path, text)
    assert issue.line == line and "'{' opened here is not closed" in issue.message, issue
    text = GOOD.replace("states: [x, v]", "states: [x, v")
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "states: [x, v" in ln)
    (issue,) = _issues(tmp_path, text)
    assert issue.line == line and "'[' opened here is not closed" in issue.message, issue


TWO_PHASE_COST = """name: two-phase minimum energy
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
phases:
  full:
    time: {t0: 0, tf: 1}
    constraints: [x(t0) == 0, v(t0) == 0]
  half:
    time: {t0: 1, tf: 2}
    constraints: [x(tf) == 1, v(tf) == 0]
links: [full.x(tf) == half.x(t0), full.v(tf) == half.v(t0)]
method: {transcription: LGR, segments: 4, degree: 5}
objective: minimize full.integral(u**2) + half.integral(u**2)
"""


def test_a_phase_integral_in_the_top_level_objective_says_where_it_is_written(tmp_path):
    """unseen5: `full.integral(u**2)` read as a boundary value ("a boundary value is written
    integral(t0) or integral(tf)"); it now names the phase's own objective, and that form
    compiles to the sum of the phases' costs."""
    p = tmp_path / "two.yaml"
    p.write_text(TWO_PHASE_COST)
    with pytest.raises(SpecError) as info:
        compile_file(p)
    text = str(info.value)
    assert f"{p}:15:" in text and "phases: {full: {objective: integral(u ** 2)}}" in text, text
    # in a constraint the way out is a state carrying the integral (unseen39 F5: only the
    # objective's way was said)
    budget = TWO_PHASE_COST.replace("links: [", "links: [full.integral(u**2) + half.integral(u**2) <= 16, ")
    p.write_text(budget)
    with pytest.raises(SpecError, match=r"carry the integral as a state: a state E with dynamics `E: u \*\* 2`"):
        compile_file(p)
    fixed = TWO_PHASE_COST.replace("objective: minimize full.integral(u**2) + half.integral(u**2)",
                                   "objective: minimize 0").replace(
        "    constraints: [x(t0) == 0, v(t0) == 0]", "    constraints: [x(t0) == 0, v(t0) == 0]\n    objective: integral(u**2)"
    ).replace("    constraints: [x(tf) == 1, v(tf) == 0]", "    constraints: [x(tf) == 1, v(tf) == 0]\n    objective: integral(u**2)")
    p.write_text(fixed)
    assert compile_file(p).problem.objective.expr.free_symbols      # both integrals in it


def test_a_time_may_name_a_constant_parameter(tmp_path):
    """unseen9 F11: `tf: T` with `parameters: {T: 1.0}` said "unknown name 'T'" of a declared
    parameter; it is the parameter's value (and --param or a sweep changes it)."""
    text = ("name: t\nparameters: {T: 1.5}\nmodel:\n  states: [x]\n  controls: [u]\n  dynamics: {x: u}\n"
            "problem:\n  time: {t0: 0, tf: 2*T}\n  constraints: [x(t0) == 0, x(tf) == 1]\n"
            "  objective: minimize integral(u**2)\n")
    p = tmp_path / "f.yaml"
    p.write_text(text)
    assert compile_file(p).problem.phases[0].tf == 3.0
    assert compile_file(p, {"T": 2.0}).problem.phases[0].tf == 4.0
    p.write_text(text.replace("tf: 2*T", "tf: 2*TT"))
    with pytest.raises(SpecError, match=r"f.yaml:8: .*`2\*TT`: unknown name 'TT'.*did you mean 'T'"):
        compile_file(p)


def test_a_vector_literal_in_a_flow_list_says_how_to_write_it(tmp_path):
    """unseen10 F6: `[r(t0) == [1, 0.5], ...]` is a YAML error whose message did not say why."""
    p = tmp_path / "f.yaml"
    p.write_text("name: v\nmodel:\n  states: [r]\n  controls: [u]\n  dynamics: {r: u}\nproblem:\n"
                 "  time: {t0: 0, tf: 1}\n  constraints: [r(t0) == [1, 0.5], r(tf) == 0]\n"
                 "  objective: minimize integral(u**2)\n")
    with pytest.raises(SpecError, match=r"f.yaml:8: YAML syntax error: .*write the relations one per line"):
        compile_file(p)


def test_a_boundary_values_t0_or_tf_is_not_listed_as_an_unknown_name(tmp_path):
    """unseen29: an undefined weight in a top-level objective of two phases was reported with
    'tf' beside it, and tf's explanation about dynamics (`-b.x(tf) + cc*b.v(tf)**2`)."""
    p = tmp_path / "w.yaml"
    p.write_text("""name: two phases
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
phases:
  a:
    time: {t0: 0, tf: 1}
    constraints: [x(t0) == 0, v(t0) == 0, -1 <= u <= 1]
  b:
    time: {t0: 1, tf: 2}
    constraints: [v(tf) == 0, -1 <= u <= 1]
links:
  - continuous(a, b)
objective: minimize -b.x(tf) + cc*b.v(tf)**2
""")
    with pytest.raises(SpecError) as e:
        compile_file(p)
    (issue,) = e.value.issues
    assert issue.line == 12 and issue.message == "unknown name 'cc'", issue.message


def test_a_degree_suffix_in_an_expression_says_where_it_is_read(tmp_path):
    """unseen29: `x(tf) == 10deg` in a problem constraint was only 'syntax error (invalid
    decimal literal)'; the suffix is read in a controller's numbers alone."""
    p = tmp_path / "deg.yaml"
    p.write_text("""name: d
model:
  states: [x]
  controls: [u]
  dynamics: {x: u}
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, x(tf) == 10deg]
  objective: minimize integral(u**2)
""")
    with pytest.raises(SpecError) as e:
        compile_file(p)
    (issue,) = e.value.issues
    assert issue.line == 8 and "controller" in issue.message and "10*pi/180" in issue.message, issue.message


def test_a_free_parameter_as_a_time_says_how_to_write_it(tmp_path):
    """unseen34 F9: `tf: T` with T a declared free parameter said "unknown name 'T'"; T is known,
    it only cannot set a time. The error says so, with the way to write it."""
    from ocdsl.spec.compile import load
    from ocdsl.spec.errors import SpecError

    path = tmp_path / "t.yaml"
    path.write_text("name: t\nparameters:\n  T: {value: 2, free: true, bounds: [1, 3]}\nmodel:\n  states: [x]\n"
                    "  controls: [u]\n  dynamics: {x: u}\nproblem:\n  time: {t0: 0, tf: T}\n"
                    "  constraints: [x(t0) == 0, x(tf) == 1]\n  objective: minimize integral(u**2) + T\n")
    with pytest.raises(SpecError) as e:
        load(path)
    (issue,) = e.value.issues
    assert issue.line == 9 and "T is a free parameter, which cannot set a time; write `tf: free`" in issue.message


def test_yes_no_on_off_are_names_as_in_yaml_1_2(tmp_path):
    """unseen40 F1: a state declared 'on' and written unquoted in the dynamics (`x: on`) was
    YAML 1.1's boolean true, solved as x' = 1 (J = -1, optimal and verified, against -1/12)."""
    p = tmp_path / "on.yaml"
    p.write_text(GOOD.replace("states: [x, v]", "states: [x, 'on']").replace("x: v", "x: on")
                 .replace("v: u", "'on': u").replace("v(t0)", "on(t0)").replace("v(tf)", "on(tf)"))
    phase = compile_file(p).problem.phases[0]
    rhs = dict(zip(map(str, phase.states), phase.rhs()))
    assert rhs["x"] == phase.states[1] and str(rhs["x"]) == "on"


def test_an_ipopt_yes_no_option_is_taken_either_way(tmp_path):
    """Ipopt's yes/no options take YAML's `true` (the word yes) and the text `yes` alike."""
    for word in ("yes", "true", "'yes'"):
        p = tmp_path / f"o_{word.strip(chr(39))}.yaml"
        p.write_text(GOOD + f"solver: {{options: {{warm_start_init_point: {word}}}}}\n")
        assert compile_file(p).spec.solver.options["warm_start_init_point"] == "yes"
