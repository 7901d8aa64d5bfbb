"""Path-constraint multipliers: their estimate from the NLP duals and the certificate's H_aug.

Analytic case (tests/data/path_multiplier_lq.yaml): x' = u, x(0) = -1, T = 3, minimise
int (x^2 + u^2)/2 with ``u - 0.5 <= 0`` as a general path constraint. On the arc [0, t1]
u = 1/2 and H_aug = L + lambda u + mu (u - 1/2) is stationary: mu = -(u + lambda) =
lambda0 - 1/2 - t + t^2/4, lambda0 = 1/2 + t1 - t1^2/4; mu = 0 after t1.
"""
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import ocdsl
from ocdsl.result import Result
from ocdsl.solve.certificate import certificate
from ocdsl.symbolic.model import Model, syms

DATA = Path(__file__).parent / "data"
T = 3.0
T1 = brentq(lambda s: np.tanh(T - s) - 1.0 / (2.0 - s), 0, 1.9)
LAM0 = 0.5 + T1 - T1**2 / 4

x, u = syms("x u")
LQ = Model("lq", (x,), (u,), {x: u})
L_LQ = (x**2 + u**2) / 2
PATH = [(u - 0.5, None, 0.0)]


def exact(t):
    """States, control, costate and multiplier of the analytic case."""
    first = t < T1
    A = 0.5 / np.sinh(T - T1)
    X = np.where(first, -1 + 0.5 * t, -A * np.cosh(T - t))
    lam = np.where(first, -(LAM0 - t + t**2 / 4), -A * np.sinh(T - t))
    U = np.where(first, 0.5, -lam)
    mu = np.where(first, LAM0 - 0.5 - t + t**2 / 4, 0.0)
    return X, U, lam, mu


def lg_nodes(segments, degree):
    tau, _ = np.polynomial.legendre.leggauss(degree)
    edges = np.linspace(0, T, segments + 1)
    return np.concatenate([(a + b) / 2 + (b - a) / 2 * tau for a, b in zip(edges[:-1], edges[1:])]), edges


def analytic_traj():
    t, edges = lg_nodes(30, 3)
    X, U, lam, mu = exact(t)
    return {"time": t, "states": {"x": X}, "controls": {"u": U}, "costates": {"x": lam}}, mu, edges


# ---- the certificate on analytic arrays ------------------------------------------------
def test_exact_multiplier_certifies_and_plain_hamiltonian_does_not():
    traj, mu, edges = analytic_traj()
    assert mu.max() > 0.5                     # the arc is long enough to matter
    cert = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf",
                       path_constraints=PATH, multipliers={"mu_0": mu})
    assert cert["passed"], cert["failed"]
    assert cert["stationarity"]["max_relative"] < 1e-12
    pm = cert["path_multipliers"]
    assert pm["complementarity"] < 1e-12 and pm["max_wrong_sign_relative"] == 0.0
    (c,) = pm["per_constraint"]
    assert c["kind"] == "upper" and c["active_nodes"] == int(np.sum(traj["time"] < T1))
    # without the path term (backward-compatible call) the arc violates dH/du = 0
    plain = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf")
    assert "path_multipliers" not in plain
    assert plain["failed"] == ["stationarity"]
    assert plain["stationarity"]["max_relative"] > 0.3


def test_wrong_multipliers_fail():
    traj, mu, edges = analytic_traj()
    kw = dict(path_constraints=PATH)
    # a sign-flipped multiplier: wrong sign at an upper bound and not stationary
    bad = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf", multipliers={"mu_0": -mu}, **kw)
    assert set(bad["failed"]) == {"stationarity", "path_multipliers"}
    assert bad["path_multipliers"]["per_constraint"][0]["wrong_sign_nodes"] > 20
    # a multiplier on the free arc (g < 0 there): complementarity fails
    off = mu + np.where(traj["time"] > T1 + 0.5, 0.1, 0.0)
    bad = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf", multipliers={"mu_0": off}, **kw)
    assert "path_multipliers" in bad["failed"]
    assert bad["path_multipliers"]["complementarity_relative"] > 1e-3
    # a multiplier scaled by a wrong factor (e.g. a missing h/2): stationarity fails
    bad = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf", multipliers={"mu_0": 2 * mu}, **kw)
    assert bad["failed"] == ["stationarity"]
    with pytest.raises(ValueError, match="mu_0"):
        certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf", **kw)


def test_lower_bound_needs_a_nonpositive_multiplier():
    """The same constraint written as ``0.5 - u >= 0`` (a lower bound): H_aug's term is
    -mu (u - 1/2), so the multiplier is -mu <= 0; +mu has the wrong sign."""
    traj, mu, edges = analytic_traj()
    kw = dict(path_constraints=[(0.5 - u, 0.0, None)])
    lower = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf", multipliers={"mu_0": -mu}, **kw)
    assert lower["passed"], lower["failed"]
    assert lower["path_multipliers"]["per_constraint"][0]["kind"] == "lower"
    wrong = certificate(LQ, {}, traj, {}, L_LQ, "fixed_tf", multipliers={"mu_0": mu}, **kw)
    assert set(wrong["failed"]) == {"stationarity", "path_multipliers"}
    assert wrong["path_multipliers"]["per_constraint"][0]["wrong_sign_nodes"] > 20


# ---- the estimate from the NLP duals -----------------------------------------------------
@pytest.mark.ipopt
@pytest.mark.parametrize("scheme", ["LGR", "LG", "LGL"])
def test_multiplier_estimate_matches_the_analytic_one(tmp_path, scheme):
    text = (DATA / "path_multiplier_lq.yaml").read_text().replace("transcription: LGR", f"transcription: {scheme}")
    p = tmp_path / "lq.yaml"
    p.write_text(text)
    res = ocdsl.load(p).solve()
    assert res.status == "optimal"
    ph = res.phase()
    col = ph.extra["collocated"] > 0
    mu = ph.extra["mu_0"]
    assert np.isnan(mu[~col]).all() and np.isfinite(mu[col]).all()
    assert res.extra["path_multipliers"] == {"main": {"mu_0": "u - 0.5 <= 0"}}
    _, _, _, mu_exact = exact(ph.time)
    err = np.abs(mu[col] - mu_exact[col])
    # measured 1e-4 (LGR), 3e-5 (LG), 4e-4 (LGL) on a multiplier of size 0.7
    assert err.max() < 2e-3 and mu[col].max() > 0.6
    assert np.abs(mu[col & (ph.time > T1 + 0.2)]).max() < 1e-6
    cert = res.certificate
    assert cert["passed"], cert["failed"]
    assert cert["stationarity"]["max_relative"] < 1e-6
    assert cert["path_multipliers"]["passed"]
    # the multipliers survive the run folder
    back = Result.read(res.write(tmp_path / "run"))
    assert np.allclose(back.phase().extra["mu_0"], mu, equal_nan=True)


@pytest.mark.ipopt
def test_unit_direction_path_constraint():
    """Minimum time with a unit heading (ux^2 + uy^2 == 1): H_aug_u = lambda + 2 mu u = 0,
    so u = -lambda/|lambda| and mu = |lambda|/2; H = -1."""
    res = ocdsl.load(DATA / "unit_direction.yaml").solve()
    assert res.status == "optimal"
    ph = res.phase()
    col = ph.extra["collocated"] > 0
    lx, ly = ph.costates["x"][col], ph.costates["y"][col]
    lam = np.hypot(lx, ly)
    mu = ph.extra["mu_0"][col]
    assert np.allclose(mu, lam / 2, rtol=1e-6, atol=0)
    assert np.allclose(ph.controls["ux"][col], -lx / lam, atol=1e-6)
    cert = res.certificate
    assert cert["passed"], cert["failed"]
    assert cert["stationarity"]["interior_nodes"] == 2 * int(col.sum())
    assert cert["stationarity"]["max_relative"] < 1e-6
    assert cert["hamiltonian"]["expected"] == -1.0
    pm = cert["path_multipliers"]["per_constraint"][0]
    assert pm["kind"] == "equality" and pm["text"] == "ux**2 + uy**2 == 1"
    # an equality's multiplier has free sign: -(ux^2 + uy^2) == -1 takes -mu and passes,
    # while as an upper bound (-(ux^2 + uy^2) <= -1) the same -mu has the wrong sign
    phase = ocdsl.load(DATA / "unit_direction.yaml").problem.phases[0]
    ux, uy = phase.controls
    arrays = {"time": ph.time[col], "states": {k: v[col] for k, v in ph.states.items()},
              "controls": {k: v[col] for k, v in ph.controls.items()},
              "costates": {k: v[col] for k, v in ph.costates.items()}}
    g = -(ux**2 + uy**2)
    args = (phase.model, res.parameters, arrays, {}, 0, "min_tf")
    eq = certificate(*args, path_constraints=[(g, -1, -1)], multipliers={"mu_0": -mu})
    assert eq["passed"], eq["failed"]
    up = certificate(*args, path_constraints=[(g, None, -1)], multipliers={"mu_0": -mu})
    assert up["failed"] == ["path_multipliers"]
    assert up["path_multipliers"]["per_constraint"][0]["wrong_sign_nodes"] == int(col.sum())
    # the plain Hamiltonian (no path term) is not stationary: the failure this fixes
    plain = certificate(*args)
    assert "stationarity" in plain["failed"] and "path_multipliers" not in plain


def test_a_multiplier_on_a_sliver_of_a_segment_is_weighed_by_its_share():
    """unseen56 F1: the Chebyshev approximation of t^2 by a line as a minimax problem (min p,
    |x - t^2| <= p, x(t0) free; p* = 1/8) touches its bound at t0, which LGR holds no node of:
    the refinement bisected the first segment down to 3e-7, where the path multiplier (a
    density) reached 1e6 and mu (g - b) 0.1 at Ipopt's slack: `certificate failed
    (path_multipliers)`, exit 1, for p right to 1e-7. A node counts by its share of the phase."""
    from pathlib import Path

    from ocdsl.api import run_file

    res = run_file(Path(__file__).parent / "data" / "chebyshev_minimax_mesh.yaml", None)
    assert res.status == "optimal" and res.verified
    assert res.objective == pytest.approx(0.125, rel=1e-6)
    cert = res.certificate
    assert cert["path_multipliers"]["passed"] is True and not cert.get("failed"), cert.get("failed")


def test_a_phase_without_controls_has_no_control_jump(tmp_path):
    """unseen56 F3: the jump locator took numpy's argmax of no controls, and every mesh line said
    "the locator stopped: attempt to get argmax of an empty sequence"."""
    from pathlib import Path

    from click.testing import CliRunner

    from ocdsl.cli import main

    out = CliRunner().invoke(main, ["run", str(Path(__file__).parent / "data" / "chebyshev_minimax_mesh.yaml"),
                                    "--out", str(tmp_path / "run")]).output
    assert "mesh  2:" in out and "the locator stopped" not in out, out
