"""Relative-motion models and closed forms (seed 4, digest ../shared/seeds/seed_004.md §2, §5.2).

The closed forms are checked against numerical integration of the *registered* models,
so a slip in either the model or the formula fails a test.
"""
import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from ocdsl.symbolic import relative_motion as rm
from ocdsl.symbolic.model import sym, syms
from ocdsl.symbolic.registry import build_model, model_names

OMEGA = 7.292116e-5      # GEO rate (digest §3), rad/s
A_THRUST = 1e-4          # m/s^2 -> K = 37.612 km
RNG = np.random.default_rng(4)


def _rhs(model_name, options=None, params=None):
    """Numerical f(x, u) of a registered model (lambdified from its SymPy rhs)."""
    m = build_model(model_name, options)
    vals = m.default_parameters()
    vals.update({m.symbol(k): v for k, v in (params or {}).items()})
    f = sp.lambdify([m.states, m.controls], list(m.rhs(vals)), "math")
    return m, f


def _integrate(f, x0, u, T):
    sol = solve_ivp(lambda t, x: f(x, u), (0.0, T), np.asarray(x0, float), method="DOP853",
                    rtol=1e-13, atol=1e-15)
    assert sol.success
    return sol.y[:, -1]


def _integrate_programme(f, y0, segments):
    """segments: [(delta, duration)] in order, from y0."""
    y = np.asarray(y0, float)
    for delta, dur in segments:
        if dur > 0:
            y = _integrate(f, y, [delta], dur)
    return y


def test_models_registered():
    names = model_names()
    assert "hcw" in names and "relative_motion_secular" in names
    m = build_model("hcw", {"lateral": True})
    assert [s.name for s in m.states] == ["dr", "dL", "dVr", "dVu", "dz", "dVz"]
    with pytest.raises(ValueError, match="unknown options"):
        build_model("relative_motion_secular", {"lateral": True})


# ---- §5.2 check 6: fundamental matrix ------------------------------------------------
def test_fundamental_matrix_against_integration():
    _, f = _rhs("hcw", params={"omega": OMEGA})
    for t in (0.3 / OMEGA, 2.0 / OMEGA, 7.5 / OMEGA):
        Phi = rm.fundamental_matrix(t, OMEGA)
        for j in range(4):
            e = np.zeros(4)
            e[j] = [1.0, 1.0, OMEGA, OMEGA][j]   # unit position / velocity scales
            x = _integrate(f, e, [0.0, 0.0], t)
            ref = Phi @ e
            assert np.max(np.abs(x - ref)) / np.max(np.abs(ref)) < 1e-8


def test_fundamental_matrix_inverse_and_ode_symbolically():
    t, w = sym("tt"), sym("w")
    Phi = rm.fundamental_matrix(t, w)
    A, _ = rm.hcw_matrices(w)
    assert sp.simplify(Phi.diff(t) - A * Phi) == sp.zeros(4, 4)
    assert sp.simplify(Phi.subs(t, 0)) == sp.eye(4)
    for tv in (0.7, 3.1, 11.0):
        P, Pm = rm.fundamental_matrix(tv, 1.3), rm.fundamental_matrix(-tv, 1.3)
        assert np.max(np.abs(P @ Pm - np.eye(4))) < 1e-12
    # the registered model's Jacobians are A and B
    m = build_model("hcw")
    om = m.symbol("omega")
    assert m.rhs().jacobian(m.states).subs(om, w) == A
    assert m.rhs().jacobian(m.controls) == rm.hcw_matrices(w)[1]


def test_lateral_block_and_forced_response():
    _, f = _rhs("hcw", {"lateral": True}, params={"omega": OMEGA})
    t = 2.5 / OMEGA
    x = _integrate(f, [0, 0, 0, 0, 100.0, 0.01], [0, 0, 0], t)
    assert np.allclose(x[4:], rm.fundamental_matrix_lateral(t, OMEGA) @ [100.0, 0.01], rtol=1e-9, atol=1e-9)
    x = _integrate(f, np.zeros(6), [0.0, A_THRUST, 0.0], t)
    ref = rm.forced_response_aT(t, OMEGA, A_THRUST)
    assert np.max(np.abs(x[:4] - ref) / np.maximum(np.abs(ref), 1e-12)) < 1e-8


# ---- §5.2 check 7: secular/periodic map ----------------------------------------------
def test_secular_map_round_trips_exactly():
    x = syms("dr dL dVr dVu")
    w, a = sym("omega"), sym("a")
    back = rm.from_secular(rm.to_secular(x, w), w)
    assert all(sp.simplify(b - xi) == 0 for b, xi in zip(back, x))
    y = syms("r_av L_av l_x l_y")
    fwd = rm.to_secular(rm.from_secular(y, w), w)
    assert all(sp.simplify(b - yi) == 0 for b, yi in zip(fwd, y))
    back = rm.from_dimensionless(rm.to_dimensionless(x, w, a), w, a)
    assert all(sp.simplify(b - xi) == 0 for b, xi in zip(back, x))


def test_secular_odes_hold_for_any_thrust():
    """d/dt of the map along HCW = eqs. (9)/(11), and through K and tau = the registered (15)."""
    hcw = build_model("hcw", {"lateral": True})
    w = hcw.symbol("omega")
    aS, aT = hcw.symbol("aS"), hcw.symbol("aT")
    f = dict(zip(hcw.states, hcw.rhs()))
    x = hcw.states[:4]
    sec = rm.to_secular(x, w)
    dsec = [sum(sp.diff(s, xi) * f[xi] for xi in x) for s in sec]
    r_av, L_av, lx, ly = sec
    expected = [2 * aT / w, -sp.Rational(3, 2) * w * r_av - 2 * aS / w, -w * ly - 2 * aT / w, w * lx - aS / w]
    assert all(sp.simplify(d - e) == 0 for d, e in zip(dsec, expected))
    # dimensionless: d(y/K)/d(tau) = (1/(omega K)) d(sec)/dt with aT = a delta, aS = a delta_s
    a = sym("a")
    dim = build_model("relative_motion_secular", {"radial": True})
    delta, delta_s = dim.symbol("delta"), dim.symbol("delta_s")
    K = rm.scale_length(a, w)
    y = rm.to_dimensionless(x, w, a)
    lhs = [sum(sp.diff(yi, xi) * f[xi] for xi in x) / w for yi in y]
    rhs = dim.rhs().subs(dict(zip(dim.states, y)))
    sub = {aT: a * delta, aS: a * delta_s}
    assert all(sp.simplify(l.subs(sub) - r) == 0 for l, r in zip(lhs, rhs))
    assert sp.simplify(K - 2 * a / w**2) == 0
    # rm.dimensionless_rhs is the same function as the registered model
    assert all(sp.simplify(p - q) == 0 for p, q in
               zip(rm.dimensionless_rhs(dim.states, delta, delta_s), dim.rhs()))


# ---- §2.6 closed forms; §5.2 check 8 --------------------------------------------------
def test_segment_and_semi_axis_against_integration():
    _, f = _rhs("relative_motion_secular")
    for _ in range(5):
        y0 = RNG.normal(size=4)
        delta = float(RNG.choice([-1, 0, 1]))
        tau = float(RNG.uniform(0.1, 9.0))
        y = _integrate(f, y0, [delta], tau)
        assert np.max(np.abs(y - rm.segment(y0, delta, tau))) < 1e-10
        l0, phi0 = math.hypot(y0[2], y0[3]), math.atan2(y0[3], y0[2])
        assert abs(rm.semi_axis_after_burn(l0, phi0, delta, tau) - math.hypot(y[2], y[3])) < 1e-10


def test_multi_burn_closed_form_against_integration():
    _, f = _rhs("relative_motion_secular")
    for _ in range(4):
        y0 = RNG.normal(size=4) * [0.5, 5.0, 0.5, 0.5]
        durs = RNG.uniform(0.05, 4.0, size=6)          # coast, burn, coast, burn, coast, burn
        signs = [0.0, *RNG.choice([-1.0, 1.0], size=1), 0.0, *RNG.choice([-1.0, 1.0], size=1),
                 0.0, *RNG.choice([-1.0, 1.0], size=1)]
        burns, t = [], 0.0
        for s, d in zip(signs, durs):
            if s:
                burns.append((s, t, t + d))
            t += d
        y_cf = rm.multi_burn(y0, burns, t)
        y_num = _integrate_programme(f, y0, list(zip(signs, durs)))
        assert np.max(np.abs(y_cf - y_num)) < 1e-10


def test_dimensional_hcw_through_K_and_tau_gives_same_answer():
    """Two-burn programme in metres and seconds (GEO, a = 1e-4) = dimensionless closed form."""
    y0 = np.array([-0.5, -20.0, 0.49, 0.0])
    t0, t1, tp, t2 = 0.240668, 1.621522, 4.165474, 2.121522   # dimensionless durations
    d1, d2 = -1, 1
    x = np.array(rm.from_dimensionless(y0, OMEGA, A_THRUST))
    for aT, dur in ((0.0, t0), (d1 * A_THRUST, t1), (0.0, tp), (d2 * A_THRUST, t2)):
        t = rm.t_of_tau(dur, OMEGA)
        x = rm.fundamental_matrix(t, OMEGA) @ x + rm.forced_response_aT(t, OMEGA, aT)
    y_dim = np.array(rm.to_dimensionless(x, OMEGA, A_THRUST))
    y_cf = rm.two_burn_final_state(y0, t0, t1, tp, t2, d1, d2)
    assert np.max(np.abs(y_dim - y_cf)) < 1e-10
    # and the closed form of a programme equals integration of the dimensional registered model
    _, f = _rhs("hcw", params={"omega": OMEGA})
    x = np.array(rm.from_dimensionless(y0, OMEGA, A_THRUST))
    for aT, dur in ((0.0, t0), (d1 * A_THRUST, t1), (0.0, tp), (d2 * A_THRUST, t2)):
        x = _integrate(f, x, [0.0, aT], rm.t_of_tau(dur, OMEGA))
    y_int = np.array(rm.to_dimensionless(x, OMEGA, A_THRUST))
    assert np.max(np.abs(y_int - y_cf)) < 1e-8


def test_two_burn_sums_match_printed_A_B_C():
    """The printed (30) A, B, C (same sign, delta factored out) follow from the general sums."""
    t0, t1, tp, t2 = 0.3, 0.7, 5.1, 1.1
    y0 = (0.0, 0.0, 0.0, 0.0)
    for d2, A, B, C in (
            (1, -math.cos(t1 + tp + t2) + math.cos(tp + t2) - math.cos(t2) + 1,
             math.sin(t1 + tp + t2) - math.sin(tp + t2) + math.sin(t2), t1 + t2),
            (-1, -math.cos(t1 + tp + t2) + math.cos(tp + t2) + math.cos(t2) - 1,
             math.sin(t1 + tp + t2) - math.sin(tp + t2) - math.sin(t2), t1 - t2)):
        y = rm.two_burn_final_state(y0, t0, t1, tp, t2, 1, d2)
        assert abs(y[0] - C) < 1e-14 and abs(y[2] + B) < 1e-14 and abs(y[3] + A) < 1e-14
        D = t1**2 + 2 * t1 * (tp + t2) + d2 * t2**2
        assert abs(y[1] + 0.75 * D) < 1e-12


# ---- §2.8: burn durations, boundary, ends --------------------------------------------
@pytest.mark.parametrize("d1,d2", [(1, 1), (-1, -1), (1, -1), (-1, 1)])
def test_burn_durations_meet_secular_conditions(d1, d2):
    for _ in range(20):
        y0 = (float(RNG.uniform(-1, 1)), float(RNG.uniform(-25, 25)), 0.3, -0.2)
        final = (float(RNG.uniform(-0.3, 0.3)), float(RNG.uniform(-2, 2)))
        t0, tp = float(RNG.uniform(0, 2 * math.pi)), float(RNG.uniform(0.1, 40))
        t1, t2 = rm.burn_durations(y0, t0, tp, d1, d2, final)
        if math.isnan(t1):
            continue
        y = rm.two_burn_final_state(y0, t0, t1, tp, t2, d1, d2)
        assert abs(y[0] - final[0]) < 1e-12
        assert abs(y[1] - final[1]) < 1e-9 * (1 + abs(y0[1]))
        if d1 == d2:
            assert abs((t1 + t2) - d1 * (final[0] - y0[0])) < 1e-12


def test_opposite_sign_durations_equal_digest_formula():
    """Zero final state: t2 = (-tp + sqrt(tp^2 + 2 r0^2 + 4 d (2/3 L0 - r0 t0)))/2, t1 = t2 - r0/d."""
    for d in (1, -1):
        for _ in range(10):
            r0, L0 = float(RNG.uniform(-1, 1)), float(RNG.uniform(-25, 25))
            t0, tp = float(RNG.uniform(0, 6)), float(RNG.uniform(0, 30))
            disc = tp**2 + 2 * r0**2 + 4 * d * (2 / 3 * L0 - r0 * t0)
            t1, t2 = rm.burn_durations((r0, L0, 0, 0), t0, tp, d, -d)
            if disc < 0:
                assert math.isnan(t1)
                continue
            t2r = 0.5 * (-tp + math.sqrt(disc))
            assert abs(t2 - t2r) < 1e-12 and abs(t1 - (t2r - r0 / d)) < 1e-12


def test_boundary_and_ends_case_A_data():
    """Digest §5.3 boundary table (case A data, delta1 = -1) and (27)."""
    y0 = (-0.5, -20.0, 0.49, 0.0)
    ref = {0.0: (26.916667, 18.194444, 11.516667, 7.731481, (6.837120, 6.837120)),
           2 * math.pi: (26.916667, 20.288840, 15.286578, 12.618403, (5.923937, 12.207122))}
    for t0, row in ref.items():
        for t_mot, t_sum in zip((0.5, 1.0, 2.0, 4.0), row[:4]):
            assert abs(rm.boundary_t_sum(t_mot, t0, y0, -1) - t_sum) < 5e-7
            # on the boundary the durations of (22) reproduce t_mot
            tp = rm.boundary_tp(t_mot, t0, y0, -1)
            t1, t2 = rm.burn_durations(y0, t0, tp, -1, 1)
            assert abs(t1 + t2 - t_mot) < 1e-9
        tm, ts = rm.right_end(t0, y0, -1)
        assert abs(tm - row[4][0]) < 5e-7 and abs(ts - row[4][1]) < 5e-7
        t1, t2 = rm.burn_durations(y0, t0, 0.0, -1, 1)
        assert abs(t0 + t1 + t2 - ts) < 1e-12          # §5.1 check 3: at tp = 0, t_sum = t0 + t_mot


def test_same_sign_bound():
    assert abs(rm.same_sign_bound(0.5) - 0.498699) < 5e-7
    # the bound is the largest |2 sin(t1/2) + 2 sin(t2/2)| with t1 + t2 = |Delta|
    t1 = np.linspace(0, 0.5, 2001)
    assert abs(np.max(2 * np.sin(t1 / 2) + 2 * np.sin((0.5 - t1) / 2)) - rm.same_sign_bound(-0.5)) < 1e-12
