import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from ocdsl.symbolic.registry import build_model, model_names
from ocdsl.symbolic.vectors import cross, mrp_to_dcm, rot2

NAMES = ["omega1", "omega2", "omega3", "sigma1", "sigma2", "sigma3", "vx", "vy", "vz", "x", "y", "z"]
MU, RE, H = 398600.4418, 6378.137, 580.0


def numeric_rhs(model, **overrides):
    p = model.default_parameters()
    for k, v in overrides.items():
        p[model.symbol(k)] = v
    f = model.rhs(p)
    fun = sp.lambdify([model.states, model.controls], list(f), "numpy", cse=True)
    return lambda x, u: np.array(fun(x, u), dtype=float)


def mu_for_rate(wn):
    """mu (km^3/s^2) that gives orbit rate wn at the default altitude."""
    return wn**2 * (RE + H) ** 3


def test_registered_and_options():
    assert "rendezvous_6dof" in model_names()
    m = build_model("rendezvous_6dof")
    assert [s.name for s in m.states] == NAMES
    assert [c.name for c in m.controls] == ["T1", "T2", "T3", "F1", "F2", "F3"]
    assert m.positions == ("x", "y", "z")
    for s in (*m.states, *m.controls, *m.parameters):
        assert s.name in m.units, s
    assert build_model("rendezvous_6dof", {"euler": "exact"}).description.endswith("exact")
    with pytest.raises(ValueError, match="euler"):
        build_model("rendezvous_6dof", {"euler": "approximate"})
    with pytest.raises(ValueError, match="unknown options"):
        build_model("rendezvous_6dof", {"eulr": "exact"})


def test_orbit_rate_from_altitude():
    m = build_model("rendezvous_6dof")
    wn = m.expand(m.symbol("omega_n")).xreplace(m.default_parameters())
    assert float(wn) == pytest.approx(np.sqrt(MU / (RE + H) ** 3), rel=1e-14)
    assert float(wn) == pytest.approx(1.08775e-3, rel=1e-5)
    # L rotates about -y_L: the orbit rate in B at sigma = 0 is [0, -wn, 0]
    wo2 = m.expand(m.symbol("omega_o2")).xreplace(m.default_parameters())
    assert float(wo2.xreplace({s: 0 for s in m.states})) == pytest.approx(-float(wn))


def test_exact_minus_printed_is_the_dropped_terms():
    mp, me = build_model("rendezvous_6dof"), build_model("rendezvous_6dof", {"euler": "exact"})
    I = sp.diag(*[mp.symbol(n) for n in ("I1", "I2", "I3")])
    w = sp.Matrix(mp.states[:3])
    wo = sp.Matrix([mp.expand(mp.symbol(f"omega_o{i}")) for i in (1, 2, 3)])
    diff = I * (me.rhs()[:3, 0] - mp.rhs()[:3, 0])
    expected = I * cross(w, wo) - cross(w, I * wo)
    rng = np.random.default_rng(3)
    for _ in range(3):
        subs = {s: rng.normal() * 0.3 for s in (*mp.states, *mp.controls)}
        subs.update({mp.symbol(n): v for n, v in zip(("I1", "I2", "I3", "m", "h", "mu", "R_E"),
                                                        (5621, 4547, 2364, 3200, 580, MU, RE))})
        assert np.allclose(np.array((diff - expected).xreplace(subs).evalf(), dtype=float), 0, atol=1e-10)
        # and the difference does not vanish for this asymmetric body
        assert np.abs(np.array(diff.xreplace(subs).evalf(), dtype=float)).max() > 1e-4
    # for a spherical inertia the two forms coincide
    sph = {mp.symbol("I2"): mp.symbol("I1"), mp.symbol("I3"): mp.symbol("I1")}
    assert sp.simplify((me.rhs()[:3, 0] - mp.rhs()[:3, 0]).xreplace(sph)) == sp.zeros(3, 1)


def inertial_momentum(x, t, wn, Ib):
    """Inertial angular momentum in I components: C_LI(t)^T C_BL^T I (w + C_BL [0,-wn,0])."""
    C = np.array(mrp_to_dcm(x[3:6]).evalf(), dtype=float)
    wbi = x[:3] + C @ np.array([0.0, -wn, 0.0])
    C_LI = np.array(rot2(-wn * t).evalf(), dtype=float)   # L is I rotated by -wn t about axis 2
    return C_LI.T @ C.T @ (Ib @ wbi)


@pytest.mark.parametrize("euler,conserved", [("exact", True), ("printed", False)])
def test_torque_free_inertial_angular_momentum(euler, conserved):
    wn = 0.05   # exaggerated orbit rate so that the printed form's error is visible
    m = build_model("rendezvous_6dof", {"euler": euler})
    f = numeric_rhs(m, mu=mu_for_rate(wn))
    Ib = np.diag([5621.0, 4547.0, 2364.0])
    x0 = np.zeros(12)
    x0[:3] = [0.05, -0.2, 0.1]
    x0[3:6] = [0.1, 0.05, -0.1]
    sol = solve_ivp(lambda t, x: f(x, np.zeros(6)), (0, 10), x0, method="DOP853",
                    rtol=1e-11, atol=1e-13, dense_output=True)
    assert sol.success
    h0 = inertial_momentum(x0, 0.0, wn, Ib)
    dev = max(np.linalg.norm(inertial_momentum(sol.sol(t), t, wn, Ib) - h0) for t in np.linspace(0, 10, 21))
    assert np.linalg.norm(sol.y[3:6, -1]) < 1   # MRP stayed on the short branch
    if conserved:
        assert dev < 1e-7 * np.linalg.norm(h0)
    else:
        assert dev > 1e-3 * np.linalg.norm(h0)


def test_cw_translation_matches_closed_form():
    m = build_model("rendezvous_6dof")
    f = numeric_rhs(m)
    wn = np.sqrt(MU / (RE + H) ** 3)
    x0 = np.zeros(12)
    x0[6:] = [0.02, -0.01, 0.015, 20.0, 3.0, -5.0]
    tend = 3000.0
    sol = solve_ivp(lambda t, x: f(x, np.zeros(6)), (0, tend), x0, method="DOP853",
                    rtol=1e-12, atol=1e-12, dense_output=True)
    assert sol.success
    vx0, vy0, vz0, X0, Y0, Z0 = x0[6:]
    for t in np.linspace(0, tend, 9):
        s, c = np.sin(wn * t), np.cos(wn * t)
        X = (4 * vx0 / wn - 6 * Z0) * s - 2 * vz0 / wn * c + (6 * wn * Z0 - 3 * vx0) * t + X0 + 2 * vz0 / wn
        Y = Y0 * c + vy0 / wn * s
        Z = (2 * vx0 / wn - 3 * Z0) * c + vz0 / wn * s + 4 * Z0 - 2 * vx0 / wn
        assert np.allclose(sol.sol(t)[9:], [X, Y, Z], atol=1e-6, rtol=0)
    # no torque, no rate: the attitude stays put
    assert np.abs(sol.y[:6]).max() < 1e-12


def test_body_thrust_is_rotated_into_lvlh():
    m = build_model("rendezvous_6dof")
    f = numeric_rhs(m)
    x = np.zeros(12)
    x[4] = np.tan(np.pi / 8)          # 90 deg about body axis 2
    u = np.array([0, 0, 0, 320.0, 0, 0])
    xdot = f(x, u)
    # body x then points to -z_L (away from the Earth): F_L = [0, 0, -320]
    assert np.allclose(xdot[6:9], [0, 0, -320.0 / 3200.0], atol=1e-12)
    assert np.allclose(xdot[:6], 0, atol=1e-15)
    # torques: T / I on each axis at rest in the L frame with sigma = 0
    x[4] = 0
    xdot = f(x, np.array([50.0, 50.0, 50.0, 0, 0, 0]))
    assert np.allclose(xdot[:3], [50 / 5621, 50 / 4547, 50 / 2364], rtol=1e-12)
