"""A file's independent mistakes come in one pass (issue 28): a misspelt key, a bad method
setting and a bad expression elsewhere are reported together, in line order, each once."""
import textwrap

import pytest

from ocdsl.spec.compile import load
from ocdsl.spec.errors import SpecError


def _errors(tmp_path, text: str) -> list:
    p = tmp_path / "p.yaml"
    p.write_text(textwrap.dedent(text))
    with pytest.raises(SpecError) as e:
        load(p)
    return e.value.issues


def test_schema_method_and_expression_mistakes_in_one_pass(tmp_path):
    issues = _errors(tmp_path, """\
        name: three mistakes
        model:
          states: [x, v]
          controls: [u]
          dynamics: {x: v, v: u}
        problem:
          time: {t0: 0, tf: free}
          constraint: [x(t0) == 1]
          objective: minimize tff
        method: {transcription: LGR, segmnts: 4}
        """)
    msgs = [(i.line, i.message) for i in issues]
    assert [line for line, _ in msgs] == [8, 9, 10]
    assert "unknown key 'constraint' (did you mean 'constraints'?)" in msgs[0][1]
    assert "unknown name 'tff' (did you mean 'tf'?)" in msgs[1][1]
    assert "unknown key 'segmnts'" in msgs[2][1]


def test_a_value_of_no_union_type_is_one_issue_with_the_comma_hint(tmp_path):
    issues = _errors(tmp_path, """\
        name: comma
        model:
          states: [x]
          controls: [u]
          expressions: {a: atan2(x, u)}
          dynamics: {x: a}
        problem:
          time: {t0: 0, tf: 1}
          constraints: [x(t0) == 1]
          objective: minimize x(tf)
        """)
    schema = [i for i in issues if "model.expressions" in i.message]
    assert len(schema) == 1 and "quote an expression with commas" in schema[0].message


def test_a_missing_required_key_still_reports_alone(tmp_path):
    issues = _errors(tmp_path, """\
        name: no objective
        model: {states: [x], dynamics: {x: 1}}
        problem:
          time: {t0: 0, tf: 1}
        """)
    assert len(issues) == 1 and "missing required key 'objective'" in issues[0].message


def test_an_anchored_list_of_constraints_is_spliced_and_errors_keep_its_lines(tmp_path):
    text = """\
        name: shared bounds
        definitions:
          bounds: &bounds
            - -1 <= u <= 1
            - v <= 2
        model:
          states: [x, v]
          controls: [u]
          dynamics: {x: v, v: u}
        problem:
          time: {t0: 0, tf: free}
          constraints:
            - *bounds
            - x(t0) == -1
            - v(t0) == 0
            - x(tf) == 0
            - v(tf) == 0
            - 0.1 <= tf <= 5
          objective: minimize tf
        """
    p = tmp_path / "p.yaml"
    p.write_text(textwrap.dedent(text))
    ph = load(p).problem.phases[0]
    assert {s.name: b for s, b in ph.control_bounds.items()} == {"u": (-1.0, 1.0)}
    assert {s.name: b for s, b in ph.state_bounds.items()}["v"][1] == 2.0
    issues = _errors(tmp_path, text.replace("- v <= 2", "- w <= 2"))
    assert [(i.line, "unknown name 'w'" in i.message) for i in issues] == [(5, True)]


@pytest.mark.parametrize("dynamics, model_message", [
    ("{x: v, v: u}", "state 'w' has no dynamics"),
    ("{x: v, v: u, w: 0, q: 1}", "dynamics given for 'q', which is not a state"),
])
def test_a_dynamics_mistake_leaves_the_constraints_and_objective_checked(tmp_path, dynamics, model_message):
    """unseen10 F5: a state without dynamics (or dynamics of a non-state) hid the strict
    inequality and the unknown name below it until it was fixed."""
    issues = _errors(tmp_path, f"""\
        name: misc
        model:
          states: [x, v, w]
          controls: [u]
          dynamics: {dynamics}
        problem:
          time: {{t0: 0, tf: 2}}
          constraints: [x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0, u < 1]
          objective: minimize integral(u**2 + gain*x)
        """)
    msgs = [(i.line, i.message) for i in issues]
    assert len(msgs) == 3, msgs
    assert model_message in msgs[0][1]
    assert msgs[1][0] == 8 and "strict" in msgs[1][1]
    assert msgs[2][0] == 9 and "unknown name 'gain'" in msgs[2][1]


def _with_options(tmp_path, options: str):
    from ocdsl.spec.compile import load

    p = tmp_path / "o.yaml"
    p.write_text(textwrap.dedent(f"""\
        name: options
        model: {{states: [x], controls: [u], dynamics: {{x: u}}}}
        problem:
          time: {{t0: 0, tf: 1}}
          constraints: [x(t0) == 1]
          objective: minimize integral(x**2 + u**2)
        solver:
          options: {options}
        """))
    return load(p)


def test_ipopt_option_values_are_checked_and_yaml_spellings_taken(tmp_path):
    """unseen12 F4: `tol: 1e-10` (a string to YAML), `max_iter: 500.0`, `print_timing_statistics:
    no` (a boolean to YAML) passed `ocdsl check`, then Ipopt refused them after the build
    (status error, a run folder); a misspelt value or one out of range likewise. Now the
    spellings a user means are taken, and the rest refused at the line, all in one message."""
    f = _with_options(tmp_path, "{tol: 1e-10, max_iter: 500.0, print_timing_statistics: no, "
                                "mu_strategy: adaptive, linear_solver: mumps}")
    assert f.spec.solver.options == {"tol": 1e-10, "max_iter": 500, "print_timing_statistics": "no",
                                     "mu_strategy": "adaptive", "linear_solver": "mumps"}
    assert isinstance(f.spec.solver.options["max_iter"], int)
    with pytest.raises(SpecError) as e:
        _with_options(tmp_path, "{tol: -1.0, max_iter: 2.5, mu_strategy: adaptve, print_level: 13, max_itr: 5}")
    (issue,) = e.value.issues
    assert issue.line == 8
    for part in ("'tol' must be > 0", "'max_iter' takes an integer", "did you mean 'adaptive'",
                 "'print_level' must be <= 12", "unknown Ipopt option 'max_itr'"):
        assert part in issue.message, issue.message


def test_every_unknown_name_of_an_expression_in_one_message(tmp_path):
    """unseen12 F6: `uu + q + zz` reported `uu`, then `q`, then `zz`, one run each."""
    issues = _errors(tmp_path, """\
        name: names
        model: {states: [x, v], controls: [u], dynamics: {x: v, v: uu + q + zz}}
        problem:
          time: {t0: 0, tf: 1}
          constraints: [x(t0) == 1, x(tf) == 0]
          objective: minimize integral(u**2)
        """)
    (issue,) = issues
    assert issue.line == 2 and issue.message.startswith("unknown names 'uu' (did you mean 'u'?), 'q', 'zz'"), issue


def test_named_expressions_may_come_in_any_order_and_a_cycle_is_refused(tmp_path):
    """unseen12 F6: `acc: u*k + drag` written above `drag: ...` was 'unknown name drag'."""
    from ocdsl.spec.compile import load

    p = tmp_path / "order.yaml"
    p.write_text(textwrap.dedent("""\
        name: order
        model:
          states: [x, v]
          controls: [u]
          parameters: {k: 2}
          expressions:
            acc: u*k + drag
            drag: -0.1*v
          dynamics: {x: v, v: acc}
        problem:
          time: {t0: 0, tf: 1}
          constraints: [x(t0) == 1, v(t0) == 0]
          objective: minimize integral(u**2) + x(tf)**2
        """))
    model = load(p).problem.phases[0].model
    assert [str(s) for s in model.expressions] == ["drag", "acc"]
    issues = _errors(tmp_path, """\
        name: cycle
        model:
          states: [x]
          controls: [u]
          expressions: {c: a + 1, a: b + 1, b: a*2}
          dynamics: {x: u + c}
        problem:
          time: {t0: 0, tf: 1}
          constraints: [x(t0) == 1]
          objective: minimize integral(u**2) + zz
        """)
    msgs = [(i.line, i.message) for i in issues]
    assert [m for _, m in msgs][:2] == ["'a' is defined through itself (a cycle of named expressions: a, b)",
                                        "'b' is defined through itself (a cycle of named expressions: a, b)"]
    assert msgs[2][0] == 10 and "unknown name 'zz'" in msgs[2][1] and len(msgs) == 3   # nothing cascades


def test_parameters_may_be_constant_expressions_and_a_bad_one_does_not_cascade(tmp_path):
    """unseen12 F8: `parameters: {c: 2*pi}` was 'unable to parse string as a number' (the
    docs allow `tf: 2*pi`), and every refused parameter added a false 'unknown name c'."""
    import math

    from ocdsl.spec.compile import load

    text = """\
        name: constants
        parameters: {{c: {c}, d: {{value: 9.81/2, free: true, bounds: [0, 10]}}}}
        model: {{states: [x], controls: [u], dynamics: {{x: c*u + d}}}}
        problem:
          time: {{t0: 0, tf: 1}}
          constraints: [x(t0) == 1]
          objective: minimize integral(x**2 + u**2){extra}
        """
    p = tmp_path / "c.yaml"
    p.write_text(textwrap.dedent(text.format(c="2*pi", extra="")))
    f = load(p)
    assert f.spec.parameters["c"] == 2 * math.pi and f.spec.parameters["d"].value == 9.81 / 2
    for bad, why in (("1/0", "division by zero"), ("sqrt(-1)", "complex value"), ("2*g", "unknown name 'g'")):
        issues = _errors(tmp_path, text.format(c=bad, extra=" + zz"))
        msgs = [(i.line, i.message) for i in issues]
        assert len(msgs) == 2 and msgs[0][0] == 2 and why in msgs[0][1], msgs
        assert msgs[1] == (7, "unknown name 'zz'"), msgs


def test_a_unit_written_in_a_bound_gets_a_hint(tmp_path):
    """unseen12 F11: `-1 m/s**2 <= u` was a bare 'syntax error (invalid syntax)'."""
    issues = _errors(tmp_path, """\
        name: units
        model: {states: [x], controls: [u], dynamics: {x: u}}
        problem:
          time: {t0: 0, tf: 1}
          constraints: [x(t0) == 1, -1 m/s**2 <= u <= 1]
          objective: minimize integral(x**2 + u**2)
        """)
    (issue,) = issues
    assert issue.line == 5 and "units are not written in expressions" in issue.message, issue


def test_a_bad_method_comes_with_the_schema_mistakes_that_stop_the_compile(tmp_path):
    """unseen12 F6: with a required key missing (`objectiv:`), `transcription: LGX` was
    reported only on the next run."""
    issues = _errors(tmp_path, """\
        name: typos
        model:
          states: [x, v]
          controls: [u]
          dynamic: {x: v, v: u}
        problem:
          time: {t0: 0, tf: free}
          constraints: [-1 <= u <= 1, x(t0) == 1]
          objectiv: minimize tf
        method: {transcription: LGX, segments: 10, degree: 5}
        """)
    msgs = [(i.line, i.message) for i in issues]
    assert msgs[-1][0] == 10 and "unknown transcription 'LGX'" in msgs[-1][1], msgs
    assert any("unknown key 'dynamic'" in m for _, m in msgs) and any("'objectiv'" in m for _, m in msgs)
