"""Pareto machinery and the seed-4 two-burn Pareto sets (digest ../shared/seeds/seed_004.md §5).

The reference tables of cases A and B are the digest's §5.3: synthetic benchmarks made from
its reconstruction of the lost equations, NOT the paper's (lost) Table 1.
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.optimize import minimize

from ocdsl.result import Result
from ocdsl.spec.pareto import ParetoSpecError, load_pareto, parse_pareto
from ocdsl.study import pareto as P
from ocdsl.study.pareto_run import run_pareto, two_burn_pareto, two_burn_problem, two_burn_trajectory
from ocdsl.verify import verify_result
from ocdsl.symbolic import relative_motion as rm
from ocdsl.symbolic.registry import build_model

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

# digest §5.3: (family, d1, t0, t1, tp, t2, t_mot, t_sum, pareto)
CASE_A = [
    ("opposite", -1, 0.240668, 1.621522, 4.165474, 2.121522, 3.743044, 8.149185, True),
    ("opposite", -1, 4.926443, 1.122437, 5.154472, 1.622437, 2.744875, 12.825790, True),
    ("opposite", -1, 0.214968, 0.560933, 11.523134, 1.060933, 1.621866, 13.359968, True),
    ("opposite", -1, 5.789870, 0.311094, 12.212548, 0.811094, 1.122188, 19.124606, True),
    ("opposite", -1, 0.139170, 0.207328, 18.221298, 0.707328, 0.914656, 19.275125, True),
    ("same", 1, 0.356561, 0.075604, 30.702562, 0.424396, 0.500000, 31.559123, True),
    ("same", 1, 5.881854, 0.094466, 25.318226, 0.405534, 0.500000, 31.700081, False),
    ("same", 1, 0.206975, 0.146329, 37.053826, 0.353671, 0.500000, 37.760801, False),
    ("same", 1, 5.945763, 0.175581, 31.550085, 0.324419, 0.500000, 37.995848, False),
    ("same", 1, 5.965606, 0.229654, 37.823913, 0.270346, 0.500000, 44.289520, False),
]
CASE_B = [
    ("opposite", 1, 5.013360, 1.530174, 4.760122, 1.030174, 2.560348, 12.333830, True),
    ("opposite", 1, 6.022844, 1.530859, 5.245222, 1.030859, 2.561718, 13.829785, False),
    ("opposite", 1, 5.536399, 1.015165, 11.571319, 0.515165, 1.530330, 18.638049, True),
    ("opposite", 1, 6.014811, 1.015352, 12.030916, 0.515352, 1.530703, 19.576430, False),
    ("opposite", 1, 5.713378, 0.843461, 18.042964, 0.343461, 1.186922, 24.943264, True),
    ("opposite", 1, 6.009535, 0.843550, 18.469151, 0.343550, 1.187100, 25.665786, False),
    ("opposite", 1, 5.803493, 0.757603, 24.431822, 0.257603, 1.015207, 31.250522, True),
    ("opposite", 1, 6.005277, 0.757655, 24.818420, 0.257655, 1.015310, 31.839007, False),
    ("opposite", 1, 5.858977, 0.706087, 30.789659, 0.206087, 0.912174, 37.560810, True),
    ("opposite", 1, 6.001310, 0.706120, 31.130008, 0.206120, 0.912239, 38.043557, False),
    ("opposite", 1, 5.897544, 0.671742, 37.134772, 0.171742, 0.843485, 43.875800, True),
    ("opposite", 1, 5.997087, 0.671763, 37.419969, 0.171763, 0.843526, 44.260583, False),
]
Y0_A = (-0.5, -20.0, 0.49, 0.0)
Y0_B = (-0.5, 5.0, 0.49, 0.0)
# The reference values are printed to 6 decimals: "within 1e-6" allows their rounding.
TOL_TABLE = 1e-6 + 5e-7


# ---- generic machinery ------------------------------------------------------------------
def test_nondominated_and_deduplicate():
    F = [[1, 5], [2, 3], [3, 3], [2, 4], [4, 1], [4, 1], [np.nan, 0], [5, 0.5]]
    mask = P.nondominated(F)
    assert mask.tolist() == [True, True, False, False, True, True, False, True]
    assert P.nondominated([[1, 5], [2, 6]], senses=["minimize", "maximize"]).tolist() == [True, True]
    pts = [P.ParetoPoint({"f": 1.0}, {"a": 1.0}, residual=1e-9),
           P.ParetoPoint({"f": 1.0}, {"a": 1.0 + 1e-8}, residual=1e-12),
           P.ParetoPoint({"f": 1.0}, {"a": 1.0 + 1e-8}, family="other"),
           P.ParetoPoint({"f": 2.0}, {"a": 1.1})]
    kept = P.deduplicate(pts, tol=1e-6)
    assert len(kept) == 3 and kept[0].residual == 1e-12
    assert P.window_cells(0, 40, 2 * math.pi)[-1] == (12 * math.pi, 40)
    assert len(P.window_cells(0, 40, 2 * math.pi)) == 7
    assert P.split_chains(list(range(10)), 3) == [[0, 1, 2], [3, 4, 5, 6], [7, 8, 9]]


def _assert_matches(pset, reference, y0):
    """Same number of roots, same flags, durations within 1e-6 (reference rounded to 6 decimals)."""
    pts = sorted(pset.points, key=lambda p: p.objectives["t_sum"])
    ref = sorted(reference, key=lambda r: r[7])
    assert len(pts) == len(ref)
    for p, r in zip(pts, ref):
        v = p.variables
        assert p.family == r[0] and v["d1"] == r[1]
        got = [v["t0"], v["t1"], v["tp"], v["t2"], p.objectives["t_mot"], p.objectives["t_sum"]]
        assert np.max(np.abs(np.array(got) - np.array(r[2:8]))) < TOL_TABLE, (got, r)
        assert p.pareto == r[8]
        assert p.residual < 1e-9


@pytest.fixture(scope="module")
def case_a():
    return two_burn_pareto(Y0_A)


@pytest.fixture(scope="module")
def case_b():
    return two_burn_pareto(Y0_B)


def test_case_A_reproduced(case_a):
    _assert_matches(case_a, CASE_A, Y0_A)


def test_case_B_reproduced_with_alternating_pattern(case_b):
    _assert_matches(case_b, CASE_B, Y0_B)
    flags = [p.pareto for p in sorted(case_b.points, key=lambda p: p.objectives["t_sum"])]
    assert flags == [i % 2 == 0 for i in range(len(flags))]       # yes, no, yes, no, ...
    assert [p.label for p in case_b.front()][::-1] == ["2.1", "2.3", "2.5", "2.7", "2.9", "2.11"]


def _integrate_root(p, y0):
    m = build_model("relative_motion_secular")
    f = sp.lambdify([m.states, m.controls], list(m.rhs()), "math")
    v = p.variables
    y = np.asarray(y0, float)
    for delta, dur in ((0, v["t0"]), (v["d1"], v["t1"]), (0, v["tp"]), (v["d2"], v["t2"])):
        if dur > 0:
            y = solve_ivp(lambda t, x: f(x, [delta]), (0, dur), y, method="DOP853",
                          rtol=1e-13, atol=1e-15).y[:, -1]
    return y


@pytest.mark.parametrize("which", ["A", "B"])
def test_every_root_integrates_to_zero_final_state(which, case_a, case_b):
    pset, y0 = (case_a, Y0_A) if which == "A" else (case_b, Y0_B)
    for p in pset.points:
        assert np.max(np.abs(_integrate_root(p, y0))) < 1e-9


@pytest.mark.parametrize("which", ["A", "B"])
def test_every_closed_form_point_is_verified(which, case_a, case_b):
    """The closed-form roots go through ocdsl/verify like any solve: all verified."""
    pset = case_a if which == "A" else case_b
    verdicts = [p.extra["verification"]["status"] for p in pset.points]
    assert verdicts and set(verdicts) == {"verified"}


def test_a_perturbed_closed_form_point_fails_verification(case_a):
    """A coast 1e-3 too long (the other durations kept): the verification names the end state."""
    p = max(case_a.points, key=lambda q: q.variables["tp"])
    v = p.variables
    phases = two_burn_trajectory(Y0_A, v["t0"], v["t1"], v["tp"] + 1e-3, v["t2"], v["d1"], v["d2"])
    res = Result("perturbed", "optimal", phases=phases)
    verdict = verify_result(two_burn_problem(Y0_A, int(v["d1"]), int(v["d2"])), res)
    assert verdict["status"] == "failed"
    failed = {c["name"] for c in verdict["checks"] if not c["passed"]}
    assert failed == {"boundary conditions"}, verdict["checks"]


def test_a_phase_of_zero_duration_is_verified(case_a):
    """Started where a point's wait ends, the same burns and coast with a wait of length 0
    are a root too: the zero-length phase must verify, not crash."""
    p = case_a.points[0]
    v = p.variables
    y_wait_end = tuple(float(p.phases[0].states[n][-1]) for n in ("r_av", "L_av", "l_x", "l_y"))
    phases = two_burn_trajectory(y_wait_end, 0.0, v["t1"], v["tp"], v["t2"], v["d1"], v["d2"])
    verdict = verify_result(two_burn_problem(y_wait_end, int(v["d1"]), int(v["d2"])),
                            Result("no wait", "optimal", phases=phases))
    assert verdict["status"] == "verified", verdict["summary"]
    wait = [c for c in verdict["checks"] if c["phase"] == "wait" and c["name"] == "dynamics per piece"]
    assert wait and "zero duration" in wait[0]["detail"]


@pytest.mark.parametrize("which", ["A", "B"])
def test_paper_statements(which, case_a, case_b):
    """Digest §5.1 checks 1-4 and §5.2 check 10."""
    pset, y0 = (case_a, Y0_A) if which == "A" else (case_b, Y0_B)
    delta = abs(0.0 - y0[0])
    for p in pset.points:
        v, o = p.variables, p.objectives
        if p.family == "same":
            assert abs(o["t_mot"] - delta) < 1e-9
        else:
            assert abs(o["t_mot"] - delta - 2 * min(v["t1"], v["t2"])) < 1e-9
            # each root lies on its own analytic boundary (24)-(26)
            assert abs(rm.boundary_tp(o["t_mot"], v["t0"], y0, int(v["d1"])) - v["tp"]) < 1e-8
        assert abs(o["t_sum"] - (v["t0"] + o["t_mot"] + v["tp"])) < 1e-12
    front = pset.front()
    assert 0 < len(front) < len(pset.points) or which == "A"
    assert len(front) == len({(round(p.objectives["t_mot"], 9), round(p.objectives["t_sum"], 9))
                              for p in front})                    # isolated points
    min_tsum = min(pset.points, key=lambda p: p.objectives["t_sum"])
    min_tp = min(pset.points, key=lambda p: p.variables["tp"])
    assert min_tsum is min_tp and min_tsum.pareto
    same = [p for p in pset.points if p.family == "same"]
    if same:
        leftmost = front[0]
        assert leftmost.family == "same"
        assert leftmost is min(same, key=lambda p: p.objectives["t_sum"])
        assert all(p.family == "opposite" for p in front[1:])


def test_same_sign_existence_bound():
    """l_x0 = 0.49 < 4 sin(|Delta|/4) = 0.498699: same-sign roots; 0.499 > bound: none."""
    same = {"same": [(1, 1), (-1, -1)]}
    assert 0.49 < rm.same_sign_bound(0.5) < 0.499
    assert len(two_burn_pareto((-0.5, -20.0, 0.49, 0.0), same, trajectory=False).points) > 0
    assert len(two_burn_pareto((-0.5, -20.0, 0.499, 0.0), same, trajectory=False).points) == 0


def test_case_A_variants():
    """Digest §5.3: l_x0 = 1.0 -> 3 opposite-sign roots (values printed to 4 decimals); 0.3 -> same-sign only."""
    s = two_burn_pareto((-0.5, -20.0, 1.0, 0.0), trajectory=False)
    got = sorted((p.objectives["t_mot"], p.objectives["t_sum"]) for p in s.points)
    ref = sorted([(3.9070, 8.3882), (2.6052, 12.5435), (1.6907, 13.6956)])
    assert all(p.family == "opposite" for p in s.points)
    assert np.max(np.abs(np.array(got) - np.array(ref))) < 5e-5 + 1e-6
    s = two_burn_pareto((-0.5, -20.0, 0.3, 0.0), trajectory=False)
    assert s.points and all(p.family == "same" for p in s.points)


# ---- the runner, the configs, the executor -----------------------------------------------
def test_run_pareto_case_files_and_study_folder(tmp_path):
    results, table = run_pareto(CONFIGS / "seed4_case_B.yaml", tmp_path / "B")
    assert len(results) == len(CASE_B) == len(table["label"])
    assert sum(table["pareto"]) == 6 and set(table["family"]) == {"opposite"}
    assert all(isinstance(r, Result) and r.status == "optimal" for r in results)
    summary = json.loads((tmp_path / "B" / "result.json").read_text())
    assert summary["expect"] and all(c["passed"] for c in summary["expect"])
    back = Result.read(tmp_path / "B" / "points" / "2.1")
    assert back.extra["pareto"] is True and abs(back.extra["objectives"]["t_sum"] - 12.333830) < TOL_TABLE
    assert [p.name for p in back.phases] == ["wait", "burn1", "coast", "burn2"]
    assert abs(back.phase("burn2").states["l_x"][-1]) < 1e-9
    assert (tmp_path / "B" / "pareto.csv").read_text().startswith("label,family,")
    # a variant through parameter overrides: l_x0 = 0.499 leaves case A without same-sign roots
    results, table = run_pareto(CONFIGS / "seed4_case_A.yaml", parameters={"lx0": 0.499})
    assert results and set(table["family"]) == {"opposite"}


def test_executor_map_gives_the_same_set(case_a):
    from ocdsl.study.executor import Executor

    with Executor(workers=2) as ex:
        s = two_burn_pareto(Y0_A, map=ex.map)
    assert [(p.label, p.pareto) for p in s.points] == [(p.label, p.pareto) for p in case_a.points]
    for p, q in zip(s.points, case_a.points):
        assert abs(p.objectives["t_sum"] - q.objectives["t_sum"]) < 1e-12


# ---- epsilon and weighted on problems with analytic fronts -------------------------------
# Schaffer's problem SCH (J. D. Schaffer, "Multiple objective optimization with vector
# evaluated genetic algorithms", ICGA 1985; also K. Deb, "Multi-Objective Optimization using
# Evolutionary Algorithms", Wiley 2001, §2.x test problems): f1 = x^2, f2 = (x-2)^2,
# Pareto set x in [0, 2], front f2 = (2 - sqrt(f1))^2, convex and continuous.
def _sch(x):
    return x[0] ** 2, (x[0] - 2) ** 2


def solve_sch_eps(eps, warm):
    x0 = [0.0] if warm is None else warm
    r = minimize(lambda x: _sch(x)[0], x0, method="SLSQP", bounds=[(-5, 5)],
                 constraints=[{"type": "ineq", "fun": lambda x: eps - _sch(x)[1]}],
                 options={"ftol": 1e-14, "maxiter": 200})
    f1, f2 = _sch(r.x)
    return P.ParetoPoint({"f1": f1, "f2": f2}, {"x": float(r.x[0])},
                         status="optimal" if r.success else "infeasible",
                         residual=max(0.0, f2 - eps), warm=list(r.x), extra={"nit": r.nit})


def solve_sch_weighted(w, warm):
    r = minimize(lambda x: w[0] * _sch(x)[0] + w[1] * _sch(x)[1], [1.0] if warm is None else warm,
                 method="BFGS", options={"gtol": 1e-12})
    f1, f2 = _sch(r.x)
    return P.ParetoPoint({"f1": f1, "f2": f2}, {"x": float(r.x[0])}, warm=list(r.x))


def test_epsilon_traces_schaffer_front():
    eps = np.linspace(0.05, 3.9, 25)
    s = P.epsilon(solve_sch_eps, eps, ["f1", "f2"])
    assert len(s.points) == len(eps) and all(p.pareto for p in s.points)
    for p, e in zip(sorted(s.points, key=lambda q: q.extra["epsilon"]), eps):
        f1, f2 = p.objectives["f1"], p.objectives["f2"]
        assert abs(f1 - (2 - math.sqrt(e)) ** 2) < 1e-6          # analytic epsilon solution
        assert abs(f2 - (2 - math.sqrt(f1)) ** 2) < 1e-6          # on the analytic front
    # warm starts: later solves start at the previous optimum and need fewer iterations
    its = [p.extra["nit"] for p in s.points]
    assert np.mean(its[1:]) < its[0] + 1
    # chains through a map give the same front
    s2 = P.epsilon(solve_sch_eps, eps, ["f1", "f2"], chains=3, map=map)
    assert np.allclose(sorted(p.objectives["f1"] for p in s2.points),
                       sorted(p.objectives["f1"] for p in s.points), atol=1e-8)


def test_weighted_on_convex_front_has_no_warning(recwarn):
    s = P.weighted(solve_sch_weighted, 11, ["f1", "f2"])
    assert len(s.points) == 11 and not s.warnings
    assert not [w for w in recwarn if issubclass(w.category, P.ParetoWarning)]
    for p in s.points:  # analytic weighted-sum optimum of SCH: x = 2 w2 / (w1 + w2)
        w1, w2 = p.extra["weights"]
        assert abs(p.variables["x"] - 2 * w2 / (w1 + w2)) < 1e-7


# ZDT2 (Zitzler, Deb & Thiele, Evolutionary Computation 8(2), 2000), two variables:
# f1 = x1, f2 = g (1 - (x1/g)^2), g = 1 + 9 x2; front f2 = 1 - f1^2 (non-convex).
def _zdt2(x):
    g = 1 + 9 * x[1]
    return x[0], g * (1 - (x[0] / g) ** 2)


def solve_zdt2_weighted(w, warm):
    grid = [(a, b) for a in np.linspace(0, 1, 101) for b in np.linspace(0, 1, 11)]
    best = min(grid, key=lambda x: w[0] * _zdt2(x)[0] + w[1] * _zdt2(x)[1])
    r = minimize(lambda x: w[0] * _zdt2(x)[0] + w[1] * _zdt2(x)[1], best, method="L-BFGS-B",
                 bounds=[(0, 1), (0, 1)])
    f1, f2 = _zdt2(r.x)
    return P.ParetoPoint({"f1": f1, "f2": f2}, {"x1": float(r.x[0]), "x2": float(r.x[1])})


def solve_zdt2_eps(eps, warm):
    # min f2 s.t. f1 <= eps: x2 = 0, x1 = eps on the front
    x0 = [min(eps, 1.0), 0.0] if warm is None else warm
    r = minimize(lambda x: _zdt2(x)[1], x0, method="SLSQP", bounds=[(0, 1), (0, 1)],
                 constraints=[{"type": "ineq", "fun": lambda x: eps - x[0]}], options={"ftol": 1e-14})
    f1, f2 = _zdt2(r.x)
    return P.ParetoPoint({"f1": f1, "f2": f2}, {"x1": float(r.x[0]), "x2": float(r.x[1])}, warm=list(r.x))


def test_weighted_warns_on_nonconvex_front():
    with pytest.warns(P.ParetoWarning, match="non-convex"):
        s = P.weighted(solve_zdt2_weighted, 11, ["f1", "f2"])
    ends = sorted((round(p.objectives["f1"], 6), round(p.objectives["f2"], 6)) for p in s.points)
    assert ends == [(0.0, 1.0), (1.0, 0.0)]            # only the ends of 1 - f1^2
    # the epsilon method finds the interior; weighted sums are told which points they miss
    e = P.epsilon(solve_zdt2_eps, np.linspace(0.1, 0.9, 9), ["f2", "f1"])
    for p in e.points:
        assert abs(p.objectives["f2"] - (1 - p.objectives["f1"] ** 2)) < 1e-8
    with pytest.warns(P.ParetoWarning) as caught:
        w = P.weighted(solve_zdt2_weighted, 5, ["f1", "f2"], reference=e.points)
    messages = [str(c.message) for c in caught]
    assert any("not convex" in m for m in messages) and any("non-convex" in m for m in messages), messages
    assert any("e." in msg for msg in w.warnings)


def test_supported_points_of_case_B(case_b):
    F = [[p.objectives["t_mot"], p.objectives["t_sum"]] for p in case_b.points]
    sup = P.supported(F)
    assert not np.any(sup & ~P.nondominated(F))
    assert 0 < sup.sum() <= 6


# ---- the pareto: block ---------------------------------------------------------------------
GOOD = CONFIGS / "seed4_case_A.yaml"


def _write_variant(tmp_path, old, new):
    text = GOOD.read_text()
    assert old in text
    p = tmp_path / "bad.yaml"
    p.write_text(text.replace(old, new))
    return p, text.replace(old, new).splitlines()


def test_spec_loads_configs():
    for name in ("seed4_case_A.yaml", "seed4_case_B.yaml"):
        spec, doc = load_pareto(CONFIGS / name)
        assert spec.method == "enumerate" and spec.objective_names == ["t_mot", "t_sum"]
        assert spec.window["wait.duration"].range == (0.0, 2 * math.pi)
        assert spec.window["coast.duration"].split == pytest.approx(2 * math.pi, abs=0)


def test_spec_fewer_than_two_objectives(tmp_path):
    path, lines = _write_variant(
        tmp_path, "    t_sum: wait.duration + burn1.duration + coast.duration + burn2.duration\n", "")
    with pytest.raises(ParetoSpecError, match="at least two objectives") as exc:
        load_pareto(path)
    assert exc.value.file == str(path) and "objectives" in lines[exc.value.line - 1]
    assert str(path) in str(exc.value)


def test_spec_empty_window(tmp_path):
    path, lines = _write_variant(tmp_path, "range: [0, 40]", "range: [40, 40]")
    with pytest.raises(ParetoSpecError, match="empty window") as exc:
        load_pareto(path)
    assert "coast.duration" in lines[exc.value.line - 1] and f":{exc.value.line}" in str(exc.value)


def test_spec_negative_duration_bound(tmp_path):
    path, lines = _write_variant(tmp_path, "burn1: {duration: [0, 10]", "burn1: {duration: [-1, 10]")
    with pytest.raises(ParetoSpecError, match="phase 'burn1': negative duration bound -1") as exc:
        load_pareto(path)
    assert "burn1" in lines[exc.value.line - 1]
    path, lines = _write_variant(tmp_path, "range: [0, 2*pi]", "range: [-0.5, 2*pi]")
    with pytest.raises(ParetoSpecError, match="phase 'wait': negative duration bound") as exc:
        load_pareto(path)
    assert "wait.duration" in lines[exc.value.line - 1]


def test_spec_other_errors():
    base = {"method": "enumerate", "objectives": {"a": "x", "b": "y"}, "window": {"p": {"range": [0, 1]}}}
    assert parse_pareto(base).window["p"].starts == 4
    with pytest.raises(ParetoSpecError, match="Extra inputs are not permitted"):
        parse_pareto({**base, "methdo": "x"})
    with pytest.raises(ParetoSpecError, match="needs an epsilon"):
        parse_pareto({**base, "method": "epsilon"})
    with pytest.raises(ParetoSpecError, match="not a constant expression"):
        parse_pareto({**base, "window": {"p": {"range": [0, "__import__('os')"]}}})
    s = parse_pareto({**base, "method": "epsilon", "epsilon": {"objective": "b", "values": {"from": 1, "to": 2, "num": 3}}})
    assert s.epsilon.values == [1.0, 1.5, 2.0]


def test_objectives_equal_to_rounding_are_ties():
    """unseen22 FA2: one solution solved four times, J differing in its last bits, was flagged
    dominated by itself; a difference above rounding still dominates."""
    J = 0.44444444312112863
    same = [[3.0000000029774436, J], [3.0000000029774436, np.nextafter(J, 0)],
            [3.0000000029774436, np.nextafter(np.nextafter(J, 0), 0)]]
    assert P.nondominated(same).all()
    assert list(P.nondominated(same + [[3.0000000029774436, J * (1 - 1e-9)]])) == [False, False, False, True]


# the minimum-energy rest-to-rest transfer with T <= eps (J = 12 / eps^3); also the Pareto
# report's test (test_report_defects)
EPSILON_FRONT = (Path(__file__).parent / "data" / "pareto_energy_time.yaml").read_text()


@pytest.mark.parametrize("old,new,words", [
    # FC2: reported with the NLP's value (integral(u**2)), 50 % off
    ("energy: integral(u ** 2)", "energy: integral(2*u**2)", "the first Pareto objective is the one the NLP minimises"),
    # a traceback once: the others are read from final times and durations
    ("time: tf", "time: x(tf) + tf", "read from the phases' final times and durations"),
    ("method: {transcription: LGR, segments: 2, degree: 4}",
     "method: {transcription: flat-bspline, flat_outputs: [x], degree: 5, control_points: 8}", "pseudospectral collocation"),
])
def test_what_the_epsilon_nlp_solver_cannot_report_is_refused_at_check_time(tmp_path, old, new, words):
    path = tmp_path / "front.yaml"
    path.write_text(EPSILON_FRONT.replace(old, new))
    assert new in path.read_text()
    with pytest.raises(Exception) as err:
        load_pareto(path)
    assert "front.yaml:" in str(err.value) and words in str(err.value), str(err.value)


@pytest.mark.ipopt
def test_epsilon_front_first_objective_as_written_is_the_nlps(tmp_path):
    """The minimum-energy rest-to-rest transfer: integral(u**2) = 12 / T**3 on the front."""
    path = tmp_path / "front.yaml"
    path.write_text(EPSILON_FRONT)
    load_pareto(path)
    run_pareto(path, tmp_path / "run")
    rows = (tmp_path / "run" / "pareto.csv").read_text().splitlines()
    head = rows[0].split(",")
    for row in rows[1:]:
        cells = dict(zip(head, row.split(",")))
        T = float(cells["time"])
        assert abs(float(cells["energy"]) - 12 / T ** 3) <= 1e-6 * 12 / T ** 3


def test_objectives_equal_to_the_solvers_noise_are_ties():
    """unseen35 F3: an epsilon front of (miss, T) where every point past T = 1 reaches the
    target: misses of 2.1e-17, 5.7e-18, 1.1e-18 and 4.0e-19 (all zero) with longer and
    longer times were each "Pareto-optimal", each 1e-17 better in miss than the last. Within
    1e-9 of an objective's spread over the set they are ties, and only the shortest stays."""
    values = [[0.25, 0.5], [0.0625, 0.75], [2.1e-17, 1.1023], [5.7e-18, 1.7283], [1.1e-18, 2.3166],
              [4.0e-19, 2.8809]]
    assert P.nondominated(values).tolist() == [True, True, True, False, False, False]
    # a real trade-off far below 1e-9 of the spread in absolute terms is kept when it is the spread
    tiny = [[1e-12, 2.0], [0.5e-12, 3.0]]
    assert P.nondominated(tiny).tolist() == [True, True]


def test_a_closed_form_file_with_a_method_it_cannot_run_is_refused_at_check(tmp_path):
    """unseen35 F6: seed 4's case A with `method: weighted` passed `ocdsl check` and `run`
    refused it without a line ("closed_form exists for the two-burn programme ... with method
    enumerate"). Refused at the method's line by check and run alike."""
    text = (Path(__file__).parents[1] / "configs" / "seed4_case_A.yaml").read_text()
    assert "method: enumerate" in text
    path = tmp_path / "weighted.yaml"
    path.write_text(text.replace("method: enumerate", "method: weighted\n  weights: {num: 11}", 1))
    from ocdsl.spec.errors import SpecError

    with pytest.raises(SpecError) as e:
        load_pareto(path)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if "method: weighted" in ln)
    assert f"weighted.yaml:{line}" in str(e.value) and "runs method enumerate only" in str(e.value)


def _on_curve(g):
    s_grid = np.linspace(0, 1, 100001)

    def solve(w, warm):
        s = float(s_grid[int(np.argmin(w[0] * s_grid + w[1] * g(s_grid)))])
        return P.ParetoPoint({"f1": s, "f2": float(g(s))}, {"s": s})
    return solve


def test_a_jump_of_the_weights_spacing_alone_is_no_warning(recwarn):
    """unseen54 F5: on the convex front f2 = (1 - f1)^2 the weights 1 ... 0.7 all give its end
    (0, 1) and 0.6 gives (0.25, 0.5625): "the front may be non-convex there". Weights bisected
    between them close the jump; on a line (weighted sums find its ends only) it stays."""
    convex = P.weighted(_on_curve(lambda s: (1 - s) ** 2), 11, ["f1", "f2"])
    assert not convex.warnings
    assert not [w for w in recwarn if issubclass(w.category, P.ParetoWarning)]
    with pytest.warns(P.ParetoWarning, match="non-convex or flat"):
        line = P.weighted(_on_curve(lambda s: 1 - s), 11, ["f1", "f2"])
    assert "np.float64" not in line.warnings[0] and "(0.0, 1.0)" in line.warnings[0]
