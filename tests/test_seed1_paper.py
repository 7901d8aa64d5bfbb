"""Seed 1 paper mode: a short CI run of the machinery; the full runs are slow tests."""
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
    spec = lf.method.model_copy(update={"optimizer": lf.method.optimizer.model_copy(
        update={"particles": particles, "iterations": iterations, "seed": seed})})
    return lf, spec


def test_short_run_machinery(tmp_path):
    lf, spec = _short()
    res = run(lf.problem, spec, progress=False, integer_parameters={"N_rev"})
    assert res.status in ("feasible", "infeasible"), res.message
    assert res.iterations == 4 and res.extra["evaluations"] == 8 * 5
    assert 3 <= res.extra["N_rev"] <= 8 and isinstance(res.extra["N_rev"], int)
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
    assert pp.y0[1] == pytest.approx(-2.0)               # theta(t0): atan2 convention
    X = lo + np.random.default_rng(0).random((6, len(lo))) * (hi - lo)
    X[:, 0] = np.round(X[:, 0])
    serial = pp.final(X, parallel=False)
    threaded = pp.final(X, parallel=True)
    assert np.array_equal(serial[0], threaded[0]) and np.array_equal(serial[1], threaded[1])


PAPER = {10: (5, 1.8265), 5: (10, 3.024), 2: (25, 6.873)}


@pytest.mark.slow
@pytest.mark.parametrize("n", [10, 5, 2])
def test_paper_mode_reproduction(n):
    lf = load(CONFIGS / f"seed1_{n}N_paper.yaml")
    res = run(lf.problem, lf.method, progress=False, integer_parameters={"N_rev"})
    nrev, tf = PAPER[n]
    assert res.status == "feasible", res.message
    assert res.extra["N_rev"] == nrev
    assert abs(res.tf - tf) / tf < 0.02
    assert abs(res.extra["m_p"] - T_MAX[n] * res.tf / C) < 1e-6
