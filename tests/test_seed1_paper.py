"""Seed 1 paper mode: a short CI run of the machinery; the full runs are slow tests."""
import json
from pathlib import Path

import numpy as np
import pytest

from ocdsl.result import Result
from ocdsl.search.run import build, run
from ocdsl.spec.compile import load

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
T_MAX = {10: 2.4476474, 5: 1.2238237, 2: 0.4895295}
C = 28.751961


def _short(n=10, particles=8, iterations=4, seed=3):
    lf = load(CONFIGS / f"seed1_{n}N_paper.yaml")
    # the swarm and the polish only: the later local stages run in the slow tests
    spec = lf.method.model_copy(update={
        "optimizer": lf.method.optimizer.model_copy(update={"particles": particles, "iterations": iterations, "seed": seed}),
        "continuation": lf.method.continuation.model_copy(update={"enabled": False}),
        "refine": lf.method.refine.model_copy(update={"method": "none"})})
    return lf, spec


def test_short_run_machinery(tmp_path):
    lf, spec = _short()
    res = run(lf.problem, spec, progress=False, integer_parameters={"N_rev"})
    assert res.status in ("feasible", "infeasible"), res.message
    assert res.iterations == 4 and res.extra["evaluations"] == 8 * 5
    assert res.extra["N_rev"] == 5 and isinstance(res.extra["N_rev"], int)   # held at the paper's class
    tf = res.tf
    assert 1.2 <= tf <= 2.6
    ph = res.phase()
    assert abs(ph.time[-1] - tf) < 1e-12 and ph.time[0] == 0.0
    # thrust always on: m_p = T_max tf / c
    assert abs(res.extra["m_p"] - T_MAX[10] * tf / C) < 1e-6
    # the fitness is tf + the normalised penalties of the reported errors
    ratios = np.array(list(res.extra["terminal_error_over_zeta"].values()))
    assert res.extra["fitness_final"] == pytest.approx(tf + np.maximum(ratios - 1, 0).sum(), rel=1e-9)
    # the polish (configured) never makes the swarm's best worse, and keeps tf and N_rev
    assert res.extra["fitness_final"] <= res.extra["fitness"]
    assert res.extra["pso_only"]["tf"] == tf
    assert res.status == ("feasible" if np.all(ratios <= 1) else "infeasible")
    h = res.tables["history"]
    assert len(h["best_f"]) == 5 and np.all(np.diff(h["best_f"]) <= 0)
    assert h["best_f"][-1] == pytest.approx(res.extra["fitness"])
    # the run folder round-trips
    res.write(tmp_path / "run")
    back = Result.read(tmp_path / "run")
    assert back.extra["N_rev"] == res.extra["N_rev"]
    assert np.allclose(back.tables["history"]["best_f"], h["best_f"])
    # reproducible from the seed
    again = run(lf.problem, spec, progress=False, integer_parameters={"N_rev"})
    assert again.extra["decision_vector"] == res.extra["decision_vector"]


def test_executor_map_gives_the_same_search():
    lf, spec = _short(iterations=2)
    spec = spec.model_copy(update={"optimizer": spec.optimizer.model_copy(update={"chunks": 3})})
    a = run(lf.problem, spec, progress=False, integer_parameters={"N_rev"})
    b = run(lf.problem, spec, progress=False, integer_parameters={"N_rev"}, executor=map)
    assert a.extra["decision_vector"] == b.extra["decision_vector"]


def test_decision_vector_layout():
    lf, spec = _short()
    pp = build(lf.problem, spec, {"N_rev"})
    names = pp.names()
    assert names[:2] == ["N_rev", "tf"]                 # eq. 34 order
    assert len(names) == 30                             # 10 N: 2 + (2*5+1) + (2*8+1)
    lo, hi, is_int = pp.bounds()
    assert is_int.tolist() == [True] + [False] * 29
    assert pp.y0[1] == pytest.approx(2 * np.pi - 2.0)    # theta(t0): [0, 2 pi) convention
    X = lo + np.random.default_rng(0).random((6, len(lo))) * (hi - lo)
    X[:, 0] = np.round(X[:, 0])
    serial = pp.final(X, parallel=False)
    threaded = pp.final(X, parallel=True)
    assert np.array_equal(serial[0], threaded[0]) and np.array_equal(serial[1], threaded[1])


PAPER = {10: (5, 1.8265), 5: (10, 3.024), 2: (25, 6.873)}

READINGS = json.loads((Path(__file__).parent / "data" / "seed1_readings.json").read_text())
ATAN2, ARCTAN = READINGS["atan2"], READINGS["arctan"]
CLASS = json.loads((Path(__file__).parent / "data" / "seed1_class_solutions.json").read_text())["cases"]


def _class_values(n: int) -> dict[str, float]:
    """The stored class member of ``n`` N as class mode's values (T and coefficients)."""
    member = CLASS[f"{n}N"]
    return {"T": member["tf"], **member["coefficients"]}


def _variant_file(n: int, old: str, new: str, path: Path) -> Path:
    """The paper-mode file of ``n`` N with its text ``old`` (which must be there) replaced
    by ``new``, written to ``path``."""
    text = (CONFIGS / f"seed1_{n}N_paper.yaml").read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return path


def _reading_file(n: int, theta0: float, tmp_path: Path) -> Path:
    """The paper-mode file of ``n`` N with another initial angle (the files use 4.2832 rad)."""
    return _variant_file(n, "theta(t0) == 4.283185307179586", f"theta(t0) == {theta0!r}",
                         tmp_path / f"seed1_{n}N_theta0_{theta0:.4f}.yaml")


def _atan2_file(n: int, tmp_path: Path) -> Path:
    """theta counted from the atan2 value -2 rad of Table 2's state."""
    return _reading_file(n, -2.0, tmp_path)


# Measured on the 2-core machine (2026-11-23), configs as committed ([0, 2 pi) convention,
# polish + continuation + SLSQP refinement):
XFAIL_10N = ("10 N: N_rev 5, every terminal error inside zeta, but tf 1.94317 TU is +6.4 % from 1.8265: "
             "the swarm path (seeds 1, 2, 3), the projection of the optimal-mode control and 9 of 10 random "
             "starts that reached the zeta box end in the same Fourier-(5, 8) local minimum 1.9431-1.9432 "
             "(test_10N_local_minima_by_reading); under the atan2 reading the same stages end at 1.6896 "
             "(-7.5 %), so no reading puts 10 N within 2 % of a local minimum; with the files' reading the "
             "class reaches 1.8265 only with every terminal tolerance near 0.07 "
             "(test_10N_printed_tf_needs_a_terminal_tolerance_near_0_07)")
XFAIL_2N = ("2 N: N_rev 25, every terminal error inside zeta, but tf 7.24121 TU is +5.4 % from 6.873 "
            "(swarm 7.55380, continuation 7.36997, SLSQP with restoration 7.24121: its line search fails "
            "over 25 revolutions; one of two restorations got back inside zeta, the second did not; from "
            "the previous run's point the same stage reached 7.22492, +5.1 %). The class's unrestricted "
            "optimum is 6.83164 (optimal mode), 0.6 % below the paper; the Fourier class's best member "
            "found is 7.16586 even with coefficients bounded at 1000 "
            "(test_printed_tf_stays_below_the_class_optimum_without_coefficient_bounds)")


@pytest.mark.slow
@pytest.mark.parametrize("n", [pytest.param(10, marks=pytest.mark.xfail(strict=True, reason=XFAIL_10N)), 5,
                               pytest.param(2, marks=pytest.mark.xfail(strict=True, reason=XFAIL_2N))])
def test_paper_mode_reproduction(n):
    lf = load(CONFIGS / f"seed1_{n}N_paper.yaml")
    res = run(lf.problem, lf.method, progress=False, integer_parameters={"N_rev"})
    nrev, tf = PAPER[n]
    assert res.status == "feasible", res.message
    ratios = np.array(list(res.extra["terminal_error_over_zeta"].values()))
    assert np.all(ratios <= 1.0)
    assert abs(res.extra["m_p"] - T_MAX[n] * res.tf / C) < 1e-6
    if "continuation" in res.extra:   # the swarm's and the polish's numbers are kept apart
        c = res.extra["continuation"]
        assert c["polished"]["tf"] == res.extra["pso_only"]["tf"] >= res.tf
    if "refine" in res.extra:         # SLSQP starts where the continuation stopped
        r = res.extra["refine"]
        assert r["tf_start"] == res.extra["continuation"]["tf_end"] >= r["tf_end"] == res.tf
    assert res.extra["N_rev"] == nrev
    assert abs(res.tf - tf) / tf < 0.02, (res.tf, tf)


TOY = """\
name: toy minimum-time double integrator, parametric
model:
  states: [x, v]
  controls: [u]
  dynamics:
    x: v
    v: u
problem:
  time: {t0: 0, tf: free}
  constraints:
    - x(t0) == 0
    - v(t0) == 0
    - x(tf) == 1
    - v(tf) == 0
    - 1.0 <= tf <= 4.0
  objective: minimize tf
method:
  transcription: parametric
  controls:
    u: {series: fourier, order: 1, bounds: [-1.0, 1.0], a0: [-1.0, 1.0]}
  tolerances: {default: 1.0e-3}
  integrator: {rtol: 1.0e-10, atol: 1.0e-12}
  polish: {method: least_squares, max_iterations: 200}
  continuation: {enabled: true, step: 0.05, min_step: 1.0e-3, max_steps: 60}
  optimizer: {particles: 6, iterations: 2, seed: 0}
"""


def _lp_tf_min(zeta):
    """Independent bound: with u = a0/2 + a1 cos(pi t/tf) + b1 sin(pi t/tf),
    v(tf) = tf (a0/2 + 2 b1/pi) and x(tf) = tf^2 (a0/4 + 2 a1/pi^2 + b1/pi), so the
    smallest tf reaching x = 1 +- zeta, v = 0 +- zeta over the coefficient box is an LP
    in the coefficients (for a given tf) -- bisection on tf."""
    from scipy.optimize import linprog

    def reach(tf):   # max x(tf)/tf^2 with |v(tf)| <= zeta
        c = -np.array([1 / 4, 2 / np.pi ** 2, 1 / np.pi])
        A = np.array([[1 / 2, 0, 2 / np.pi], [-1 / 2, 0, -2 / np.pi]])
        r = linprog(c, A_ub=A, b_ub=[zeta / tf, zeta / tf], bounds=[(-1, 1)] * 3)
        return -r.fun
    lo, hi = 1.0, 4.0
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if mid ** 2 * reach(mid) >= 1 - zeta else (mid, hi)
    return hi


def test_continuation_in_tf_reaches_the_lp_minimum(tmp_path):
    from ocdsl.search.local import continue_tf

    p = tmp_path / "toy.yaml"
    p.write_text(TOY)
    lf = load(p)
    pp = build(lf.problem, lf.method)
    assert pp.names() == ["tf", "u_a0", "u_a1", "u_b1"]
    x0 = np.array([3.0, 0.0, np.pi ** 2 / (2 * 9.0), 0.0])     # exactly on target at tf = 3
    assert pp.details(x0)["ratio"].max() < 1e-6
    x, info, table = continue_tf(pp, x0, lf.method.polish, lf.method.continuation)
    det = pp.details(x)
    assert np.all(det["ratio"] <= 1.0)                          # every accepted point inside zeta
    assert info["tf_end"] == det["tf"] == x[0] and info["tf_start"] == 3.0
    tf_min = _lp_tf_min(1e-3)                                   # pi/sqrt(2) up to the zeta slack
    assert abs(tf_min - np.pi / np.sqrt(2)) < 0.01
    assert tf_min - 1e-9 <= det["tf"] <= tf_min * 1.01, (det["tf"], tf_min)
    acc = table["accepted"].astype(bool)
    assert np.all(np.diff(table["tf"]) <= 0) and table["tf"][-1] == det["tf"]
    assert np.all(table["max_error_over_zeta"][acc] <= 1.0)
    # below the minimum no coefficients reach the target with tf fixed: the continuation
    # first restores feasibility with tf free, then comes back down
    xb = np.array([2.0, 0.0, 1.0, 0.0])
    assert pp.details(xb)["ratio"].max() > 100
    x, info, _ = continue_tf(pp, xb, lf.method.polish, lf.method.continuation)
    assert info["restored_with_free_tf"]["tf"] >= tf_min - 1e-9
    assert info["restored_with_free_tf"]["max_error_over_zeta"] <= lf.method.continuation.target_ratio
    assert np.all(pp.details(x)["ratio"] <= 1.0) and tf_min - 1e-9 <= x[0] <= tf_min * 1.01
    # the runner keeps the swarm's and the polish's numbers apart from the continued ones
    res = run(lf.problem, lf.method, progress=False)
    c = res.extra["continuation"]
    if c["continuation"].startswith("skipped"):
        assert res.tf == res.extra["pso_only"]["tf"]
    else:
        assert res.tf == c["tf_end"] <= c["polished"]["tf"] == res.extra["pso_only"]["tf"]
        assert res.status == "feasible" and "continuation" in res.tables


def test_slsqp_refinement_reaches_the_lp_minimum(tmp_path):
    """The constrained refinement (min tf with every |e|/zeta <= target) lands on the LP
    bound of the toy problem from a point far above it, with the errors inside the box,
    and a widened box (box_scale) can only lower it further."""
    from ocdsl.search.local import refine_objective
    from ocdsl.spec.parametric import RefineSpec

    p = tmp_path / "toy.yaml"
    p.write_text(TOY)
    lf = load(p)
    pp = build(lf.problem, lf.method)
    x0 = np.array([3.0, 0.0, np.pi ** 2 / (2 * 9.0), 0.0])
    x, info = refine_objective(pp, x0, RefineSpec(method="slsqp", target_ratio=0.999))
    det = pp.details(x)
    tf_min = _lp_tf_min(1e-3)
    assert np.all(det["ratio"] <= 1.0 + 1e-6)
    assert abs(det["tf"] - tf_min) <= 1e-4 * tf_min, (det["tf"], tf_min, info)
    assert info["tf_start"] == 3.0 and info["tf_end"] == det["tf"]
    x2, info2 = refine_objective(pp, x0, RefineSpec(method="slsqp", target_ratio=0.999, box_scale=2.0))
    assert not info2["refine"].startswith("rejected") and info2["tf_end"] <= info["tf_end"] + 1e-9, info2
    # a start it cannot improve on (tf at its lower bound, far outside the box) is rejected
    xb = np.array([1.0, 0.0, 0.0, 0.0])
    x3, info3 = refine_objective(pp, xb, RefineSpec(method="slsqp", max_iterations=3))
    assert np.array_equal(x3, xb) and info3["refine"].startswith("rejected")


def test_refinement_restores_an_iterate_outside_the_zeta_box(tmp_path):
    """SLSQP stopped after 2 iterations ends outside the zeta box below the best tf: least
    squares at that tf brings it back inside and SLSQP restarts from there to the LP bound;
    an iterate below the bound (1 iteration) cannot be restored and the start is kept."""
    from ocdsl.search.local import refine_objective
    from ocdsl.spec.parametric import RefineSpec

    p = tmp_path / "toy.yaml"
    p.write_text(TOY)
    lf = load(p)
    pp = build(lf.problem, lf.method)
    x0 = np.array([3.0, 0.0, np.pi ** 2 / (2 * 9.0), 0.0])
    tf_min = _lp_tf_min(1e-3)
    x, info = refine_objective(pp, x0, RefineSpec(method="slsqp", target_ratio=0.999, max_iterations=2, restarts=0))
    assert info["restorations"] == {"attempts": 1, "inside": 1}
    assert np.all(pp.details(x)["ratio"] <= 1.0) and tf_min <= x[0] < 3.0
    x, info = refine_objective(pp, x0, RefineSpec(method="slsqp", target_ratio=0.999, max_iterations=2, restarts=3))
    assert info["restorations"]["inside"] >= 1 and info["slsqp_runs"] >= 2
    assert np.all(pp.details(x)["ratio"] <= 1.0) and abs(x[0] - tf_min) <= 1e-4 * tf_min, (x[0], tf_min)
    x, info = refine_objective(pp, x0, RefineSpec(method="slsqp", target_ratio=0.999, max_iterations=1))
    assert info["restorations"] == {"attempts": 1, "inside": 0} and np.array_equal(x, x0)


@pytest.mark.slow
def test_10N_local_minima_by_reading(tmp_path):
    """Why 10 N paper mode misses the 2 % band (docs/seed1.md): from random starts the local
    stages end in one Fourier-(5, 8) minimum near 1.943 TU under the files' [0, 2 pi)
    reading, above 1.8265 + 2 %; under the atan2 reading they end more than 2 % *below*
    1.8265, so there the paper's number is not a local minimum of its own problem."""
    from ocdsl.search.multistart import local_minima

    minima = local_minima(str(CONFIGS / "seed1_10N_paper.yaml"), starts=10, seed=1, verbose=False)
    assert len(minima) >= 3, minima
    assert min(minima) > 1.8265 * 1.02, minima
    assert sum(m - min(minima) < 1e-3 for m in minima) >= 3, minima     # one basin, reached again and again
    minima = local_minima(str(_atan2_file(10, tmp_path)), starts=8, seed=0, verbose=False)
    assert len(minima) >= 2 and min(minima) < 1.8265 * 0.98, minima


def test_10N_printed_tf_is_not_the_minimum_under_the_atan2_count(tmp_path):
    """Under the revolution count the paper's Table 5 implies for [36] (theta from -2 rad),
    a Fourier-(5, 8) member with N_rev = 5, every terminal error inside zeta and thrust always
    on reaches the halo point in 1.68958 TU, 7.5 % below the printed 1.8265 TU: there the
    printed value is not the minimum of the paper's own problem (a run of the file with that
    count, session 8; docs/seed1.md)."""
    case = ATAN2["10N"]
    atan2 = load(_atan2_file(10, tmp_path))
    pp = build(atan2.problem, atan2.method, {"N_rev"})
    assert pp.y0[1] == -2.0
    x = np.array([case["decision_vector"][n] for n in pp.names()])
    det = pp.details(x)
    assert det["variables"]["N_rev"] == 5 and det["status"] == 1
    assert np.all(det["ratio"] <= 1.0), det["ratio"]
    assert det["fitness"] == det["tf"] == case["tf"]
    assert det["tf"] < 0.98 * PAPER[10][1]
    m_p = 1.0 - det["final"][6]
    assert abs(m_p - T_MAX[10] * det["tf"] / C) < 1e-6         # the check (8-digit T_max, c)
    # the same control counted from the files' [0, 2 pi) angle is N_rev = 4, not the paper's class
    files = load(CONFIGS / "seed1_10N_paper.yaml")
    assert build(files.problem, files.method, {"N_rev"}).details(x)["ratio"].max() > 1000


def test_10N_printed_tf_is_met_with_eq_27_as_printed(tmp_path):
    """Eq. (27) as printed, theta = arctan(y / (x + mu)) with the principal arctan, gives
    pi - 2 = 1.1416 rad for Table 2's state: the perigee mirrored through the Earth. With
    that start the file's own stages end at 1.81799 TU (SLSQP converged there), 0.47 % below
    the printed 1.8265, with N_rev = 5 and every terminal error inside zeta; the fastest
    transfer of that class over all controls is 1.7734 (optimal mode from the mirrored
    start, docs/seed1.md). The same reading does not give 5 N or 2 N (3.22650 and 7.77389;
    class optima 3.06626 and 7.03420, above the printed 3.02396 and 6.8730), so it is no more
    the paper's reading than the others."""
    import math

    theta0 = math.atan(-0.016033479812051 / (-0.019488511458668 + 0.0121506683))   # Table 2
    assert theta0 == pytest.approx(math.pi - 2.0, abs=1e-12)
    case = ARCTAN["10N"]
    arctan = load(_reading_file(10, math.pi - 2.0, tmp_path))
    pp = build(arctan.problem, arctan.method, {"N_rev"})
    det = pp.details(np.array([case["decision_vector"][n] for n in pp.names()]))
    assert det["variables"]["N_rev"] == 5 and np.all(det["ratio"] <= 1.0), det["ratio"]
    assert det["tf"] == case["tf"] and abs(det["tf"] - PAPER[10][1]) / PAPER[10][1] < 0.005
    assert abs(1.0 - det["final"][6] - T_MAX[10] * det["tf"] / C) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("n, class_optimum", [(5, 3.07341), (2, 6.88598)])
def test_printed_tf_is_below_the_class_optimum_under_the_atan2_count(tmp_path, n, class_optimum):
    """Under the atan2 count the paper's 5 N and 2 N values (3.02396 TU with N_rev = 10,
    6.8730 TU with N_rev = 25) are below the minimum time of those revolution classes over
    *all* thrust-direction histories with the paper's own terminal box (every polar terminal
    error within zeta): optimal mode with that box, from this session's paper-mode members
    (3.19341, 7.30531), ends at 3.07341 and 6.88598 (exact terminal state: 3.07732, as in
    session 1 from another start, and 6.89558; docs/seed1.md). With the 10 N test above: no
    reading makes every printed value attainable and Table 5's N_rev comparison true at once."""
    import yaml

    from ocdsl.api import run_file
    from ocdsl.search import class_collocation as cc

    case = ATAN2[f"{n}N"]
    paper_file = load(_atan2_file(n, tmp_path))
    values = {("T" if k == "tf" else k): v for k, v in case["decision_vector"].items() if k != "N_rev"}
    member = cc.member_run(paper_file, values, tmp_path / "member")
    assert member.status == "feasible" and member.tf == pytest.approx(case["tf"], rel=1e-9)
    doc = yaml.safe_load((CONFIGS / f"seed1_{n}N_optimal.yaml").read_text())
    doc["problem"]["constraints"] = cc.with_terminal_box(doc["problem"]["constraints"], doc,
                                                         cc.paper_tolerances(paper_file)[0], 1.0)
    doc.pop("expect")
    doc["problem"]["guess"] = {"from": str(tmp_path / "member"), "transform": "cr3bp_polar_to_sundman"}
    boxed = tmp_path / "optimal_box.yaml"
    boxed.write_text(yaml.safe_dump(doc, sort_keys=False, width=100000))
    res = run_file(boxed, tmp_path / "optimal")
    assert res.extra["reintegration"]["passed"]
    assert res.extra["side_by_side"]["optimal"]["N_rev"] == PAPER[n][0]
    assert res.extra["tf_physical"] == pytest.approx(class_optimum, abs=5e-4)
    assert res.extra["tf_physical"] > 1.0015 * PAPER[n][1]
    # the fixed mesh's own bisection check (the runs of 2026-12-06 on): at 5 N the 240 x 6
    # mesh is not converged to 1e-5 (bisected: 3.07322, 5.9e-5 lower; the control jumps at a
    # node near the end), so the run says mesh_not_converged, not optimal; the comparison
    # with the printed value holds on every level, its margin (1.6 %) far above that error
    assert res.status in ("optimal", "acceptable", "mesh_not_converged")
    check = res.extra.get("bisection") or {}
    levels = [res.objective] + [lv["objective"] for lv in check.get("levels", [])]
    tf_scale = res.extra["tf_physical"] / res.objective
    assert all(tf_scale * J > 1.0015 * PAPER[n][1] for J in levels)
    assert all(tf_scale * J == pytest.approx(class_optimum, abs=5e-4) for J in levels)
    if res.status == "mesh_not_converged":
        assert check["estimated_error"] < 0.01 * (res.extra["tf_physical"] / PAPER[n][1] - 1)


def test_default_tolerance_integration_cannot_resolve_the_terminal_box(tmp_path):
    """The paper states no integrator. At the default tolerances of MATLAB's ode45 and SciPy's
    solve_ivp (Dormand-Prince 5(4), rtol 1e-3, atol 1e-6), the verified 10 N class member
    (1.93743 TU, every terminal error within 0.9 zeta by the files' DOP853 fitness) ends
    thousands of zeta from the halo point, in physical time as eq. (28) is written: a fitness
    evaluated that way cannot tell members inside the terminal box from members far outside,
    so t_f values found with it need not survive accurate integration (docs/seed1.md)."""
    from ocdsl.search.class_collocation import _decision_vector
    from ocdsl.simulate import scipy_final_state

    lf = load(_variant_file(10, "integrator: {rtol: 1.0e-8, atol: 1.0e-10, sundman_k: 1.5}",
                            "integrator: {rtol: 1.0e-8, atol: 1.0e-10}", tmp_path / "physical_time.yaml"))
    pp, x = _decision_vector(lf, _class_values(10))
    assert pp.model.states[-1].name != "time"          # no Sundman clock: eq. (28) in t
    var, tf, CD = pp.decode(x)
    assert var["N_rev"][0] == 5
    P = pp._P(var, 1)[0]

    def ratios(method, rtol, atol):
        y, _ = scipy_final_state(pp.compiled, pp.y0, float(tf[0]), P, pp.layout, CD[0],
                                 rtol=rtol, atol=atol, method=method)
        E, _ = pp.errors(y[None], var, tf)
        return np.abs(E[0]) / np.array([t.zeta for t in pp.terminals])

    assert ratios("DOP853", 1e-11, 1e-13).max() <= 0.91          # the member, in physical time
    assert ratios("RK45", 1e-6, 1e-9).max() > 1.0                 # already outside the box
    assert ratios("RK45", 1e-3, 1e-6).max() > 1e3                 # the defaults: far outside


def _zeta_file(n: int, zeta: float, tmp_path: Path) -> Path:
    """The paper-mode file of ``n`` N with every terminal tolerance set to ``zeta`` (the
    files use 1e-3; the paper states none)."""
    states = ("r", "theta", "z", "rdot", "thetadot", "zdot")
    return _variant_file(n, "tolerances: {" + ", ".join(f"{s}: 1.0e-3" for s in states) + "}",
                         "tolerances: {" + ", ".join(f"{s}: {zeta!r}" for s in states) + "}",
                         tmp_path / f"seed1_{n}N_zeta_{zeta:g}.yaml")


def _class_chain(tmp_path: Path, n: int, steps, segments: int) -> list:
    """Class mode (:mod:`ocdsl.search.class_collocation`) from the stored class member of
    ``n`` N, each step from the previous step's optimum; ``steps`` are (zeta, coefficient
    bound) pairs. Returns the Results."""
    from ocdsl.search import class_collocation as cc

    previous = tmp_path / "member"
    start = cc.member_run(load(CONFIGS / f"seed1_{n}N_paper.yaml"), _class_values(n), previous)
    assert start.status == "feasible"
    results = []
    for zeta, bound in steps:
        out = tmp_path / f"class_{zeta:g}_{bound:g}"
        paper_file = CONFIGS / f"seed1_{n}N_paper.yaml" if zeta == 1e-3 else _zeta_file(n, zeta, tmp_path)
        res = cc.refine_class(paper_file, CONFIGS / f"seed1_{n}N_optimal.yaml", out, paper_run=previous,
                              segments=segments, coefficient_bound=bound, progress=False)
        assert res.status == "feasible", res.message            # hard problem solved, inside zeta
        assert res.extra["N_rev"] == PAPER[n][0]
        results.append(res)
        previous = out
    return results


@pytest.mark.slow
def test_10N_printed_tf_needs_a_terminal_tolerance_near_0_07(tmp_path):
    """The files' zeta = 1e-3 is a choice (the paper gives none). Under the files' revolution
    count the fastest Fourier-(5, 8) member found from the stored class member (1.93743 TU)
    stays above the printed 1.8265 TU until every terminal tolerance is between 0.06 and 0.08
    (23,000-31,000 km and 61-82 m/s): the 10 N miss is not an artefact of zeta, and the
    coefficient bound is inactive from zeta = 3e-2 on (measured 2026-12-02, docs/seed1.md)."""
    chain = {3e-3: 1.93412, 1e-2: 1.92250, 3e-2: 1.88906, 6e-2: 1.83780, 8e-2: 1.80216}
    results = _class_chain(tmp_path, 10, [(z, 60.0) for z in chain], segments=120)
    optima = [r.tf for r in results]
    assert optima == pytest.approx(list(chain.values()), abs=5e-4)
    assert optima == sorted(optima, reverse=True)                 # a larger box, a faster member
    assert optima[-2] > PAPER[10][1] > optima[-1]
    assert results[-2].extra["class_mode"]["coefficients_at_bound"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("n, bounds, optimum", [(5, (60.0, 120.0, 300.0, 1000.0), 3.05879),
                                                (2, (1000.0,), 7.16586)])
def test_printed_tf_stays_below_the_class_optimum_without_coefficient_bounds(tmp_path, n, bounds, optimum):
    """The paper bounds no Fourier coefficient; the files bound them at 30 to 60. Released to
    1000 (the 5 N optimum then has no coefficient at its bound, its largest 573 rad), the
    class optimum from the stored member moves to 3.05879 TU at 5 N (from 3.07578) and
    7.16586 at 2 N (from 7.16670), still above the printed 3.02396 and 6.8730 with the files'
    zeta (at 10 N nothing moves: 1.93743 for bounds 120 to 1000)."""
    results = _class_chain(tmp_path, n, [(1e-3, b) for b in bounds], segments=120 if n == 5 else 300)
    optima = [r.tf for r in results]
    assert optima == sorted(optima, reverse=True)
    assert optima[-1] == pytest.approx(optimum, abs=5e-4)
    assert optima[-1] > PAPER[n][1]
