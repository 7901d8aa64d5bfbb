"""Seed 1 optimal mode: a paper-mode trajectory warm-starts LGR collocation (Cartesian, Sundman
variable) through the registered transform cr3bp_polar_to_sundman (ocdsl.search.refine_optimal,
declared in the file: ``guess: {from: ..., transform: ...}``, ocdsl/chain).

The fast test builds its own short "paper-mode" run (transverse thrust for 0.05 TU from the
GTO perigee), aims the optimal-mode file at that run's end point on a coarse mesh and checks
the conversion, the solve, the re-integration and the side-by-side table. The slow tests run
the optimal-mode files alone (``ocdsl.api.run_file``, what ``ocdsl run`` does): the chain
solves the paper-mode file first (or reuses its current run under reports/).
"""
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from ocdsl.result import PhaseTrajectory, Result
from ocdsl.search import refine_optimal as R
from ocdsl.symbolic import frames
from ocdsl.symbolic.registry import build_model

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
MU = 0.0121506683
T_MAX = {10: 2.4476474, 5: 1.2238237, 2: 0.4895295}
C = 28.751961
PAPER_X0 = dict(r=0.017632822153718267, theta=-2.0, z=0.0, rdot=0.0, thetadot=556.2661398665742,
                zdot=0.0, m=1.0)
POLAR = ("r", "theta", "z", "rdot", "thetadot", "zdot", "m")


def _short_paper_run(folder: Path, horizon: float) -> Result:
    """A paper-mode-like run folder: polar trajectory under a slowly turning thrust direction."""

    model = build_model("cr3bp_polar", {})
    f = sp.lambdify(list(model.states) + list(model.controls), list(model.rhs(model.default_parameters())), "numpy")

    def angles(t):
        return 0.2 * np.sin(2 * np.pi * t / horizon), np.pi / 2 - 0.1 * t / horizon

    def rhs(t, x):
        return np.array(f(*x, *angles(t)), float)

    t = np.linspace(0.0, horizon, 400)
    sol = solve_ivp(rhs, (0, horizon), [PAPER_X0[n] for n in POLAR], method="DOP853",
                    rtol=1e-12, atol=1e-13, t_eval=t)
    assert sol.success
    d, p = angles(t)
    states = {n: sol.y[i] for i, n in enumerate(POLAR)}
    res = Result(name="short paper", status="feasible", tf=horizon, wall_time_s={"total": 1.0},
                 phases=[PhaseTrajectory("main", t, states=states, controls={"delta": d, "phi": p})],
                 problem={"phases": {"main": {"states": list(POLAR), "controls": ["delta", "phi"]}}},
                 extra={"N_rev": 0})
    res.write(folder)
    return res


def _retarget(text: str, end: dict, segments: int, degree: int, paper: Path) -> str:
    """The 10 N optimal-mode file aimed at ``end`` (synodic state) on a coarse mesh, its guess
    from the run folder ``paper``."""
    out = []
    for line in text.splitlines():
        s = line.strip()
        for n in ("x", "y", "z", "vx", "vy", "vz"):
            if s.startswith(f"- {n}(tf) =="):
                line = f"    - {n}(tf) == {float(end[n])!r}"
        if s.startswith("segments:"):
            line = f"  segments: {segments}"
        if s.startswith("degree:"):
            line = f"  degree: {degree}"
        if s.startswith("- 1 <= tf <= 1000"):
            line = "    - 0.01 <= tf <= 1000"
        if s.startswith("time(tf):") or s == "expect:":
            continue
        if s.startswith("from: seed1_10N_paper.yaml"):
            line = f"    from: {paper}"
        if s.startswith("reuse:"):
            continue
        out.append(line)
    return "\n".join(out) + "\n"


@pytest.mark.ipopt
def test_refine_machinery_short_horizon(tmp_path):
    horizon = 0.05
    paper = _short_paper_run(tmp_path / "paper", horizon)
    fin = {n: float(paper.phase().states[n][-1]) for n in POLAR}
    end = dict(zip(("x", "y", "z", "vx", "vy", "vz"),
                   frames.ecrf_to_synodic(*(fin[n] for n in POLAR[:6]), MU)))
    cfg = tmp_path / "short_optimal.yaml"
    cfg.write_text(_retarget((CONFIGS / "seed1_10N_optimal.yaml").read_text(), end, 12, 5, tmp_path / "paper"))

    # conversion: the warm start starts at the initial state, ends at the paper's end at its tf
    import ocdsl

    loaded = ocdsl.load(cfg).file
    warm = R.paper_to_warm_start(tmp_path / "paper", loaded, tmp_path / "warm", points=500)
    w = warm.phase()
    assert w.states["time"][0] == 0.0
    assert w.states["time"][-1] == pytest.approx(horizon, abs=1e-9)
    assert np.all(np.diff(w.time) > 0) and np.all(np.diff(w.states["time"]) > 0)
    x0 = frames.ecrf_to_synodic(*(PAPER_X0[n] for n in POLAR[:6]), MU)
    for n, v in zip(("x", "y", "z", "vx", "vy", "vz"), x0):
        assert w.states[n][0] == pytest.approx(v, abs=1e-12)
    for n in ("x", "y", "z", "vx", "vy", "vz"):   # re-integrated in s: same end point
        assert w.states[n][-1] == pytest.approx(end[n], abs=1e-6)
    u = np.sqrt(w.controls["ux"] ** 2 + w.controls["uy"] ** 2 + w.controls["uz"] ** 2)
    assert np.allclose(u, 1.0, atol=1e-12)

    from ocdsl.api import run_file

    res = run_file(cfg, tmp_path / "opt")
    assert res.status == "optimal", res.message
    assert res.extra["chain"][0]["transform"] == "cr3bp_polar_to_sundman"
    tr = res.phase()
    t_opt = res.extra["tf_physical"]
    # the paper trajectory is feasible, so the minimum time is not later than its t_f
    assert 0 < t_opt <= horizon + 1e-6
    assert res.extra["m_p"] == pytest.approx(T_MAX[10] * t_opt / C, abs=1e-8)
    col = tr.extra["collocated"] > 0
    norm = tr.controls["ux"] ** 2 + tr.controls["uy"] ** 2 + tr.controls["uz"] ** 2
    assert np.allclose(norm[col], 1.0, atol=1e-7)
    # the collocated control, re-integrated, reaches the target
    reint = res.extra["reintegration"]
    assert reint["passed"], reint
    assert reint["position_error_LU"] < 1e-3 and reint["velocity_error_VU"] < 1e-3
    assert reint["arrival_time"] == pytest.approx(t_opt, abs=1e-6)
    # side by side, and the run folder round-trips
    back = Result.read(tmp_path / "opt")
    table = back.tables["paper_vs_optimal"]
    assert list(table["mode"]) == [0.0, 1.0]
    assert table["tf"][0] == pytest.approx(horizon) and table["tf"][1] == pytest.approx(t_opt)
    assert table["position_error_LU"][0] < 1e-9        # the paper run ends on its own target
    assert back.extra["side_by_side"]["optimal"]["N_rev"] == 0
    assert "convert_guess" in back.wall_time_s and "reintegrate" in back.wall_time_s


def test_refuses_a_non_polar_run(tmp_path):
    import ocdsl

    res = Result(name="x", status="optimal", tf=1.0,
                 phases=[PhaseTrajectory("main", np.linspace(0, 1, 3), states={"x": np.zeros(3)})],
                 problem={"phases": {"main": {"states": ["x"], "controls": []}}})
    res.write(tmp_path / "run")
    loaded = ocdsl.load(CONFIGS / "seed1_10N_optimal.yaml").file
    with pytest.raises(ValueError, match="not a polar paper-mode trajectory"):
        R.paper_to_warm_start(tmp_path / "run", loaded, tmp_path / "warm")


def test_revolutions_of_a_cartesian_trajectory():
    """N_rev of a Cartesian trajectory from the unwrapped angle, under the paper run's convention."""
    import ocdsl

    num = R._Numeric(ocdsl.load(CONFIGS / "seed1_10N_optimal.yaml").file)
    for end, n_rev in [(10 * np.pi + 0.3, 5), (8 * np.pi + 0.3, 4), (8 * np.pi - 0.3, 3)]:
        th = np.linspace(-2.0, end, 3000)
        r = np.linspace(0.02, 0.8, th.size)
        tr = PhaseTrajectory("main", th, states={"x": r * np.cos(th) - MU, "y": r * np.sin(th)})
        theta = R.unwrapped_angle(tr, num)
        assert theta[0] == pytest.approx(-2.0) and theta[-1] == pytest.approx(end)
        assert frames.revolutions(theta[-1]) == n_rev
        # counted from the paper run's start in [0, 2 pi) (4.28 rad): one revolution more
        theta = R.unwrapped_angle(tr, num, theta0=2 * np.pi - 2.0)
        assert theta[0] == pytest.approx(2 * np.pi - 2.0) and theta[-1] == pytest.approx(end + 2 * np.pi)
        assert frames.revolutions(theta[-1]) == n_rev + 1


@pytest.mark.parametrize("end_offset", [-4e-4, 0.0, 4e-4])
@pytest.mark.parametrize("paper_offset", [-9e-4, 9e-4])
def test_optimal_mode_counts_revolutions_against_the_paper_runs_target(end_offset, paper_offset):
    """Both runs end within zeta of the target angle 2 pi N_rev (theta_f = 0): on either side
    of it the optimal-mode end is counted in the paper run's class. The end angle's own
    [0, 2 pi) residue miscounts an end just below the target (a terminal box allows it)."""
    for n_rev in (5, 10, 25):
        target = 2 * np.pi * n_rev
        assert R._revolutions(target + end_offset, n_rev, target + paper_offset) == n_rev
    assert frames.revolutions(2 * np.pi * 10 - 4e-4) == 9
    assert R._revolutions(float("nan"), 10, 0.0) is None


# ---------------------------------------------------------------------------------------
# the full cases: paper mode first, then optimal mode from its best particle
def _paper_then_optimal(n: int, tmp_path: Path) -> tuple[Result, Result]:
    """``ocdsl run configs/seed1_<n>N_optimal.yaml`` alone: the chain runs the paper-mode file
    first (or reuses its current run under reports/)."""
    from ocdsl.api import run_file

    opt = run_file(CONFIGS / f"seed1_{n}N_optimal.yaml", tmp_path / "optimal")
    # no flight judges J of these minimum-time transfers (J of t_f alone, path constraints), so
    # the mesh is bisected: 10 N moved T by 2.8e-5 (1.5448003 -> 1.5447566), more than the
    # tolerance, and says mesh_not_converged; either way both T are the digest's to 1e-3
    bisection = opt.extra.get("bisection") or {}
    assert opt.status == "optimal" or (opt.status == "mesh_not_converged" and bisection.get("agrees") is False), \
        opt.message
    for level in bisection.get("levels", []):
        assert level["status"] == "optimal" and abs(level["objective"] - opt.objective) <= 1e-3 * opt.objective
    stage = opt.extra["chain"][0]
    paper = Result.read(stage["reused"] or tmp_path / "optimal" / "stages" / f"seed1_{n}N_paper")
    assert paper.phases
    tf = opt.extra["tf_physical"]
    assert opt.extra["m_p"] == pytest.approx(T_MAX[n] * tf / C, abs=1e-8)
    reint = opt.extra["reintegration"]
    assert reint["position_error_LU"] <= 1e-3 and reint["velocity_error_VU"] <= 1e-3, reint
    return paper, opt


@pytest.mark.slow
@pytest.mark.ipopt
def test_optimal_10N(tmp_path):
    paper, opt = _paper_then_optimal(10, tmp_path)
    tf = opt.extra["tf_physical"]
    assert tf <= 1.8065                     # the paper's indirect reference
    assert tf <= paper.tf
    assert all(c["passed"] for c in opt.expect)
    # the digest's independent collocation optimum (Hermite-Simpson N = 3000: 1.54475 TU), in
    # the paper's revolution class N_rev = 5 ([0, 2 pi) convention)
    assert abs(tf - 1.54475) <= 1e-3 * 1.54475, tf
    assert opt.extra["side_by_side"]["optimal"]["N_rev"] == paper.extra["N_rev"] == 5


@pytest.mark.slow
@pytest.mark.ipopt
@pytest.mark.parametrize("n", [5, 2])
def test_optimal_5N_2N(n, tmp_path):
    paper, opt = _paper_then_optimal(n, tmp_path)
    assert opt.extra["tf_physical"] <= paper.tf
    # in the paper's class and at or below its printed Fourier-DPSO tf (3.02396 / 6.8730 TU)
    assert opt.extra["side_by_side"]["optimal"]["N_rev"] == {5: 10, 2: 25}[n]
    assert all(c["passed"] for c in opt.expect)
