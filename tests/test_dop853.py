"""ocdsl's NumPy DOP853 (ocdsl/verify/dop853.py) against SciPy's ``solve_ivp(method="DOP853")``.

The stepping is meant to be SciPy's, so the two must agree to round-off at the same
tolerances (same number of right-hand side calls, values within 1e-12 relative), and both
must meet the exact solution where there is one. Cases: smooth (harmonic oscillator, a
Kepler orbit, backwards in time), stiff-ish (Van der Pol with mu = 10, where an explicit
method takes thousands of steps), a vector atol, and a right-hand side that leaves its
domain (both must fail, not return a number).
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ocdsl.verify import dop853


def _vdp(mu):
    return lambda t, y: np.array([y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]])


def _kepler(t, y):
    r3 = np.hypot(y[0], y[1]) ** 3
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


def _oscillator(t, y):
    return np.array([y[1], -y[0]])


CASES = {
    "oscillator": (_oscillator, (0.0, 12.0), [1.0, 0.0], 1e-10, 1e-12),
    "kepler": (_kepler, (0.0, 20.0), [1.0, 0.0, 0.0, 1.2], 1e-10, np.full(4, 1e-12)),
    "kepler_backwards": (_kepler, (5.0, 0.0), [1.0, 0.0, 0.0, 1.2], 1e-9, 1e-12),
    "van_der_pol_stiffish": (_vdp(10.0), (0.0, 20.0), [2.0, 0.0], 1e-8, 1e-10),
    "van_der_pol": (_vdp(1.0), (0.0, 10.0), [2.0, 0.0], 1e-10, np.array([1e-12, 1e-11])),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_same_steps_and_values_as_scipy(name):
    f, span, y0, rtol, atol = CASES[name]
    t_eval = np.linspace(*span, 41)
    ref = solve_ivp(f, span, y0, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol)
    ours = dop853.solve(f, span, y0, t_eval, rtol, atol)
    assert ref.success and ours.success
    assert ours.nfev == ref.nfev
    assert ours.y.shape == ref.y.shape
    np.testing.assert_allclose(ours.y, ref.y, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(ours.t, ref.t)


def test_exact_solution_within_tolerance():
    t_eval = np.linspace(0.0, 12.0, 25)
    sol = dop853.solve(_oscillator, (0.0, 12.0), [1.0, 0.0], t_eval, 1e-10, 1e-12)
    assert np.max(np.abs(sol.y[0] - np.cos(t_eval))) < 1e-8
    assert np.max(np.abs(sol.y[1] + np.sin(t_eval))) < 1e-8
    # a Kepler orbit keeps its energy
    sol = dop853.solve(_kepler, (0.0, 20.0), [1.0, 0.0, 0.0, 1.2], t_eval, 1e-11, 1e-13)
    x, y, vx, vy = sol.y
    energy = 0.5 * (vx ** 2 + vy ** 2) - 1 / np.hypot(x, y)
    assert np.max(np.abs(energy - energy[0])) < 1e-8


def test_leaving_the_domain_fails_like_scipy():
    def f(t, y):              # y' = -1/(2 y): y = sqrt(1 - t) reaches 0 at t = 1
        with np.errstate(all="ignore"):
            return np.array([-0.5 / np.sqrt(y[0])])

    t_eval = np.linspace(0.0, 2.0, 9)
    with np.errstate(all="ignore"):
        ref = solve_ivp(f, (0.0, 2.0), [1.0], method="DOP853", t_eval=t_eval, rtol=1e-8, atol=1e-10)
        ours = dop853.solve(f, (0.0, 2.0), [1.0], t_eval, 1e-8, 1e-10)
    assert ref.success is False and ours.success is False
    assert ours.y.shape == ref.y.shape and ours.t_end < 2.0
    np.testing.assert_allclose(ours.y, ref.y, rtol=1e-12, equal_nan=True)


def test_empty_state_and_zero_span():
    sol = dop853.solve(lambda t, y: np.zeros(0), (0.0, 1.0), np.zeros(0), [0.0, 0.5, 1.0], 1e-8, 1e-10)
    assert sol.success and sol.y.shape == (0, 3)
    sol = dop853.solve(_oscillator, (1.0, 1.0), [1.0, 2.0], [1.0], 1e-8, 1e-10)
    assert sol.success and sol.y[:, 0].tolist() == [1.0, 2.0]


def test_importing_it_does_not_import_scipy():
    import subprocess
    import sys

    code = ("import sys; from ocdsl.verify import dop853; dop853._table(); "
            "print(sorted(m for m in sys.modules if m == 'scipy' or m.startswith('scipy.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_ensemble_steps_each_piece_as_alone():
    """``solve_ensemble``: pieces of very different difficulty side by side (Van der Pol at
    mu = 1 and 10 over spans of 1 and 12, in their own time s in [0, 1]): each piece takes the
    steps it takes alone and gives its values at the positions to round-off; a piece that
    leaves its domain fails the ensemble instead of returning numbers."""
    spans = np.array([1.0, 12.0, 3.0, 12.0])
    mus = np.array([1.0, 1.0, 10.0, 10.0])
    y0 = np.array([[2.0, 0.0], [1.0, 0.5], [2.0, 0.0], [0.5, -1.0]])
    positions = np.linspace(0.0, 1.0, 9)

    def fun(idx, s, Y):
        mu = mus[idx]
        return np.column_stack([Y[:, 1], mu * (1 - Y[:, 0] ** 2) * Y[:, 1] - Y[:, 0]]) * spans[idx, None]

    ens = dop853.solve_ensemble(fun, y0, positions, 1e-9, 1e-11)
    assert ens.success and ens.y.shape == (9, 4, 2)
    steps = 0
    for k in range(4):
        alone = dop853.solve(lambda s, y: fun(np.array([k]), np.array([s]), y[None])[0], (0.0, 1.0), y0[k],
                             positions, 1e-9, 1e-11)
        steps += alone.steps
        assert np.max(np.abs(ens.y[:, k].T - alone.y)) < 1e-12 * max(1.0, np.abs(alone.y).max())
    assert ens.steps == steps

    def leaves(idx, s, Y):
        F = fun(idx, s, Y)
        F[idx == 2] = np.where(s[idx == 2, None] > 0.5, np.nan, F[idx == 2])
        return F

    bad = dop853.solve_ensemble(leaves, y0, positions, 1e-9, 1e-11)
    assert not bad.success and "piece 2" in bad.message
