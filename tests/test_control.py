"""LQR, SDRE and Theta-D on the seed-3 spacecraft (seed_003.md section 5)."""
from pathlib import Path

import json

import numpy as np
import pytest
import yaml
from pydantic import ValidationError

from ocdsl.control.lqr import ControlError, LQRController
from ocdsl.control.run import robustness_sweep, run_controllers
from ocdsl.control.sdre import SDREController
from ocdsl.control.simulate import overshoot, settling_time, simulate
from ocdsl.control.theta_d import ThetaDController
from ocdsl.result import Result
from ocdsl.spec.controller import ControllerSpec, to_number
from ocdsl.symbolic import sdc
from ocdsl.symbolic.registry import build_model

ROOT = Path(__file__).resolve().parents[1]
AUX = ["hx", "hy", "hz"]
Q = np.diag([0.5] * 6 + [0.05] * 3)
R = np.eye(3)
DEG = np.pi / 180


def _load(name):
    return yaml.safe_load((ROOT / "configs" / name).read_text())


@pytest.fixture(scope="module")
def plant():
    from ocdsl.models.spacecraft_wheels import paper_sdc_matrix

    m = build_model("spacecraft_wheels", {})
    num = sdc.lambdify_sdc(sdc.given(m, paper_sdc_matrix(m), auxiliary=AUX))
    z0 = np.zeros(12)
    z0[:3] = 10 * DEG
    z0[6:9] = 0.01
    return m, num, z0


# ---- method checks (B1-B5) -------------------------------------------------------

def test_T0_is_the_lqr_riccati_solution(plant):
    m, num, z0 = plant
    lqr = LQRController(num, Q, R)
    td = ThetaDController(num, Q, R)
    np.testing.assert_allclose(td.T0, lqr.P, rtol=1e-9, atol=1e-12 * np.abs(lqr.P).max())
    assert np.allclose(td.T0, td.T0.T) and np.linalg.eigvalsh(td.T0).min() > 0
    assert np.linalg.eigvals(td.Ac).real.max() < 0
    resid = td.A0.T @ td.T0 + td.T0 @ td.A0 - td.T0 @ td.S @ td.T0 + Q
    assert np.abs(resid).max() < 1e-10


def test_lqr_integral_gains_are_sqrt_half(plant):
    K = LQRController(plant[1], Q, R).K
    np.testing.assert_allclose(K[:, 3:6], np.sqrt(0.5) * np.eye(3), atol=1e-4)


def test_theta_d_equals_lqr_at_t0_with_k_one(plant):
    m, num, z0 = plant
    u_td = ThetaDController(num, Q, R, terms=3, k=[1, 1], a=[0.5, 0.5])(0.0, z0)
    u_lqr = LQRController(num, Q, R)(0.0, z0)
    np.testing.assert_allclose(u_td, u_lqr, rtol=0, atol=1e-12)
    # ... and not later: the higher terms fade in
    assert np.abs(ThetaDController(num, Q, R)(5.0, z0) - u_lqr).max() > 1e-3


@pytest.mark.parametrize("terms", [1, 2, 3])
def test_theta_d_series_converges_to_sdre_at_order_N_plus_1(plant, terms):
    m, num, z0 = plant
    sdre = SDREController(num, Q, R)
    td = ThetaDController(num, Q, R, terms=terms, k=0.0)
    err = [np.linalg.norm(sdre.riccati(s * z0) - td.gain_matrix(0.0, s * z0)) for s in (1, 0.5, 0.25, 0.125)]
    ratios = np.array(err[:-1]) / np.array(err[1:])
    target = 2.0 ** terms  # N = terms - 1, error O(s^(N+1))
    assert np.all(np.abs(ratios / target - 1) < 0.15), (err, ratios)


def test_lyapunov_paths_agree_and_online_step_avoids_riccati(plant, monkeypatch):
    m, num, z0 = plant
    a = ThetaDController(num, Q, R, k=0.0, lyapunov="schur")
    b = ThetaDController(num, Q, R, k=0.0, lyapunov="scipy")
    for Ta, Tb in zip(a.series(1.0, z0), b.series(1.0, z0)):
        np.testing.assert_allclose(Ta, Tb, atol=1e-10 * np.abs(Tb).max())
    import scipy.linalg as sla

    def boom(*args, **kw):
        raise AssertionError("Riccati solved online")

    monkeypatch.setattr(sla, "solve_continuous_are", boom)
    a(2.0, z0)  # no Riccati equation in the online step


def test_unstabilisable_pair_gives_clear_error():
    m = build_model("spacecraft_wheels", {"wheels": "2"})
    num = sdc.lambdify_sdc(sdc.factorise(m, auxiliary=AUX))
    with pytest.raises(ControlError, match="rank 6 of 9"):
        LQRController(num, Q, np.eye(2))
    with pytest.raises(ControlError, match="rank 6 of 9"):
        ThetaDController(num, Q, np.eye(2))


# ---- closed loop (A4, A5, A7) -----------------------------------------------------

@pytest.fixture(scope="module")
def closed_loop(plant):
    m, num, z0 = plant
    out = {}
    for c in (LQRController(num, Q, R), SDREController(num, Q, R), ThetaDController(num, Q, R)):
        out[c.kind] = simulate(num.f, c, z0, num.index, Q, R, horizon=150.0, dt=0.05)
    return out


def test_all_three_regulate_the_angles(closed_loop):
    for kind, s in closed_loop.items():
        ang = np.abs(s.z[:, :3]) / DEG
        assert s.status == "stable", kind
        assert ang[s.t >= 60.0].max() < 0.1, kind
        assert ang[-1].max() < 1e-3 and s.t[-1] == pytest.approx(150.0), kind
        assert max(settling_time(s.t, s.z[:, i], 0.1 * DEG) for i in range(3)) < 60.0


def test_sdre_and_theta_d_are_close(closed_loop):
    d = np.abs(closed_loop["sdre"].z[:, :3] - closed_loop["theta-d"].z[:, :3]).max(axis=0) / DEG
    assert np.all(d < 0.5), d
    pk_s = np.abs(closed_loop["sdre"].u).max(axis=0)
    pk_t = np.abs(closed_loop["theta-d"].u).max(axis=0)
    assert np.all(np.abs(pk_t / pk_s - 1) < 0.2)


def test_lqr_pitch_undershoot_is_the_largest(closed_loop):
    mins = {k: overshoot(s.z[:, 1])["overshoot"] for k, s in closed_loop.items()}
    assert mins["lqr"] >= mins["sdre"] and mins["lqr"] >= mins["theta-d"]


def test_costs_agree_within_one_percent(closed_loop):
    J = {k: s.J for k, s in closed_loop.items()}
    assert max(J.values()) / min(J.values()) - 1 < 0.01, J


def test_cost_integration_is_converged(plant):
    m, num, z0 = plant
    J = {}
    for integ, dt in (("rk4", 0.05), ("rk45", 0.05), ("rk4", 0.01)):
        J[(integ, dt)] = simulate(num.f, LQRController(num, Q, R), z0, num.index, Q, R, 60.0, dt,
                                  integrator=integ).J
    assert abs(J[("rk4", 0.05)] / J[("rk45", 0.05)] - 1) < 1e-6
    assert abs(J[("rk4", 0.05)] / J[("rk4", 0.01)] - 1) < 1e-3


def test_saturation_and_update_rate(plant):
    m, num, z0 = plant
    s = simulate(num.f, LQRController(num, Q, R), z0, num.index, Q, R, 60.0, 0.05, update=0.25,
                 saturation=0.5)
    assert np.abs(s.u).max() <= 0.5 + 1e-15 and np.abs(s.u_raw).max() > 0.5
    assert s.ctrl_time.size == int(60 / 0.25) + 1
    blocks = s.u[:-1].reshape(-1, 5, 3)
    assert np.all(blocks == blocks[:, :1, :])  # held between updates
    assert s.saturated_fraction > 0
    with pytest.raises(ValueError, match="multiple"):
        simulate(num.f, LQRController(num, Q, R), z0, num.index, Q, R, 1.0, 0.05, update=0.07)


def test_metrics_helpers():
    t = np.linspace(0, 10, 11)
    y = np.array([1.0, 0.5, -0.2, 0.05, 0.01, 0, 0, 0, 0, 0, 0])
    assert settling_time(t, y, 0.1) == 3.0
    o = overshoot(y)
    assert o["overshoot"] == pytest.approx(0.2) and o["overshoot_pct"] == pytest.approx(20.0)


# ---- problem files, Result, robustness ---------------------------------------------

@pytest.mark.parametrize("name", ["seed3_attitude.yaml", "seed3_robustness.yaml"])
def test_config_controller_block_validates(name):
    d = _load(name)
    spec = ControllerSpec.model_validate(d["controller"])
    assert spec.types() == ["lqr", "sdre", "theta-d"]
    assert [s.type for s in spec.expand()] == ["lqr", "sdre", "theta-d"]
    assert spec.matrix("Q", 9)[0, 0] == 0.5 and spec.matrix("R", 3)[2, 2] == 1.0
    x0 = spec.simulate.initial_state([str(s) for s in build_model("spacecraft_wheels", {}).states])
    np.testing.assert_allclose(x0[:3], 0.174533, atol=1e-6)
    np.testing.assert_allclose(x0[6:9], 0.01)


def test_controller_spec_rejects_mistakes():
    base = _load("seed3_attitude.yaml")["controller"]
    for bad in ({"Qq": [1]}, {"sdc": "given", "A": None}, {"type": "pid"},
                {"theta_d": {"terms": 3, "k": [1]}}, {"simulate": {**base["simulate"], "update": 0.07}}):
        with pytest.raises(ValidationError):
            ControllerSpec.model_validate({**base, **bad})
    assert to_number("10deg") == pytest.approx(np.pi / 18)
    assert to_number("pi/18") == pytest.approx(np.pi / 18)
    with pytest.raises(Exception):
        to_number("__import__('os')")


def test_given_sdc_from_the_problem_file_is_the_papers(plant):
    from ocdsl.models.spacecraft_wheels import paper_sdc_matrix
    from ocdsl.control.run import build_sdc

    m = build_model("spacecraft_wheels", {})
    spec = ControllerSpec.model_validate(_load("seed3_attitude.yaml")["controller"])
    fac = build_sdc(m, spec)
    assert fac.method == "given"
    assert (fac.A - paper_sdc_matrix(m)).applyfunc(lambda e: e.simplify()) == paper_sdc_matrix(m) * 0


def test_run_controllers_results_round_trip(tmp_path):
    d = _load("seed3_attitude.yaml")
    d["controller"]["type"] = ["lqr", "theta-d"]
    d["controller"]["simulate"].update(horizon=20.0, check_times=[10])
    m = build_model("spacecraft_wheels", d["model"]["options"])
    res = run_controllers(m, [d["controller"]], parameters=d["model"]["parameters"])
    assert [r.extra["kind"] for r in res] == ["lqr", "theta-d"]
    for r in res:
        assert r.status in ("stable", "unstable") and r.objective > 0
        assert "settling_time@0.1deg" not in r.extra["metrics"]  # bands are in radians
        assert r.extra["metrics"]["controller_time_s"]["calls"] == 401
        back = Result.read(r.write(tmp_path / r.extra["kind"]))
        np.testing.assert_allclose(back.tables["closed_loop"]["phi"], r.tables["closed_loop"]["phi"])
        assert back.status == r.status
    # 20 s is too short to regulate to 1% of the initial state
    assert res[0].status == "unstable" and "not regulated" in res[0].message


def test_run_controllers_reports_unstabilisable_design():
    d = _load("seed3_attitude.yaml")["controller"]
    spec = {**d, "sdc": "auto", "A": None, "B": None, "R": [1, 1], "type": "lqr"}
    m = build_model("spacecraft_wheels", {"wheels": "2"})
    (r,) = run_controllers(m, [spec])
    assert r.status == "error" and "rank 6 of 9" in r.message


def test_robustness_sweep_one_table():
    d = _load("seed3_robustness.yaml")["controller"]
    d = {**d, "type": ["lqr", "theta-d"]}
    d["simulate"] = {**d["simulate"], "step": 0.1, "update": 0.1}
    m = build_model("spacecraft_wheels", {})
    res = robustness_sweep(m, d, factors=[0.8, 1.2], scaled=["J1", "J2", "J3"])
    tab = res.tables["robustness"]
    assert list(tab["factor"]) == [0.8, 1.2]
    assert {"lqr.cost", "theta-d.cost", "lqr.stable", "theta-d.max_abs_after@60"} <= set(tab)
    # a heavier plant under the nominal design costs more and still settles
    assert tab["lqr.cost"][1] > tab["lqr.cost"][0]
    assert np.all(tab["theta-d.stable"] == 1.0) and np.all(tab["lqr.stable"] == 1.0)
    assert res.status == "stable" and len(res.extra["runs"]) == 4


@pytest.mark.slow
def test_robustness_file_full_sweep():
    d = _load("seed3_robustness.yaml")
    m = build_model("spacecraft_wheels", d["model"]["options"])
    res = robustness_sweep(m, d["controller"], parameters=d["model"]["parameters"])
    tab = res.tables["robustness"]
    assert len(tab["factor"]) == 5 and np.isfinite(tab["sdre.cost"]).all()


SCALAR_LAWS = """name: scalar x' = x^2 + u, three laws
model:
  states: [x]
  controls: [u]
  dynamics: {x: x**2 + u}
controller:
  type: [lqr, sdre]
  Q: [1]
  R: [1]
  simulate:
    x0: {x: 1}
    horizon: 6
    step: 0.01
    integrator: rk4
"""


def test_one_law_that_does_not_regulate_leaves_the_others_verified(tmp_path):
    """unseen9 F9: x = 1 is an equilibrium of the LQR loop designed at the origin (u = -x), so
    LQR does not regulate; the SDRE run was then 'verification skipped: nothing to verify'.
    Every law's simulation is checked; the summary prints each law's status and J."""
    import subprocess
    import sys

    path = tmp_path / "laws.yaml"
    path.write_text(SCALAR_LAWS)
    run = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(path), "--out", str(tmp_path / "r")],
                         capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 1            # a law that does not regulate fails the run
    data = json.loads((tmp_path / "r" / "result.json").read_text())
    assert data["status"] == "unstable" and data["extra"]["lqr"]["status"] == "unstable"
    v = data["verification"]
    assert v["status"] == "verified" and v["checks"], v["summary"]
    assert "lqr             unstable, J = " in run.stdout and "sdre            stable, J = " in run.stdout
    # unseen9 F10: the comparison table names each law and its status (it wrote 0.0, 1.0 and
    # stable 0.0/1.0), and the text reads back as text
    table = Result.read(tmp_path / "r").tables["controllers"]
    assert list(table["law"]) == ["lqr", "sdre"] and list(table["status"]) == ["unstable", "stable"]
    assert table["cost"].dtype.kind == "f"


def test_the_robustness_sweep_outcome_is_printed(tmp_path):
    """The sweep leaves the run's status alone (docs/controllers.md), so the summary says where
    each law regulated: x' = a x + u, LQR designed at a = 1 (gain 1 + sqrt 2) loses the
    plant at a = 10 (closed-loop pole 10 - 2.41 > 0)."""
    import subprocess
    import sys

    path = tmp_path / "rob.yaml"
    path.write_text("""name: scalar robustness
model:
  states: [x]
  controls: [u]
  parameters: {a: 1}
  dynamics: {x: a*x + u}
controller:
  type: lqr
  Q: [1]
  R: [1]
  simulate: {x0: {x: 1}, horizon: 8, step: 0.01, integrator: rk4}
  robustness: {parameters: [a], factors: [0.5, 1, 10]}
""")
    run = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(path), "--out", str(tmp_path / "r")],
                         capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    line = next(ln for ln in run.stdout.splitlines() if ln.strip().startswith("robustness"))
    assert "factors 0.5, 1, 10: lqr regulates at 0.5, 1" in line and "10;" not in line, line


def test_a_loop_still_swinging_is_not_stable_when_tf_hits_a_zero_crossing(tmp_path):
    """unseen12 F2: x' = w, w' = -x + u with nearly free control (Q tiny, R huge): the loop
    keeps the open-loop swing (poles ~ -5e-7 +- 1i). With the horizon ending on a zero crossing
    of x (t = 10.5 pi + 1e-3) ||x(tf)|| was 1e-3 ||x(0)||: 'stable', exit 0."""
    import math
    import subprocess
    import sys

    horizon = 10.5 * math.pi
    path = tmp_path / "osc.yaml"
    path.write_text(f"""name: oscillator, LQR with expensive control
model:
  states: [x, w]
  controls: [u]
  dynamics: {{x: w, w: -x + u}}
controller:
  type: lqr
  Q: [1.0e-12, 1.0e-12]
  R: [1.0e+6]
  simulate: {{x0: {{x: 1, w: 0}}, horizon: {horizon!r}, step: 0.001, integrator: rk4}}
""")
    run = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(path), "--out", str(tmp_path / "r")],
                         capture_output=True, text=True, cwd=tmp_path)
    data = json.loads((tmp_path / "r" / "result.json").read_text())
    x = Result.read(tmp_path / "r").phases[0].states["x"]
    assert abs(x[-1]) < 0.01 and np.max(np.abs(x[-int(0.1 * len(x)):])) > 0.9   # the case: a zero crossing
    assert data["status"] == "unstable" and run.returncode == 1, run.stdout
    assert "last tenth of the horizon" in run.stdout


def test_lqr_with_a_mode_q_cannot_see_is_a_design_error_naming_it():
    """unseen19 c4: Q = diag(0, 1) on a double integrator ((A, Q) not detectable). SciPy returns
    a Riccati solution whose loop keeps an eigenvalue at 0; the run ended `unstable` with "not
    regulated within the horizon". Now the design fails naming the unseen mode; a nearly free
    but detectable design (Q = 1e-12 I, R = 1e6 on an oscillator) still passes."""
    from ocdsl.control.lqr import ControlError, lqr

    A, B = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]])
    with pytest.raises(ControlError, match="not detectable.*eigenvalue 0, 0"):
        lqr(A, B, np.diag([0.0, 1.0]), np.eye(1))
    K, _, eig = lqr(np.array([[0.0, 1.0], [-1.0, 0.0]]), B, 1e-12 * np.eye(2), 1e6 * np.eye(1))
    assert np.all(eig.real < 0)



DIVERGING_LQR = """\
name: scalar plant x' = x**3 + u, SDRE against LQR
model:
  states: [x]
  controls: [u]
  dynamics: {x: x**3 + u}
controller:
  type: [lqr, sdre]
  Q: [1]
  R: [1]
  simulate:
    x0: {x: 1.2}
    horizon: 10
    step: 0.001
    update: 0.01
"""


def test_a_diverging_law_s_integrator_trouble_is_said_in_the_verdict_not_as_a_scipy_warning(tmp_path):
    """unseen29: the LQR law of x' = x^3 + u from x = 1.2 escapes in finite time; the
    verification's stiff fallback (LSODA) printed SciPy's raw "Repeated convergence failures"
    UserWarning on the console before the summary. The verdict says where the integrators
    stopped; no warning leaves the run."""
    import warnings

    from ocdsl.api import run_file

    (tmp_path / "lqr.yaml").write_text(DIVERGING_LQR)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = run_file(tmp_path / "lqr.yaml", None)
    assert res.status == "unstable"
    # where the flow escapes, not the stiff fallbacks' thousands of steps towards it (unseen35)
    assert "by t = 0.58" in res.verification["summary"] and "escapes in finite time" in res.verification["summary"]
    assert not [w for w in caught if "lsoda" in str(w.message).lower()], [str(w.message) for w in caught]


def test_a_diverging_law_leaves_the_other_laws_verified(tmp_path):
    """unseen29: one law (LQR on x' = x^3 + u) blew up and the whole run's verification was
    `error`, so the stable SDRE law went unverified. Each law is flown on its own: the
    diverged one fails with where its integrators stopped, the other is verified, and the
    summary line of each law says which."""
    from click.testing import CliRunner

    from ocdsl.api import run_file
    from ocdsl.cli import main

    (tmp_path / "laws.yaml").write_text(DIVERGING_LQR)
    res = run_file(tmp_path / "laws.yaml", None)
    v = res.verification
    assert v["status"] == "failed"
    lqr = [c for c in v["checks"] if c["phase"] == "lqr"]
    sdre = [c for c in v["checks"] if c["phase"] == "sdre"]
    assert sdre and all(c["passed"] for c in sdre)
    assert any(c["passed"] is False and "escapes in finite time" in c["where"] for c in lqr)
    out = CliRunner().invoke(main, ["run", str(tmp_path / "laws.yaml"), "--out", str(tmp_path / "run")]).output
    assert "stable, J = 1.44" in out and "1.440235692, verified" in out and "not verified" in out, out


def test_the_stiffness_of_a_row_is_measured_at_its_own_size():
    """The stiffness estimate's finite-difference step was 1e-7 x the state's range: a closed
    loop that diverged to 7e26 at its end made x' = x^3 + u look stiff (5e39) at x = 1.2, and
    every one of its 590 pieces went to Radau (15 s of verification). At each row's own size
    the estimate is 3 x^2 there."""
    import numpy as np

    from ocdsl.verify.functions import PhaseFunctions
    from ocdsl.verify.integrate import _stiff

    class Cubic:
        n = 1
        fx = PhaseFunctions.fx

        def f(self, t, X, U):
            return X**3 + U

    class Zero:
        def at(self, tt):
            return np.zeros((len(tt), 1))

    t = np.array([0.0, 0.3, 0.589, 0.59, 0.591])
    X = np.array([[1.2], [1.5], [22.5], [83.0], [7e26]])
    rho = _stiff(Cubic(), Zero(), t, X, np.array([np.ptp(X)]))
    first, last = rho.per_piece([0.0, 0.3, 0.59, 0.591])[[0, 2]]
    assert first == pytest.approx(3 * 1.5**2, rel=1e-5)
    assert last > 1e50


def test_a_plant_that_escapes_in_finite_time_is_unstable_for_every_law(tmp_path):
    """unseen35 P20: x' = x^3 + u with |u| <= 1 from x = 1.2 escapes whatever the law (x^3 >
    1). The SDRE law was handed x = inf after the escape and raised LinAlgError: the whole run
    was `error` (the other laws' results lost, a traceback in result.json); the verification
    of a law alone was `error` (SciPy's "array must not contain infs or NaNs"), after 12 s of
    stiff integration. Each law is now `unstable` (diverged), and the verification fails
    saying where the flow escapes."""
    from ocdsl.api import run_file

    path = tmp_path / "escape.yaml"
    path.write_text("""name: finite escape
model:
  states: [x]
  controls: [u]
  dynamics: {x: x**3 + u}
controller:
  type: [lqr, sdre, theta-d]
  Q: [1]
  R: [1]
  saturation: 1
  simulate: {x0: [1.2], horizon: 5, step: 0.05}
""")
    res = run_file(path, tmp_path / "r")
    assert res.status == "unstable" and "error" not in res.message.lower()
    for law in ("lqr", "sdre", "theta_d"):
        assert res.extra[law]["status"] == "unstable", res.extra[law]
        assert "diverged" in res.message
    v = res.verification
    assert v["status"] == "failed" and "traceback" not in v
    assert "escapes in finite time" in v["summary"]


def test_a_diverged_loops_verification_does_not_advise_a_smaller_step(tmp_path):
    """unseen37 F5: x' = x + (1 - x)u from x = 1 (B(x0) = 0) under LQR escapes at t = 0.66;
    the law was rightly `unstable`, and the verification's advice was "the simulation's
    integrator is not accurate at its step: a smaller `simulate.step`"."""
    from ocdsl.api import run_file

    path = tmp_path / "b09.yaml"
    path.write_text("""name: stabilisable at the origin, not at x0
model:
  states: [x]
  controls: [u]
  dynamics: {x: x + (1 - x)*u}
controller:
  type: lqr
  Q: [1]
  R: [1]
  simulate: {x0: [1], horizon: 10, step: 0.01}
""")
    res = run_file(path, tmp_path / "r")
    assert res.extra["lqr"]["status"] == "unstable" and "diverged at t = 0.66" in res.extra["lqr"]["message"]
    v = res.verification
    assert v["status"] == "failed"
    assert "loop diverged" in v["summary"] and "smaller `simulate.step`" not in v["summary"], v["summary"]


def test_stability_is_judged_per_state_not_over_mixed_units(tmp_path):
    """unseen35 F16: a cart with its position in mm (p' = 1000 v, v' = F, LQR Q = diag(1e-6,
    1), R = 100, |F| <= 2) from v = 1 m/s: the position's transient (1420 mm) passed 1000 x
    ||x(0)|| = 1000 and the regulated loop was "unstable, state diverged at t = 1.41" with a
    truncated J of 11.10 (1/2 x0' P x0 = 22.91); conversely a fast loop in mm beside an
    attitude that barely moves (th' = 1e-4 tau, th = 0.2994 of 0.3 rad at the end) was
    "stable": 0.3 <= 0.01 x ||(1000 mm, 0.3 rad)||. Each state is now judged against its own
    scale."""
    import numpy as np
    import scipy.linalg as sla

    from ocdsl.api import run_file

    cart = tmp_path / "cart.yaml"
    cart.write_text("""name: cart in mm
model:
  states: [p_mm, v]
  controls: [F]
  dynamics: {p_mm: 1000*v, v: F}
controller:
  type: lqr
  Q: [1.0e-6, 1]
  R: [100]
  saturation: 2
  simulate: {x0: {v: 1}, horizon: 90, step: 0.01}
""")
    res = run_file(cart, None)
    A, B = np.array([[0.0, 1000.0], [0.0, 0.0]]), np.array([[0.0], [1.0]])
    P = sla.solve_continuous_are(A, B, np.diag([1e-6, 1.0]), np.array([[100.0]]))
    x0 = np.array([0.0, 1.0])
    assert res.status == "stable", res.message
    # |F| = K x0 = 0.1 < 2 at the start: unsaturated, so J is the Riccati value (rk4, dt 0.01)
    assert res.extra["lqr"]["cost"] == pytest.approx(0.5 * x0 @ P @ x0, rel=1e-3)

    slow = tmp_path / "slow.yaml"
    slow.write_text("""name: fast loop in mm, slow attitude in rad
model:
  states: [p_mm, th]
  controls: [F, tau]
  dynamics: {p_mm: -p_mm + 1000*F, th: 0.0001*tau}
controller:
  type: lqr
  Q: [1.0e-6, 1]
  R: [1, 1]
  simulate: {x0: {p_mm: 1000, th: 0.3}, horizon: 20, step: 0.01}
""")
    res = run_file(slow, None)
    assert res.status == "unstable" and "|th|" in res.message and "not regulated" in res.message, res.message


def test_a_given_sdc_entry_that_is_not_finite_is_named(tmp_path):
    """unseen35 F10: `sdc: given` with A "2,1" = g*sin(th)/th (0/0 at th = 0) ended `error` with
    LAPACK's "SVD did not converge". The law's error names the entry and the point."""
    from ocdsl.api import run_file

    path = tmp_path / "given.yaml"
    path.write_text("""name: pendulum with a given SDC that is 0/0 at the origin
model:
  states: [th, w]
  controls: [u]
  parameters: {g: 9.81}
  dynamics: {th: w, w: g*sin(th) + u}
controller:
  type: sdre
  Q: [1, 1]
  R: [1]
  sdc: given
  A: {"1,2": "1", "2,1": "g*sin(th)/th"}
  B: {"2,1": "1"}
  simulate: {x0: {th: 0.5, w: 0}, horizon: 5, step: 0.01}
""")
    res = run_file(path, None)
    assert res.status == "error"
    assert "A[2,1] is not finite" in res.message and "th=0" in res.message, res.message


def test_a_check_time_past_the_horizon_is_refused():
    """unseen35 F12: a check time past the horizon gave a NaN column in silence: an error of
    the file."""
    base = _load("seed3_attitude.yaml")["controller"]
    sim = {**base["simulate"], "check_times": [2 * float(base["simulate"]["horizon"])]}
    with pytest.raises(ValidationError, match="past the horizon"):
        ControllerSpec.model_validate({**base, "simulate": sim})


@pytest.mark.parametrize("horizon, step", [(1.234, 0.1), (10.5 * np.pi, 0.01), (2.0, 0.15)])
def test_the_simulation_ends_on_its_horizon(horizon, step):
    """unseen35 F12: a horizon that is not a whole number of steps ended at the nearest whole
    step (1.234 with step 0.1 ended at 1.2, in silence); the last step is now shortened onto it.
    x' = -x with a zero control is exp(-t): the cost and the end state say where the run ended."""
    res = simulate(lambda z, u: -z, lambda t, z: np.zeros(1), [1.0], [0], np.eye(1), np.eye(1),
                   horizon, step)
    assert res.t[-1] == pytest.approx(horizon, abs=1e-12)
    assert np.all(np.diff(res.t) > 0)
    assert res.z[-1, 0] == pytest.approx(np.exp(-horizon), rel=1e-4)
    assert res.J == pytest.approx(0.25 * (1 - np.exp(-2 * horizon)), rel=1e-4)


def test_a_stable_but_slow_loop_says_how_many_time_constants_the_horizon_spans(tmp_path):
    """unseen37 F3: the TORA benchmark's LQR loop (eigenvalues -0.084 +- 1.0i) was `unstable`
    at a 60 s horizon (ratio 0.0144 > 0.01; 1e-5 at 150 s) with no word that its
    linearisation is stable. The verdict stays (the run did not regulate within its horizon);
    the message says what the loop's time constant is against the horizon. x' = u with Q =
    1e-4, R = 1: K = 0.01, one time constant of 100 s against a horizon of 20 s."""
    from ocdsl.api import run_file

    path = tmp_path / "slow.yaml"
    path.write_text("""name: slow loop
model: {states: [x], controls: [u], dynamics: {x: u}}
controller:
  type: lqr
  Q: [1.0e-4]
  R: [1]
  simulate: {x0: [1], horizon: 20, step: 0.1}
""")
    res = run_file(path, tmp_path / "r")
    msg = res.extra["lqr"]["message"]
    assert res.extra["lqr"]["status"] == "unstable" and "not regulated within the horizon" in msg
    assert "slowest eigenvalue real part -0.01: a time constant of 100, of which the horizon 20 spans 0.2" in msg, msg


def test_a_loop_still_growing_at_its_horizon_is_not_called_slow(tmp_path):
    """unseen41 F3: a saturated LQR on x' = x + u from x = 2 (|u| <= 1 cannot stop it) was
    told "a longer `simulate.horizon` shows whether it regulates"; |x| grows to 2.2e4 at the
    end of the horizon: it diverges."""
    from ocdsl.api import run_file

    path = tmp_path / "grows.yaml"
    path.write_text("""name: saturated unstable plant
model: {states: [x], controls: [u], dynamics: {x: x + u}}
controller:
  type: lqr
  Q: [1]
  R: [1]
  saturation: 1
  simulate: {x0: {x: 2}, horizon: 10, step: 0.01}
""")
    res = run_file(path, tmp_path / "r")
    msg = res.extra["lqr"]["message"]
    assert res.extra["lqr"]["status"] == "unstable"
    assert "|x| grows from 2 to 2.2e+04, its largest at the end of the horizon: the loop diverges" in msg, msg
    assert "longer `simulate.horizon`" not in msg


def _run_controller(tmp_path, text):
    from ocdsl.api import run_file

    path = tmp_path / "loop.yaml"
    path.write_text(text)
    return run_file(path, tmp_path / "r")


def test_a_loop_resting_at_an_equilibrium_away_from_the_origin_is_not_regulated(tmp_path):
    """unseen46 F1: x' = 3x^2/(1 + 2x^2) + u, LQR u = -x from x = 150: the loop
    x' = -x + 3x^2/(1 + 2x^2) has a stable equilibrium at x = 1, 6.7e-3 of the scale 150,
    within the 1 % rule: "stable", "regulates", exit 0. SDRE regulates it (to 5.6e-12)."""
    res = _run_controller(tmp_path, """name: second equilibrium
model: {states: [x], controls: [u], dynamics: {x: 3*x**2/(1 + 2*x**2) + u}}
controller:
  type: [lqr, sdre]
  Q: [1]
  R: [1]
  simulate: {x0: {x: 150}, horizon: 30, step: 0.01}
""")
    lqr, sdre = res.extra["lqr"], res.extra["sdre"]
    assert lqr["status"] == "unstable", lqr["message"]
    assert "x rests at 1.000" in lqr["message"] and "equilibrium away from the origin" in lqr["message"]
    assert sdre["status"] == "stable", sdre["message"]
    assert not res.ok


def test_a_loop_stuck_at_an_equilibrium_is_not_told_a_longer_horizon_shows_it(tmp_path):
    """unseen46 F5: LQR u = -x on x' = x^2 + u from x = 1 sits at the equilibrium x = 1 for
    the whole run; it was told "a longer `simulate.horizon` shows whether it regulates"."""
    res = _run_controller(tmp_path, """name: stuck
model: {states: [x], controls: [u], dynamics: {x: x**2 + u}}
controller:
  type: lqr
  Q: [1]
  R: [1]
  simulate: {x0: {x: 1}, horizon: 20, step: 0.01}
""")
    msg = res.extra["lqr"]["message"]
    assert res.extra["lqr"]["status"] == "unstable" and "x rests at 1 " in msg, msg
    assert "longer `simulate.horizon`" not in msg


@pytest.mark.parametrize("auxiliary, horizon, said", [("", 20, "|w| (a plant state the law does not regulate) grows"),
                                                      ("auxiliary: [w]", 30, "state diverged at t = 22.5")])
def test_a_plant_state_the_law_does_not_regulate_may_not_diverge(auxiliary, horizon, said, tmp_path):
    """unseen46 F2: x'' = u regulated, w' = w + u left out of `states:` (or auxiliary): the
    closed loop has eigenvalue +1 in w, which went to -8.2e7 (horizon 20) and -1.8e12
    (horizon 30, past the documented 1e9 ||x(0)|| guard), "stable", exit 0, with
    `auxiliary_states: []` recorded for the state left out."""
    res = _run_controller(tmp_path, f"""name: unwatched
model: {{states: [x, v, w], controls: [u], dynamics: {{x: v, v: u, w: w + u}}}}
controller:
  type: lqr
  states: [x, v]
  {auxiliary}
  Q: [1, 1]
  R: [1]
  simulate: {{x0: {{x: 1, v: 0, w: 0.1}}, horizon: {horizon}, step: 0.01}}
""")
    lqr = res.extra["lqr"]
    assert lqr["status"] == "unstable" and said in lqr["message"], lqr["message"]
    assert res.problem["sdc"]["auxiliary_states"] == ["w"]


def test_a_regulated_auxiliary_state_and_a_settled_loop_stay_stable(tmp_path):
    """The same loop with w' = -w + u: w settles, the loop is stable (neither new rule fires
    on a state converging to 0 or on an auxiliary state that stays bounded)."""
    res = _run_controller(tmp_path, """name: watched
model: {states: [x, v, w], controls: [u], dynamics: {x: v, v: u, w: -w + u}}
controller:
  type: [lqr, sdre]
  states: [x, v]
  Q: [1, 1]
  R: [1]
  simulate: {x0: {x: 1, v: 0, w: 0.1}, horizon: 20, step: 0.01}
""")
    assert res.extra["lqr"]["status"] == "stable" and res.extra["sdre"]["status"] == "stable"


def test_sdre_and_theta_d_refuse_a_riccati_solution_that_does_not_stabilise(tmp_path):
    """unseen46 F4: Q = [[1, 1], [1, 1]] gives no weight to x1 - x2 of x' = u: SciPy returns
    a Riccati solution with a closed-loop eigenvalue 0 at every state. LQR refused it; SDRE
    used it with `riccati_failures: 0` and Theta-D ran its series on a non-Hurwitz A0 - B K."""
    res = _run_controller(tmp_path, """name: blind
model: {states: [x1, x2], controls: [u1, u2], dynamics: {x1: u1, x2: u2}}
controller:
  type: [lqr, sdre, theta-d]
  Q: [[1, 1], [1, 1]]
  R: [1, 1]
  simulate: {x0: {x1: 1, x2: 0}, horizon: 10, step: 0.01}
""")
    for law in ("lqr", "sdre", "theta_d"):
        assert res.extra[law]["status"] in ("error", "unstable")
        assert "(A, Q) is not detectable" in res.extra[law]["message"], (law, res.extra[law]["message"])


def test_the_overshoot_of_a_state_that_starts_at_zero_is_past_zero_after_its_excursion():
    """unseen46 F3: a velocity from 0 down to -0.405, back to +0.0017: its overshoot past zero
    is 0.0017 (it was 0.405, the excursion itself), and 0 before it crosses."""
    from ocdsl.control.simulate import overshoot

    t = np.linspace(0.0, 20.0, 2001)
    v = -t * np.exp(-t) + 0.02 * np.exp(-0.5 * t) * np.sin(t) * (t > 3)
    assert overshoot(v)["overshoot"] == pytest.approx(max(v.max(), 0.0))
    assert overshoot(v[:301])["overshoot"] == 0.0
    assert overshoot(-v)["overshoot"] == pytest.approx(overshoot(v)["overshoot"]) and overshoot(v)["overshoot"] > 0
