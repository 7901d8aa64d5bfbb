"""The certificate's PCHIP integral (ocdsl/solve/pchip.py) against SciPy's PchipInterpolator."""
import numpy as np
from hypothesis import given, settings, strategies as st
from scipy.interpolate import PchipInterpolator

from ocdsl.solve import pchip


def _scipy_to_end(t, y):
    F = PchipInterpolator(t, y).antiderivative()(t)
    return F[-1] - F


@settings(max_examples=200, deadline=None)
@given(st.integers(3, 40), st.integers(0, 2**31 - 1), st.sampled_from(["smooth", "steps", "noise"]))
def test_integral_matches_scipy(n, seed, kind):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, 1.0, n))
    if kind == "smooth":
        y = np.sin(3 * t) + 0.1 * t
    elif kind == "steps":   # flat runs and a jump: the zero-slope branches
        y = np.where(t < t[n // 2], 1.0, -2.0)
    else:
        y = rng.normal(size=n)
    ours = pchip.integral_to_end(t, y)
    ref = _scipy_to_end(t, y)
    scale = np.sum(np.abs(y[1:]) * np.diff(t)) + 1e-300
    assert np.max(np.abs(ours - ref)) <= 1e-12 * scale
    np.testing.assert_allclose(pchip.slopes(t, y), PchipInterpolator(t, y).derivative()(t),
                               rtol=1e-10, atol=1e-12 * (np.max(np.abs(y)) + 1))


def test_two_points_is_the_trapezoid():
    np.testing.assert_allclose(pchip.integral_to_end([0.0, 2.0], [1.0, 3.0]), [4.0, 0.0])


def test_exact_on_a_monotone_cubic_free_shape():
    # a straight line is reproduced exactly (all slopes equal the secant)
    t = np.array([0.0, 0.3, 1.1, 2.0])
    y = 2.0 * t + 1.0
    exact = (t[-1] ** 2 + t[-1]) - (t ** 2 + t)
    np.testing.assert_allclose(pchip.integral_to_end(t, y), exact, atol=1e-14)
