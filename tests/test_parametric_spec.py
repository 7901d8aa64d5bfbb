"""method: parametric: clear errors for bad input (file and line named)."""
from pathlib import Path

import pytest

from ocdsl.spec.compile import load
from ocdsl.spec.errors import SpecError
from ocdsl.spec.parametric import ParametricSpec

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "seed1_10N_paper.yaml"


def _variant(tmp_path, old, new):
    text = CONFIG.read_text()
    assert old in text
    p = tmp_path / "bad.yaml"
    p.write_text(text.replace(old, new))
    line = next(i + 1 for i, l in enumerate(p.read_text().splitlines()) if new.strip().split(":")[0] in l and new.strip() in l)
    return p, line


@pytest.mark.parametrize("old,new,words", [
    ("delta: {series: fourier, order: 5,", "delta: {series: fourier, order: -1,", "order"),
    ("tolerances: {r: 1.0e-3,", "tolerances: {r: 0.0,", "zeta"),
    ("    particles: 64", "    particles: 1", "particles"),
    ("    c1: 2.0", "    c1: 7.5", "c1"),
    ("    inertia: [0.9, 0.4]", "    inertia: [1.9, 0.4]", "inertia"),
    ("    velocity_limit: 0.2", "    velocity_limit: 0.0", "velocity_limit"),
])
def test_bad_input_names_file_and_line(tmp_path, old, new, words):
    p, line = _variant(tmp_path, old, new)
    with pytest.raises(SpecError) as e:
        load(p)
    msg = str(e.value)
    # the file and a line: the offending line, or (while the spec layer reports method
    # errors at the block) the line of ``method:``
    method_line = next(i + 1 for i, l in enumerate(p.read_text().splitlines()) if l.startswith("method:"))
    assert f"bad.yaml:{line}" in msg or f"bad.yaml:{method_line}" in msg, msg
    assert words in msg, msg


def test_integer_parameter_without_bounds():
    with pytest.raises(ValueError, match="integer parameter needs bounds"):
        ParametricSpec.model_validate({"controls": {"u": {"order": 2}}, "parameters": {"N": {"integer": True}}})


def test_an_infinite_integer_bound_is_an_error_not_an_overflow():
    """Fuzzing (`bounds: [10, .inf]` on an integer parameter): int(inf) raised OverflowError,
    a traceback from `ocdsl check`, where the file wants one error at its line."""
    with pytest.raises(ValueError, match="integer parameter bounds must be finite integers"):
        ParametricSpec.model_validate({"controls": {"u": {"order": 2}},
                                       "parameters": {"N": {"integer": True, "bounds": [10, float("inf")]}}})


def test_integer_free_parameter_without_bounds_in_problem(tmp_path):
    from ocdsl.search.run import run
    p, _ = _variant(tmp_path, "N_rev: {free: true, integer: true, bounds: [5, 5], value: 5}",
                    "N_rev: {free: true, integer: true, value: 5}")
    method_line = "  parameters: {N_rev: {integer: true, bounds: [5, 5]}}"
    text = p.read_text()
    assert method_line in text
    p.write_text("\n".join(l for l in text.splitlines() if not l.startswith(method_line)) + "\n")
    lf = load(p)
    res = run(lf.problem, lf.method, progress=False, integer_parameters={"N_rev"})
    assert res.status == "error" and "N_rev" in res.message and "bounds" in res.message


def test_unknown_key_is_rejected(tmp_path):
    p, line = _variant(tmp_path, "    discrete: jin", "    discrete: jinn")
    with pytest.raises(SpecError) as e:
        load(p)
    method_line = next(i + 1 for i, l in enumerate(p.read_text().splitlines()) if l.startswith("method:"))
    assert f"bad.yaml:{line}" in str(e.value) or f"bad.yaml:{method_line}" in str(e.value)
    assert "jinn" in str(e.value)


def test_a_search_result_whose_series_leaves_the_control_bound_is_infeasible():
    """unseen19 F2: the series are searched in their coefficients' box and not saturated; a
    result meeting the terminal tolerances with u = 4 against -1 <= u <= 1 was `feasible`. The
    problem-file runner now calls it infeasible, naming the control and its range; inside the
    bound it stays feasible."""
    import numpy as np

    from ocdsl.api import compile_file
    from ocdsl.result import PhaseTrajectory, Result
    from ocdsl.search.problem_file import _control_bounds

    file = compile_file(Path(__file__).parent / "data" / "series_outside_control_bound.yaml")
    t = np.linspace(0.0, 0.5, 11)

    def result(u):
        return Result(name="r", status="feasible", message="PSO stopped",
                      phases=[PhaseTrajectory("main", t, {"x": u * t}, {"u": np.full_like(t, u)})])

    outside = result(4.0)
    _control_bounds(file, outside)
    assert outside.status == "infeasible" and "u reaches 4 .. 4 against -1 <= u <= 1" in outside.message
    inside = result(1.0)
    _control_bounds(file, inside)
    assert inside.status == "feasible"


def test_an_integral_in_a_parametric_problem_is_one_error_at_check_time():
    """unseen19: `ocdsl check` said ok and the run ended with "unknown symbols
    ['integral1_main']": the shooting kernel integrates the states only."""
    from ocdsl.api import compile_file
    from ocdsl.spec.errors import SpecError

    with pytest.raises(SpecError) as err:
        compile_file(Path(__file__).parent / "data" / "parametric_integral_objective.yaml")
    text = str(err.value)
    assert "parametric_integral_objective.yaml:10" in text and "integral(...)" in text
    assert "integral1_main" not in text



ZERMELO_MIXED = """name: Zermelo, minimize tf - 0.5 x(tf) to the line y = 1
model:
  states: [x, y]
  controls: [th]
  parameters: {V: 1.0, w: 0.5}
  dynamics: {x: V*cos(th) + w, y: V*sin(th)}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 0, y(t0) == 0, y(tf) == 1, 0.2 <= tf <= 5]
  objective: minimize tf - 0.5*x(tf)
method:
  transcription: parametric
  controls:
    th: {series: constant, bounds: [-3, 3], a0: [-3, 3]}
  tolerances: {default: 1.0e-6}
  optimizer: {name: pso, particles: 30, iterations: 150, seed: 1}
  polish: {method: least_squares, max_iterations: 200}
  refine: {method: slsqp, target_ratio: 0.9, max_iterations: 300}
"""


@pytest.mark.parametrize("sense", ["minimize", "maximize"])
def test_refine_minimises_the_objective_not_tf(tmp_path, sense):
    """unseen22 FC1: `refine` minimised tf whatever the objective was, and a maximised one was
    printed with its sign flipped. A constant heading is optimal in a uniform current: J(th) =
    (0.75 - 0.5 cos th) / sin th, least at cos th = 2/3, J* = sqrt(5)/4 (it ended at 0.75, the
    fastest heading, 34 % above). Inside the tolerance zeta = 1e-6 on y(tf) J may undercut J*
    by about zeta / sin th."""
    import math

    from ocdsl.api import run_file

    text = ZERMELO_MIXED if sense == "minimize" else ZERMELO_MIXED.replace(
        "minimize tf - 0.5*x(tf)", "maximize 0.5*x(tf) - tf")
    path = tmp_path / "zermelo.yaml"
    path.write_text(text)
    res = run_file(path, tmp_path / "run")
    best = math.sqrt(5) / 4 * (1 if sense == "minimize" else -1)
    assert res.status == "feasible" and res.verified, res.message
    assert abs(res.objective - best) <= 2e-6, res.objective
    assert "objective_end" in res.extra["refine"]


def test_polish_alone_is_followed_by_a_minimisation_of_the_objective(tmp_path):
    """The polish drives the terminal errors only; for an objective other than tf the run then
    minimises J inside the tolerances as `refine` would (unseen22 FC1: -x(tf) at a fixed tf,
    13 % short of its class's best, feasible, exit 0; a note about it was not enough). A tf
    objective keeps the swarm's tf (the polish holds it), with no refinement asked."""
    import math

    from ocdsl.api import run_file

    path = tmp_path / "polish_only.yaml"
    path.write_text(ZERMELO_MIXED.replace("  refine: {method: slsqp, target_ratio: 0.9, max_iterations: 300}\n", ""))
    res = run_file(path, tmp_path / "run")
    assert res.extra["refine"]["automatic"] and any("minimised inside the tolerances" in n for n in res.extra["notes"])
    assert abs(res.objective - math.sqrt(5) / 4) <= 2e-6, res.objective
    minimum_time = tmp_path / "minimum_time.yaml"
    minimum_time.write_text(path.read_text().replace("minimize tf - 0.5*x(tf)", "minimize tf"))
    res = run_file(minimum_time, tmp_path / "run_tf")
    assert "refine" not in res.extra and not res.extra.get("notes")


@pytest.mark.parametrize("constraint,shown", [("y <= 1.5", "y <= 1.5"), ("x**2 + y**2 <= 4", "x**2 + y**2 <= 4")])
def test_state_bounds_and_path_constraints_are_refused_at_check_time(tmp_path, constraint, shown):
    """unseen22 FC4: the search sees the terminal errors only; a brachistochrone under y <= 1
    broke it by 3.3 % and said `feasible`. Refused when the file is compiled, naming it."""
    from ocdsl.api import compile_file
    from ocdsl.spec.errors import SpecError

    path = tmp_path / "bounded.yaml"
    path.write_text(ZERMELO_MIXED.replace("0.2 <= tf <= 5]", f"0.2 <= tf <= 5, {constraint}]"))
    with pytest.raises(SpecError) as err:
        compile_file(path)
    assert "at t0 and tf only" in str(err.value) and shown in str(err.value) and "guards" in str(err.value)


def test_a_top_level_free_parameter_is_an_argument_of_the_search(tmp_path):
    """unseen22 p11: a free parameter declared under the file's `parameters:` (not the
    model's) ended 'error', "right-hand side uses undeclared symbols ['k']"; LGR takes it."""
    from ocdsl.api import run_file

    path = tmp_path / "top_level.yaml"
    path.write_text(ZERMELO_MIXED.replace("  parameters: {V: 1.0, w: 0.5}\n", "  parameters: {V: 1.0}\n")
                    .replace("name: Zermelo", "parameters:\n  w: {value: 0.5, free: true, bounds: [0.4, 0.5]}\nname: Zermelo"))
    res = run_file(path, tmp_path / "run")
    assert res.status == "feasible", res.message
    assert 0.4 <= res.parameters["w"] <= 0.5



TOP_LEVEL_TARGET = """\
name: constant control to a target given at the top of the file
model:
  states: [x, v, q]
  controls: [u]
  dynamics: {x: v, v: u, q: u**2}
parameters:
  xf: 1.5
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, v(t0) == 0, q(t0) == 0, x(tf) == xf]
  objective: minimize q(tf)
method:
  transcription: parametric
  controls:
    u: {series: constant, bounds: [-5, 5]}
  tolerances: {x: 1.0e-6}
  optimizer: {name: pso, particles: 20, iterations: 100, seed: 1}
"""


def test_a_top_level_constant_in_a_terminal_condition_is_no_model_parameter(tmp_path):
    """unseen50 F2: `parameters: {xf: 1.5}` at the top of the file, `x(tf) == xf`: `check`
    said ok and every run (and study point) ended in "KeyError: model ... has no parameter
    'xf'": the problem's constants were all handed to the model's right-hand side."""
    from ocdsl.api import compile_file
    from ocdsl.search.run import build

    path = tmp_path / "xf.yaml"
    path.write_text(TOP_LEVEL_TARGET)
    file = compile_file(path)
    pp = build(file.problem, file.method)
    assert pp.parameters["xf"] == 1.5
    assert pp._P({}, 3).shape == (3, 0)        # the model itself has no parameter


@pytest.mark.slow
def test_a_top_level_constant_in_a_terminal_condition_is_taken_by_the_search(tmp_path):
    """The run (a new model's Numba kernels: 15 s on a fresh cache): a constant control u
    moves x'' = u from rest to xf in t = 1: u = 2 xf, J = 4 xf^2."""
    from ocdsl.api import run_file

    path = tmp_path / "xf.yaml"
    path.write_text(TOP_LEVEL_TARGET)
    res = run_file(path, None)
    assert res.status == "feasible" and res.ok, res.message
    assert res.objective == pytest.approx(4 * 1.5**2, rel=1e-4)


@pytest.mark.slow
def test_local_stages_that_leave_the_control_bounds_give_back_the_last_admissible_point(tmp_path):
    """unseen50 F1: minimum time, x'' = u, |u| <= 1, u linear in t/tf: the swarm found t_f =
    2.4515 inside the bound (the class's best is sqrt(6) = 2.4495); continuation and SLSQP
    then reached 1.9998 with |u| up to 1.5, and the run was `infeasible` ("narrow the series'
    bounds"). The last stage inside the bounds and the tolerances is reported, with a note."""
    from ocdsl.api import run_file

    path = tmp_path / "p07.yaml"
    path.write_text("""\
name: minimum time double integrator, control linear in s
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, -1 <= u <= 1, 0.5 <= tf <= 10]
  objective: minimize tf
method:
  transcription: parametric
  controls:
    u: {series: polynomial, order: 1, bounds: [-3, 3]}
  tolerances: {x: 1.0e-4, v: 1.0e-4}
  polish: {method: least_squares}
  continuation: {enabled: true, step: 0.02}
  refine: {method: slsqp, target_ratio: 0.9}
  optimizer: {name: pso, particles: 30, iterations: 200, seed: 1}
""")
    res = run_file(path, None)
    assert res.status == "feasible" and res.ok, res.message
    assert 6 ** 0.5 - 1e-3 < res.tf < 6 ** 0.5 + 5e-3
    assert res.extra["kept_stage"]["stage"] in ("swarm", "polish", "continuation")
    assert max(abs(u) for u in res.phases[0].controls["u"]) <= 1.0 + 1e-6
    # the summary gives the reported point's fitness beside the swarm's (unseen50 F4)
    assert f"the reported point's {res.extra['fitness_final']:.6g}, tf {res.tf:.6g}" in res.message
    # the seed the swarm used is the method's (unseen50 F5: a study point's said the file's 1)
    other = run_file(path, None, seed=7)
    assert other.method["optimizer"]["seed"] == other.extra["seed"] == 7


def test_the_documented_fourier_series_is_the_one_evaluated():
    """unseen50 F3: the docs gave cos/sin(2 pi k t/tf); the series is the half-range one,
    cos/sin(pi k t/tf). The docs' formula, read from docs/problem-language.md, against the
    evaluation."""
    import re

    import numpy as np

    from ocdsl.simulate import ControlLayout
    from ocdsl.simulate.integrate import evaluate_controls

    text = (Path(__file__).parents[1] / "docs" / "problem-language.md").read_text()
    assert re.search(r"a_k cos\(pi\s+k t/tf\) \+ b_k sin\(pi k t/tf\)", text)
    layout = ControlLayout(("fourier",), (2,))
    a0, a1, a2, b1, b2 = 0.4, 0.3, -0.2, 0.5, 0.1
    t, T = np.linspace(0.0, 2.0, 7), 2.0
    u = evaluate_controls(layout, np.array([a0, a1, a2, b1, b2]), t, T)[:, 0]
    w = np.pi * t / T
    assert np.allclose(u, a0 / 2 + a1 * np.cos(w) + a2 * np.cos(2 * w) + b1 * np.sin(w) + b2 * np.sin(2 * w))
