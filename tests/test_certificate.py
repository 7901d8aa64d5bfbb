"""The optimality certificate on analytic problems with known states and costates."""
import json

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq

from ocdsl.result import PhaseTrajectory
from ocdsl.solve.certificate import Tolerances, certificate, hamiltonian_arrays, symbolic_conditions
from ocdsl.symbolic.model import TIME, Model, sym, syms


def lg_nodes(t0, tf, segments, degree):
    tau, _ = np.polynomial.legendre.leggauss(degree)
    edges = np.linspace(t0, tf, segments + 1)
    t = np.concatenate([(a + b) / 2 + (b - a) / 2 * tau for a, b in zip(edges[:-1], edges[1:])])
    return t, edges


# ---- minimum-time double integrator: x(0) = -1, v(0) = 0 -> (0, 0), tf = 2 -------------
x, v, u = syms("x v u")
DI = Model("di", (x, v), (u,), {x: v, v: u})
DI_BOUNDS = {"u": (-1, 1)}


def di_solution(t, lam_shift=0.0, lam_scale=1.0):
    first = t < 1
    X = np.where(first, -1 + t**2 / 2, -(2 - t) ** 2 / 2)
    V = np.where(first, t, 2 - t)
    U = np.where(first, 1.0, -1.0)
    # H = lx v + lv u, lx = -1, lv = t - 1: switching function lv, H = -1
    lx = -np.ones_like(t) * lam_scale
    lv = (t - 1 - lam_shift) * lam_scale
    return PhaseTrajectory("main", t, {"x": X, "v": V}, {"u": U}, {"x": lx, "v": lv})


@pytest.fixture(scope="module")
def di_nodes():
    return lg_nodes(0, 2, 20, 3)


def test_symbolic_hamiltonian():
    sc = symbolic_conditions(DI)
    lx, lv = sc.costates[x], sc.costates[v]
    assert sp.expand(sc.hamiltonian - (lx * v + lv * u)) == 0
    assert sc.dH_du[u] == lv
    assert sc.costate_rhs[v] == -lx and sc.costate_rhs[x] == 0
    assert not sc.time_dependent
    assert "lambda" in sc.latex()["hamiltonian"]


def test_min_time_double_integrator_passes(di_nodes):
    t, edges = di_nodes
    cert = certificate(DI, {}, di_solution(t), DI_BOUNDS, 0, "min_tf")
    json.dumps(cert)
    assert cert["passed"], cert["failed"]
    h = cert["hamiltonian"]
    assert h["expected"] == -1.0
    assert abs(h["mean"] + 1) < 1e-12 and h["max_deviation"] < 1e-12
    assert cert["switching"]["agreement"] == 1.0 and cert["switching"]["saturated_nodes"] == 60
    bb = cert["bang_bang"]["per_control"]["u"]
    assert bb["bang_bang"] and bb["fraction_at_bound"] == 1.0
    assert bb["switch_count"] == 1 and bb["sequence"] == ["+", "-"]
    assert bb["switch_times"][0] == pytest.approx(1.0, abs=1e-12)
    assert cert["stationarity"]["interior_nodes"] == 0


def radau_end_nodes(t0, tf, segments, degree):
    """Flipped LGR (ocdsl's LGR): each segment collocates at its end, not at its start."""
    tau = np.sort(-np.polynomial.legendre.Legendre.basis(degree - 1).__add__(
        np.polynomial.legendre.Legendre.basis(degree)).roots().real)
    edges = np.linspace(t0, tf, segments + 1)
    t = np.concatenate([(a + b) / 2 + (b - a) / 2 * tau for a, b in zip(edges[:-1], edges[1:])])
    return t, edges


def test_segment_of_nodes_boundary_node_ends_its_segment():
    from ocdsl.verify.interpolate import segment_of_nodes

    edges = np.array([0.0, 1.0, 2.0])
    assert segment_of_nodes([0.0, 0.5, 1.0, 1.2, 2.0], edges).tolist() == [0, 0, 0, 1, 1]
    # a boundary node an ulp off its boundary (floating-point node placement) still ends it
    assert segment_of_nodes([1.0 + 2e-16, 1.0 - 2e-16, 1.0 + 1e-6], edges).tolist() == [0, 0, 1]


def test_sign_flipped_costates_fail(di_nodes):
    t, edges = di_nodes
    cert = certificate(DI, {}, di_solution(t, lam_scale=-1), DI_BOUNDS, 0, "min_tf")
    assert not cert["passed"]
    assert cert["hamiltonian"]["mean"] == pytest.approx(1.0)
    # every node disagrees but the switch's own (dH/du = 0 there: no sign to judge)
    sw = cert["switching"]
    assert sw["saturated_nodes"] - sw["agreeing_nodes"] >= sw["saturated_nodes"] - 2
    assert set(cert["failed"]) == {"hamiltonian", "switching"}


def test_shifted_switching_function_fails(di_nodes):
    t, edges = di_nodes
    cert = certificate(DI, {}, di_solution(t, lam_shift=0.3), DI_BOUNDS, 0, "min_tf")
    assert "hamiltonian" in cert["failed"] and "switching" in cert["failed"]
    assert cert["hamiltonian"]["max_deviation"] == pytest.approx(0.3, abs=1e-9)
    # nodes in (1, 1.3) are at -1 with lv < 0: disagree, unless lv is within the
    # stationarity tolerance of 0 (weakly active)
    lv = t - 1.3
    n_bad = int(np.sum((t > 1) & (t < 1.3) & (np.abs(lv) > 0.01 * np.abs(lv).max())))
    assert n_bad >= 8
    assert cert["switching"]["saturated_nodes"] - cert["switching"]["agreeing_nodes"] == n_bad


def test_scaled_costates_fail_only_the_value(di_nodes):
    t, edges = di_nodes
    cert = certificate(DI, {}, di_solution(t, lam_scale=2), DI_BOUNDS, 0, "min_tf")
    assert cert["failed"] == ["hamiltonian"]
    assert cert["hamiltonian"]["mean"] == pytest.approx(-2.0)
    # the same arrays with free tf and another objective expect H = 0
    cert = certificate(DI, {}, di_solution(t), DI_BOUNDS, 0, "free_tf")
    assert cert["failed"] == ["hamiltonian"]


def test_non_collocated_rows_are_ignored(di_nodes):
    t, edges = di_nodes
    ref = certificate(DI, {}, di_solution(t), DI_BOUNDS, 0, "min_tf")
    traj = di_solution(t)
    # add the segment ends as rows with states but no control/costate (as a back end may)
    te = np.concatenate([t, edges])
    order = np.argsort(te, kind="stable")
    full = di_solution(te)
    for group in (full.controls, full.costates):
        for k in group:
            group[k] = np.concatenate([getattr(traj, "controls" if group is full.controls else "costates")[k],
                                       np.full(len(edges), np.nan)])[order]
    full.time = te[order]
    full.states = {k: v[order] for k, v in full.states.items()}
    cert = certificate(DI, {}, full, DI_BOUNDS, 0, "min_tf")
    assert cert["nodes"] == len(t)
    assert cert["passed"] and cert["hamiltonian"]["mean"] == ref["hamiltonian"]["mean"]
    H = hamiltonian_arrays(DI, {}, full)["hamiltonian"]
    assert len(H) == len(te) and np.isnan(H).sum() == len(edges)
    assert np.allclose(H[np.isfinite(H)], -1)


def test_hamiltonian_arrays(di_nodes):
    t, _ = di_nodes
    arr = hamiltonian_arrays(DI, {}, di_solution(t))
    assert np.allclose(arr["hamiltonian"], -1)
    assert np.allclose(arr["dH_du"], t - 1)


# ---- LQ with fixed final time: x' = u, J = int (x^2 + u^2)/2, x(0) = 1, x(T) free -------
a = sym("a")
LQ = Model("lq", (x,), (u,), {x: a * u}, parameters={a: 1.0})
T = 1.5


def lq_solution(t, lam_scale=1.0):
    X = np.cosh(T - t) / np.cosh(T)
    lam = np.sinh(T - t) / np.cosh(T)
    return {"time": t, "states": {"x": X}, "controls": {"u": -lam},
            "costates": {"x": lam * lam_scale}}


def test_lq_fixed_tf_passes():
    t, edges = lg_nodes(0, T, 10, 4)
    L = (x**2 + u**2) / 2
    cert = certificate(LQ, {"a": 1.0}, lq_solution(t), {}, L, "fixed_tf")
    assert cert["passed"], cert["failed"]
    h = cert["hamiltonian"]
    assert h["expected"] is None
    assert h["mean"] == pytest.approx(1 / (2 * np.cosh(T) ** 2), rel=1e-12)
    assert h["max_deviation"] < 1e-12
    assert cert["stationarity"]["interior_nodes"] == len(t)
    assert cert["stationarity"]["max_relative"] < 1e-12
    assert cert["switching"]["agreement"] is None
    assert cert["bang_bang"]["per_control"] == {}


@pytest.mark.parametrize("scale", [1.1, -1.0])
def test_lq_wrong_costates_fail(scale):
    t, edges = lg_nodes(0, T, 10, 4)
    L = (x**2 + u**2) / 2
    cert = certificate(LQ, {"a": 1.0}, lq_solution(t, scale), {}, L, "fixed_tf")
    assert "stationarity" in cert["failed"] and "hamiltonian" in cert["failed"]


# ---- free final time, running cost: x' = u, J = int (1 + u^2/2), x: 0 -> 1 ----------------
def test_free_tf_with_running_cost():
    tf = 1 / np.sqrt(2)
    t, edges = lg_nodes(0, tf, 4, 3)
    L = 1 + u**2 / 2
    traj = {"time": t, "states": {"x": np.sqrt(2) * t}, "controls": {"u": np.full_like(t, np.sqrt(2))},
            "costates": {"x": np.full_like(t, -np.sqrt(2))}}
    cert = certificate(LQ, {"a": 1.0}, traj, {"u": (None, 10)}, L, "free_tf")
    assert cert["passed"], cert["failed"]
    assert abs(cert["hamiltonian"]["mean"]) < 1e-12
    assert certificate(LQ, {"a": 1.0}, traj, {}, L, "min_tf")["failed"] == ["hamiltonian"]
    traj["costates"]["x"] = np.full_like(t, -1.0)
    bad = certificate(LQ, {"a": 1.0}, traj, {}, L, "free_tf")
    assert set(bad["failed"]) == {"hamiltonian", "stationarity"}


# ---- a control with interior and bound arcs: |u| <= 1/2 ---------------------------------
def test_partly_saturated_lq():
    T3 = 3.0
    # u = -1/2 on [0, t1], then u = -lam with x = A cosh(T - t), lam = A sinh(T - t)
    t1 = brentq(lambda s: np.tanh(T3 - s) - 0.5 / (1 - 0.5 * s), 0, 1.9)
    A = 0.5 / np.sinh(T3 - t1)
    lam0 = 0.5 + t1 - t1**2 / 4
    t, edges = lg_nodes(0, T3, 30, 3)
    first = t < t1
    X = np.where(first, 1 - 0.5 * t, A * np.cosh(T3 - t))
    lam = np.where(first, lam0 - t + t**2 / 4, A * np.sinh(T3 - t))
    U = np.where(first, -0.5, -lam)
    traj = {"time": t, "states": {"x": X}, "controls": {"u": U}, "costates": {"x": lam}}
    L = (x**2 + u**2) / 2
    cert = certificate(LQ, {"a": 1.0}, traj, {"u": (-0.5, 0.5)}, L, "fixed_tf")
    assert cert["passed"], cert["failed"]
    sw = cert["switching"]["per_control"]["u"]
    assert sw["saturated_nodes"] >= np.sum(first) and sw["agreement"] == 1.0
    assert cert["stationarity"]["interior_nodes"] > 0
    assert not cert["bang_bang"]["all"]
    # the costate of the unconstrained problem on the bound arc violates the sign condition
    lam_bad = np.where(first, 0.2, lam)
    traj["costates"] = {"x": lam_bad}
    bad = certificate(LQ, {"a": 1.0}, traj, {"u": (-0.5, 0.5)}, L, "fixed_tf")
    assert "switching" in bad["failed"]


# ---- explicit time dependence: L = u^2/2 + t x ---------------------------------------------
def test_time_dependent_hamiltonian():
    T2 = 1.0
    t, edges = lg_nodes(0, T2, 20, 3)
    lam = (T2**2 - t**2) / 2
    X = 1 - (T2**2 * t - t**3 / 3) / 2
    traj = {"time": t, "states": {"x": X}, "controls": {"u": -lam}, "costates": {"x": lam}}
    L = u**2 / 2 + TIME * x
    cert = certificate(LQ, {"a": 1.0}, traj, {}, L, "fixed_tf")
    h = cert["hamiltonian"]
    assert h["time_dependent"]
    # H itself varies by O(1) but H + int_t^T dH/dt is constant
    H = hamiltonian_arrays(LQ, {"a": 1.0}, traj, L)["hamiltonian"]
    assert np.ptp(H) > 0.3
    assert cert["passed"], cert["failed"]
    assert h["relative_max_deviation"] < 1e-3
    traj["costates"] = {"x": 1.2 * lam}
    assert "hamiltonian" in certificate(LQ, {"a": 1.0}, traj, {}, L, "fixed_tf")["failed"]


def test_bad_inputs():
    t, _ = lg_nodes(0, 2, 2, 3)
    with pytest.raises(ValueError, match="objective"):
        certificate(DI, {}, di_solution(t), DI_BOUNDS, 0, "min_time")
    traj = di_solution(t)
    traj.costates = {}
    with pytest.raises(ValueError, match="costates"):
        certificate(DI, {}, traj, DI_BOUNDS)
    with pytest.raises(ValueError, match="no value"):
        certificate(LQ, {}, lq_solution(t), {}, sym("q") * u**2, "fixed_tf")
    tight = Tolerances(hamiltonian_max=0.0, hamiltonian_mean=0.0)
    assert certificate(DI, {}, di_solution(t, lam_scale=1.0 + 1e-6), DI_BOUNDS, 0, "min_tf",
                       tolerances=tight)["failed"] == ["hamiltonian"]
