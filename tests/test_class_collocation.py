"""Seed 1 class mode (ocdsl/search/class_collocation.py): the paper's Fourier class by collocation.

Fast tests check that the collocation problem and the paper-mode shooting mean the same
control class (series, angles, decision-vector names); the slow test runs the 10 N chain
paper mode -> optimal mode -> class mode and checks the verified optimum.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import yaml

from ocdsl.search import class_collocation as cc
from ocdsl.simulate import ControlLayout, evaluate_controls
from ocdsl.symbolic import frames

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


def _series_value(text: str, values: dict[str, float], time: np.ndarray, T: float) -> np.ndarray:
    """Evaluate a series written in the problem language with SymPy (as the compiler reads it)."""
    from ocdsl.spec.expr import Scope, parse_expression

    names = {n: sp.Symbol(n, real=True) for n in list(values) + ["time", "T"]}
    expr = parse_expression(text, Scope(names))
    f = sp.lambdify([names["time"], names["T"]] + [names[n] for n in values], expr, "numpy")
    return np.asarray(f(time, T, *values.values()), float) * np.ones_like(time)


@pytest.mark.parametrize("order", [0, 1, 5, 8])
def test_series_text_is_the_paper_mode_series(order):
    rng = np.random.default_rng(order)
    names = cc.coefficient_names("delta", order)
    coef = rng.normal(size=len(names))
    T = 1.7
    t = np.linspace(0.0, T, 37)
    written = _series_value(cc.series_text("delta", order), dict(zip(names, coef)), t, T)
    shooting = evaluate_controls(ControlLayout(("fourier",), (order,)), coef, t, T)[:, 0]
    np.testing.assert_allclose(written, shooting, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cc.basis(order, t, T) @ coef, shooting, rtol=0, atol=1e-12)


def test_coefficient_names_are_the_paper_decision_vector():
    from ocdsl.search.run import build
    import ocdsl

    paper = ocdsl.load(CONFIGS / "seed1_10N_paper.yaml").file
    pp = build(paper.problem, paper.method, ["N_rev"])
    expected = ["N_rev", "tf"] + cc.coefficient_names("delta", 5) + cc.coefficient_names("phi", 8)
    assert pp.names() == expected


def test_ecrf_angles_invert_the_papers_direction():
    rng = np.random.default_rng(3)
    mu = 0.0121506683
    n = 200
    r, theta, z = rng.uniform(0.02, 1.0, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.1, 0.1, n)
    delta = rng.uniform(-3.0, 3.0, n)
    phi = rng.uniform(0.05, np.pi - 0.05, n)
    x, y, _, _, _, _ = frames.ecrf_to_synodic(r, theta, z, 0 * r, 0 * r, 0 * r, mu, lib=np)
    ux, uy, uz = frames.polar_direction_to_cartesian(delta, phi, theta, lib=np)
    d, p = cc.ecrf_angles(x, y, ux, uy, uz, mu)
    np.testing.assert_allclose(np.sin(d), np.sin(delta), atol=1e-12)
    np.testing.assert_allclose(np.cos(d), np.cos(delta), atol=1e-12)
    np.testing.assert_allclose(p, phi, atol=1e-10)


def test_optimal_run_without_a_control_at_its_start_is_fitted(tmp_path):
    """An LGR run folder has no control at the phase start (exported NaN): the angles and the
    series fit use the nodes that have one (a NaN there made every coefficient NaN and the
    class-mode homotopy's first step file unreadable)."""
    from ocdsl.result import PhaseTrajectory, single_phase_result

    mu, T, n = 0.0121506683, 2.0, 300
    t = np.linspace(0.0, T, n)
    theta = 0.3 + 2.0 * t
    r, z = 0.5 + 0.0 * t, 0.0 * t
    x, y, _, _, _, _ = frames.ecrf_to_synodic(r, theta, z, 0 * r, 0 * r, 0 * r, mu, lib=np)
    delta = 2.0 + 1.5 * np.sin(2.0 * np.pi * t / T)     # crosses pi: needs unwrapping
    phi = 1.2 + 0.0 * t
    ux, uy, uz = frames.polar_direction_to_cartesian(delta, phi, theta, lib=np)
    for a in (ux, uy, uz):
        a[0] = np.nan
    states = {"x": x, "y": y, "z": z, "vx": 0 * t, "vy": 0 * t, "vz": 0 * t, "m": 1 + 0 * t, "time": t}
    res = single_phase_result("lgr run", "optimal",
                              PhaseTrajectory("main", t, states, {"ux": ux, "uy": uy, "uz": uz}), tf=T)
    d, p = cc.ecrf_angles(x, y, ux, uy, uz, mu)
    assert np.isnan(d[0]) and np.allclose(d[1:], delta[1:])
    values, rms = cc.warm_folder(res, mu, {"delta": 3, "phi": 3}, tmp_path / "fit", 1e-6)
    assert all(np.isfinite(v) for v in values.values()) and max(rms.values()) < 1e-2


def test_fit_recovers_a_series_and_ridge_keeps_coefficients_small():
    T, order = 2.0, 5
    rng = np.random.default_rng(5)
    coef = rng.normal(size=2 * order + 1)
    t = np.linspace(0.0, T, 2000)    # the fit's own uniform samples: no interpolation error
    v = cc.basis(order, t, T) @ coef
    # the half-range basis (cosines and sines) is nearly dependent: the values are recovered
    # to round-off, the coefficients only to the basis' conditioning
    fitted = cc.fit_series(t, v, T, order, ridge=0.0)
    np.testing.assert_allclose(cc.basis(order, t, T) @ fitted, v, atol=1e-8)
    np.testing.assert_allclose(fitted, coef, atol=1e-3)
    # an angle the basis cannot follow: the unregularised fit needs larger coefficients
    wild = np.sin(40 * np.pi * t / T) + t
    plain = cc.fit_series(t, wild, T, order, ridge=0.0)
    ridged = cc.fit_series(t, wild, T, order, ridge=1e-2)
    assert np.abs(ridged).max() < np.abs(plain).max()


@pytest.mark.parametrize("weight", [10.0, None])
def test_class_problem_files_compile(tmp_path, weight):
    import ocdsl

    optimal_doc = yaml.safe_load((CONFIGS / "seed1_10N_optimal.yaml").read_text())
    orders = {"delta": 5, "phi": 8}
    values = {"T": 1.6}
    for c, n in orders.items():
        values.update({name: 0.1 for name in cc.coefficient_names(c, n)})
    doc = cc.class_problem(optimal_doc, orders, values, weight, 30.0)
    path = tmp_path / "class.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False, width=100000))
    loaded = ocdsl.load(path).file
    ph = loaded.problem.phases[0]
    assert [s.name for s in ph.states] == ["x", "y", "z", "vx", "vy", "vz", "m", "time"]
    assert [c.name for c in ph.controls] == ["delta", "phi", "ed", "ep"]
    free = {s.name for s in loaded.problem.free_parameters}
    assert free == set(values)
    # the two ties (penalty: deviations; hard: the angles) plus the distance to the Earth;
    # in the hard problem the deviations are fixed at zero by their bounds
    assert len(ph.path) == 3
    deviations = {c.name: ph.control_bounds.get(c, None) for c in ph.controls if c.name in ("ed", "ep")}
    if weight is None:
        assert all(b == (0.0, 0.0) for b in deviations.values())
    else:
        assert all(b is None for b in deviations.values())
    objective = str(loaded.problem.objective.expr)
    assert ("integral" in objective) == (weight is not None)


@pytest.mark.parametrize("case", ["10N", "5N", "2N"])
def test_terminal_box_is_the_paper_files_terminal_conditions(case):
    """The box written in the Cartesian states at tf is centred on the paper file's own polar
    terminal values (r, theta mod 2 pi, z, rdot, thetadot, zdot) with half-width ratio * zeta:
    the optimal and paper files of a case describe the same target."""
    import ocdsl

    optimal_doc = yaml.safe_load((CONFIGS / f"seed1_{case}_optimal.yaml").read_text())
    paper_doc = yaml.safe_load((CONFIGS / f"seed1_{case}_paper.yaml").read_text())
    paper = ocdsl.load(CONFIGS / f"seed1_{case}_paper.yaml").file
    zeta, ratio = cc.paper_tolerances(paper)
    assert ratio == paper.method.refine.target_ratio
    relations, replaced = cc.terminal_box(optimal_doc, zeta, ratio)
    assert len(relations) == 6 and len(replaced) == 6
    target = {}
    for c in optimal_doc["problem"]["constraints"]:
        lhs, _, rhs = c.partition("==")
        if lhs.strip().endswith("(tf)") and rhs:
            target[lhs.strip()] = float(rhs)
    n_rev = paper_doc["parameters"]["N_rev"]["value"]
    printed = {}
    for c in paper_doc["problem"]["constraints"]:
        lhs, _, rhs = c.partition("==")
        if lhs.strip().endswith("(tf)"):
            printed[lhs.strip()[:-4]] = float(sp.sympify(rhs.replace("N_rev", str(n_rev))))
    printed["theta"] = math.remainder(printed["theta"], 2 * math.pi)
    at_target = {"mu": optimal_doc["model"]["parameters"]["mu"],
                 **{k.replace("(tf)", "_tf"): v for k, v in target.items()}}
    for name, relation in zip(cc.POLAR_TERMINALS, relations):
        low, middle, high = (part.strip() for part in relation.split("<="))
        value = float(sp.sympify(middle.replace("(tf)", "_tf")).subs(at_target))
        assert math.isclose(value, printed[name], abs_tol=1e-9), (name, value, printed[name])
        assert math.isclose(float(high) - float(low), 2 * ratio * zeta[name], rel_tol=1e-12)
        assert math.isclose((float(high) + float(low)) / 2, value, abs_tol=1e-12)


def test_class_problem_with_the_paper_box_replaces_the_exact_terminal_state(tmp_path):
    import ocdsl

    optimal_doc = yaml.safe_load((CONFIGS / "seed1_10N_optimal.yaml").read_text())
    orders = {"delta": 5, "phi": 8}
    values = {"T": 1.6, **{n: 0.1 for c, k in orders.items() for n in cc.coefficient_names(c, k)}}
    exact = cc.class_problem(optimal_doc, orders, values, None, 30.0)
    boxed = cc.class_problem(optimal_doc, orders, values, None, 30.0,
                             ({n: 1e-3 for n in cc.POLAR_TERMINALS}, 0.9))
    dropped = set(exact["problem"]["constraints"]) - set(boxed["problem"]["constraints"])
    assert dropped == {c for c in exact["problem"]["constraints"]
                       if c.split("(")[0] in cc.CARTESIAN_TERMINALS and "(tf) ==" in c}
    path = tmp_path / "boxed.yaml"
    path.write_text(yaml.safe_dump(boxed, sort_keys=False, width=100000))
    loaded = ocdsl.load(path).file
    assert sum(not c.is_equality for c in loaded.problem.boundary) >= 6


def test_class_mode_refuses_a_non_fourier_file(tmp_path):
    doc = yaml.safe_load((CONFIGS / "seed1_10N_paper.yaml").read_text())
    doc["method"]["controls"]["delta"] = {"series": "polynomial", "order": 3}
    path = tmp_path / "poly.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    with pytest.raises(ValueError, match="Fourier series of delta and phi"):
        cc.refine_class(path, tmp_path / "nowhere", tmp_path / "out")


def test_stored_10N_class_solution_is_inside_zeta_by_the_paper_fitness():
    """The class-mode collocation solution (tests/data), integrated by paper mode's own
    fitness (polar eq. 28, DOP853 at the file's tolerance): N_rev 5, every terminal error
    inside zeta without any polish, tf 1.93943 TU: the Fourier-(5, 8) class has a solution
    0.19 % faster than paper mode's SLSQP point (1.94317) and 6.2 % above the paper's 1.8265."""
    import json
    import ocdsl

    data = json.loads((ROOT / "tests" / "data" / "seed1_10N_class_solution.json").read_text())
    paper = ocdsl.load(CONFIGS / "seed1_10N_paper.yaml").file
    check = cc.shooting_check(paper, {"T": data["tf"], **data["coefficients"]})
    record, det = check["record"], check["details"]
    assert not record["polished"]
    assert record["max_error_over_zeta"] < 0.01
    assert det["variables"]["N_rev"] == 5
    assert math.isclose(det["tf"], 1.93943, rel_tol=1e-5)
    assert det["tf"] < 1.94317


#: paper mode's committed results (reports/seed1_*: swarm, continuation, SLSQP) and the paper's
PAPER_MODE_TF = {"10N": 1.94317, "5N": 3.08085, "2N": 7.24121}
PAPER_TF = {"10N": 1.8265, "5N": 3.02396, "2N": 6.8730}


@pytest.mark.parametrize("case", ["10N", "5N", "2N"])
def test_session5_class_solutions_by_the_paper_fitness(case):
    """Class mode's solutions of session 5 (paper's terminal box), integrated by paper mode's
    own fitness: every terminal error inside zeta without polish, the paper's N_rev, faster
    than paper mode's SLSQP point, and still above the paper's printed t_f at 10 N and 2 N by
    more than the 2 % band (at 5 N within it)."""
    import json
    import ocdsl

    data = json.loads((ROOT / "tests" / "data" / "seed1_class_solutions.json").read_text())["cases"][case]
    paper = ocdsl.load(CONFIGS / f"seed1_{case}_paper.yaml").file
    check = cc.shooting_check(paper, {"T": data["tf"], **data["coefficients"]})
    record, det = check["record"], check["details"]
    assert not record["polished"]
    assert record["max_error_over_zeta"] <= 1.0
    assert math.isclose(record["max_error_over_zeta"], data["max_error_over_zeta"], rel_tol=1e-3)
    assert det["variables"]["N_rev"] == data["N_rev"]
    assert math.isclose(det["tf"], data["tf"], rel_tol=1e-12)
    assert det["tf"] < PAPER_MODE_TF[case]
    excess = det["tf"] / PAPER_TF[case] - 1.0
    assert (excess < 0.02) == (case == "5N"), excess


def test_class_mode_from_a_class_member(tmp_path):
    """Start from a paper-mode run folder (here the stored 10 N class solution, written as one
    by member_run): the start is a class member (ed = ep = 0, the angles are the series), only
    the hard problem is solved, with the paper's terminal box, and its optimum, integrated by
    the paper fitness, is inside zeta and no slower than the start (the box admits the start's
    exact end state)."""
    import json
    import ocdsl
    from ocdsl.result import Result

    data = json.loads((ROOT / "tests" / "data" / "seed1_10N_class_solution.json").read_text())
    values = {"T": data["tf"], **data["coefficients"]}
    paper_file = CONFIGS / "seed1_10N_paper.yaml"
    paper = ocdsl.load(paper_file).file
    start = cc.member_run(paper, values, tmp_path / "member")
    assert start.status == "feasible"
    res = cc.refine_class(paper_file, CONFIGS / "seed1_10N_optimal.yaml", tmp_path / "c10",
                          segments=60, paper_run=tmp_path / "member", progress=False)
    warm = Result.read(tmp_path / "c10_stages" / "fit").phase()
    t = np.asarray(warm.states["time"])
    for control, order in (("delta", 5), ("phi", 8)):
        coef = [values[n] for n in cc.coefficient_names(control, order)]
        np.testing.assert_allclose(warm.controls[control], cc.basis(order, t, data["tf"]) @ coef, atol=1e-12)
        assert np.all(warm.controls[cc.DEVIATIONS[control]] == 0.0)
    assert math.isclose(t[-1], data["tf"], rel_tol=1e-8)
    table = res.tables["homotopy"]
    assert all(not np.isfinite(w) for w in table["weight"])     # no penalty steps
    assert res.extra["class_mode"]["hard_solved"]
    assert res.status == "feasible" and res.extra["N_rev"] == 5
    assert res.extra["shooting"]["max_error_over_zeta"] <= 1.0
    assert res.tf <= data["tf"] + 1e-6


def test_class_mode_cli_bad_run_folder(tmp_path, capsys):
    code = cc.main([str(CONFIGS / "seed1_10N_paper.yaml"), "--optimal", str(tmp_path / "nowhere"),
                    "--out", str(tmp_path / "out")])
    assert code == 2
    assert "not an optimal-mode run folder" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_10N_class_mode_homotopy(tmp_path):
    """Paper mode -> optimal mode -> class mode, 10 N. The penalty steps relax the class
    (the control may leave the series by ed, ep at a price), so their T rises with the
    weight and bounds the class optimum of the basin followed from below. Measured
    (session 4, exact end state): T 1.5451 -> 1.7173 over weights 0.01..60; the hard problem
    from weight 60 converged once to 1.93943 (tests/data) and once did not (see
    HARD_ATTEMPTS). Session 5, the paper's terminal box (default): T 1.5457 -> 1.7710, both
    hard attempts at the cap."""
    from ocdsl.api import run_file

    # the optimal-mode file alone: its chain solves the paper-mode file first (or reuses its run)
    opt = run_file(CONFIGS / "seed1_10N_optimal.yaml", tmp_path / "o10")
    assert abs(opt.extra["tf_physical"] - 1.54475) < 1e-3
    res = cc.refine_class(CONFIGS / "seed1_10N_paper.yaml", tmp_path / "o10", tmp_path / "c10",
                          progress=False)
    table = res.tables["homotopy"]
    penalty_steps = [i for i, w in enumerate(table["weight"]) if np.isfinite(w)]
    assert len(penalty_steps) == len(cc.DEFAULT_WEIGHTS)
    assert all(table["solved"][i] for i in penalty_steps)
    T = np.array([table["T"][i] for i in penalty_steps])
    assert np.all(np.diff(T) > -1e-6)
    assert 1.5448 < T[-1] < 1.94317
    assert res.extra["N_rev"] == 5
    if res.extra["class_mode"]["hard_solved"]:
        assert res.status == "feasible"
        assert 1.5448 < res.tf < 1.94317 + 1e-3


def test_multistart_class_stage_from_a_member(tmp_path):
    """The random-start study's class-mode stage (``multistart --class``): from a class member
    inside zeta it returns the verified class-mode tf, with the optimal file found beside the
    paper file."""
    import json
    import ocdsl
    from ocdsl.search.multistart import _class_mode

    data = json.loads((ROOT / "tests" / "data" / "seed1_10N_class_solution.json").read_text())
    path = str(CONFIGS / "seed1_10N_paper.yaml")
    lf = ocdsl.load(path).file
    pp, x = cc._decision_vector(lf, {"T": data["tf"], **data["coefficients"]})
    tf, how = _class_mode(lf, path, pp, x, 0, 60, str(tmp_path))
    assert tf is not None and tf <= data["tf"] + 1e-6, how
    assert (tmp_path / "class0" / "result.json").exists() and (tmp_path / "member0" / "result.json").exists()


def test_class_mode_cli_bad_paper_run(tmp_path, capsys):
    """--from-paper with a missing folder, or with a run that is not paper mode's (no decision
    vector): one error line, exit 2, nothing written."""
    from ocdsl.result import PhaseTrajectory, single_phase_result

    not_paper = tmp_path / "not_paper"
    single_phase_result("some run", "optimal", PhaseTrajectory("main", np.linspace(0, 1, 3))).write(not_paper)
    for start, message in ((tmp_path / "nowhere", "no result.json"), (not_paper, "no decision vector")):
        code = cc.main([str(CONFIGS / "seed1_10N_paper.yaml"), "--optimal", str(CONFIGS / "seed1_10N_optimal.yaml"),
                        "--from-paper", str(start), "--out", str(tmp_path / "out")])
        assert code == 2
        assert message in capsys.readouterr().err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["not_paper"]
