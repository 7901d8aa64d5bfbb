"""Seed 1 data and frame checks (digest seed_001 section 6A)."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ocdsl.simulate import Event, compile_model, simulate
from ocdsl.symbolic.frames import (cartesian_direction_to_polar, ecrf_to_synodic, initial_angle,
                                   jacobi_constant, polar_direction_to_cartesian, revolutions,
                                   synodic_to_ecrf, target_angle, unwrap_angle, wrap_2pi)
from ocdsl.symbolic.registry import build_model

MU = 0.0121506683
X_I = (-0.019488511458668, -0.016033479812051, 0.0, 8.918881923678198, -4.081793688818725, 0.0)
X_F = (0.823385182067467, 0.0, -0.022277556273235, 0.0, 0.134184170262437, 0.0)


def test_ecrf_initial_state():
    r, th, z, rd, thd, zd = synodic_to_ecrf(*X_I, MU)
    assert r == pytest.approx(0.017632822153718, rel=1e-9)   # digest 2.7 (6A prints 0.0176328222)
    assert r * 384405 == pytest.approx(6778.145, abs=1e-3)
    assert th == pytest.approx(-2.0, rel=1e-9)          # atan2, not arctan
    assert abs(math.atan(X_I[1] / (X_I[0] + MU)) - th) > 1.0  # plain arctan: wrong quadrant
    assert abs(rd) < 1e-9
    assert thd == pytest.approx(556.2661398666, rel=1e-9)
    assert initial_angle(th, "0_2pi") == pytest.approx(2 * math.pi - 2, abs=1e-12)
    assert initial_angle(th, "atan2") == pytest.approx(-2.0, abs=1e-12)


def test_ecrf_final_state():
    r, th, z, rd, thd, zd = synodic_to_ecrf(*X_F, MU)
    assert abs(r - 0.835535850367467) < 1e-12
    assert abs(thd - 0.160596544365419) < 1e-12
    assert abs(z - (-0.022277556273235)) < 1e-12
    assert abs(rd) < 1e-12 and abs(zd) < 1e-12 and abs(th) < 1e-12


def test_round_trip_and_revolutions():
    state = np.array([0.3, 2.5, 0.01, 0.2, 1.3, -0.05])
    back = synodic_to_ecrf(*ecrf_to_synodic(*state, MU), MU)
    assert np.allclose(back, state, atol=1e-14)
    theta = np.linspace(4.283185307179586, 10 * math.pi, 400)
    assert np.allclose(unwrap_angle(wrap_2pi(theta)) - unwrap_angle(wrap_2pi(theta))[0] + theta[0], theta)
    assert revolutions(target_angle(0.0, 5)) == 5
    assert revolutions(2 * math.pi * 3 + 1.0, 1.0) == 3
    d, p = 0.4, 1.2
    a = polar_direction_to_cartesian(d, p, 0.7)
    assert np.allclose(cartesian_direction_to_polar(*a, 0.7), (d, p))


@pytest.mark.parametrize("thrust,tmax", [(10, 2.4476474), (5, 1.2238237), (2, 0.4895295)])
def test_thrust_and_exhaust_velocity(thrust, tmax):
    m = build_model("cr3bp_polar", {})
    p = {**m.default_parameters(), m.symbol("thrust"): thrust}
    T = float(m.expand(m.symbol("T_max")).xreplace(p))
    c = float(m.expand(m.symbol("c")).xreplace(p))
    assert abs(T - tmax) < 1e-6
    assert abs(c - 28.751961) < 1e-6


@pytest.fixture(scope="module")
def cart():
    return compile_model(build_model("cr3bp_cartesian", {}))


def test_halo_is_periodic(cart):
    p = cart.params({"thrust": 0.0})
    y0 = np.array(X_F + (1.0,))
    tr = simulate(cart, y0, 2.76, p, rtol=1e-13, atol=1e-14, n_dense=8,
                  events=[Event("y", 0.0, +1, False)])
    assert len(tr.events) == 1
    _, T, yT = tr.events[0]
    assert abs(T - 2.746337) < 1e-6
    assert np.max(np.abs(yT[:6] - y0[:6])) < 1e-8
    z = tr["z"]
    assert z.min() == pytest.approx(-0.0222776, abs=1e-7)
    assert z.max() == pytest.approx(0.0192163, abs=1e-7)
    assert abs(jacobi_constant(*X_F, MU) - 3.170130) < 1e-6
    C = jacobi_constant(*(tr.y[:, i] for i in range(6)), MU)
    assert np.ptp(C) < 1e-10   # conserved along the ballistic arc


def test_polar_and_cartesian_dynamics_agree(cart):
    """Same inertially fixed thrust direction, same state: agreement to 1e-9 over 1 TU."""
    pol = compile_model(build_model("cr3bp_polar", {}))
    p_c = cart.params({"thrust": 10.0})
    p_p = pol.params({"thrust": 10.0})
    beta, tilt = 0.4, 0.3

    def alpha(t):
        a = np.array([math.cos(beta - t), math.sin(beta - t), tilt])  # inertial direction seen in the rotating frame
        return a / np.linalg.norm(a)

    def f_cart(t, y):
        return cart.f(t, y, alpha(t), p_c)

    def f_pol(t, y):
        d, ph = cartesian_direction_to_polar(*alpha(t), y[1])
        return pol.f(t, y, np.array([d, ph]), p_p)

    polar0 = np.array([0.3, 2.5, 0.01, 0.2, 1.3, -0.05, 1.0])
    cart0 = np.array(list(ecrf_to_synodic(*polar0[:6], MU)) + [1.0])
    kw = dict(method="DOP853", rtol=1e-13, atol=1e-15, dense_output=True)
    sc = solve_ivp(f_cart, (0, 1), cart0, **kw)
    sp_ = solve_ivp(f_pol, (0, 1), polar0, **kw)
    for t in (0.25, 0.5, 1.0):
        yc = sc.sol(t)
        yp = sp_.sol(t)
        back = np.array(ecrf_to_synodic(*yp[:6], MU))
        assert np.max(np.abs(back - yc[:6])) < 1e-9
        assert abs(yp[6] - yc[6]) < 1e-12
    assert sc.y[6, -1] == pytest.approx(1 - 2.4476474 / 28.751961, abs=1e-6)


def test_reference_36_counts_revolutions_from_the_atan2_angle():
    """Which revolution count the paper uses (digest section 7 item 12), from its reference
    [36]: the paper's Table 5 gives [36]'s 10 N transfer N_rev = 5, the same as its own.
    [36]'s published minimum-fuel initial costates (digest section 8 item 5; t_f = 1.1 x
    1.8065 TU, bang-bang) propagated in the registered Cartesian model reach the halo point
    after sweeping theta from -2 rad (atan2) to 10 pi: 5.32 revolutions. theta(tf) =
    2 pi N_rev + theta_f with theta_f = 0 then gives N_rev = 5 only when theta is counted
    from the atan2 value -2; from its [0, 2 pi) residue 4.28 the same transfer is N_rev = 6."""
    import sympy as sp

    model = build_model("cr3bp_cartesian", {"mass_flow": "norm"})   # no mass flow on coasts
    f = model.rhs(model.default_parameters())
    x = list(model.states)
    u = list(model.controls)
    lam = sp.symbols("l0:7", real=True)
    H = sum(l * fi for l, fi in zip(lam, f))
    costate = [-sp.diff(H, s) for s in x]       # u enters as the given thrust vector
    args = x + u + list(lam)
    state_rhs = sp.lambdify(args, list(f), "numpy")
    costate_rhs = sp.lambdify(args, costate, "numpy")
    c = float(model.expand(model.symbol("c")).xreplace(model.default_parameters()))
    lam0 = [15.616017, 32.875896, -0.094522, -0.101606, 0.044791, -0.000150, 0.133266]

    def switching(t, s):                        # S = 1 - c |lambda_v| / m - lambda_m; thrust when S < 0
        return 1 - c * np.linalg.norm(s[10:13]) / s[6] - s[13]

    def rhs(t, s, throttle):
        lv = s[10:13]
        thrust = -throttle * lv / np.linalg.norm(lv)
        a = list(s[:7]) + list(thrust) + list(s[7:])
        return np.concatenate([state_rhs(*a), costate_rhs(*a)])

    state = np.array(list(X_I) + [1.0] + lam0)
    t, tf, arcs, thetas = 0.0, 1.1 * 1.8065, 0, []
    throttle = 1.0 if switching(0.0, state) < 0 else 0.0
    while t < tf:
        event = lambda t, s, _: switching(t, s)                               # noqa: E731
        event.terminal, event.direction = True, (1 if throttle else -1)
        sol = solve_ivp(rhs, (t, tf), state, args=(throttle,), method="DOP853", rtol=1e-10,
                        atol=1e-12, events=event, max_step=5e-3)
        thetas.append(np.arctan2(sol.y[1], sol.y[0] + MU))
        t, state, arcs = sol.t[-1], sol.y[:, -1], arcs + 1
        throttle = 1.0 - throttle               # an arc ends at a switch (or at tf)
    assert 10 <= arcs <= 16                     # a bang-bang transfer, thrusting mostly at perigee
    miss_r = np.linalg.norm(state[0:3] - np.array(X_F[0:3]))
    miss_v = np.linalg.norm(state[3:6] - np.array(X_F[3:6]))
    assert miss_r < 0.015 and miss_v < 0.03     # six-digit costates: near the halo point
    theta = unwrap_angle(np.concatenate(thetas))
    assert theta[0] == pytest.approx(-2.0, abs=1e-9)
    assert theta[-1] == pytest.approx(target_angle(0.0, 5), abs=0.05)          # 10 pi
    assert revolutions(theta[-1], 0.0) == 5
    assert revolutions(theta[-1] - theta[0] + initial_angle(theta[0], "0_2pi"), 0.0) == 6
    assert (theta[-1] - theta[0]) / (2 * math.pi) == pytest.approx(5.32, abs=0.01)
