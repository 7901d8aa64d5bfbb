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


def test_the_segment_polynomial_integral_is_exact_for_polynomials_and_beats_pchip_on_smooth_data():
    """unseen21 FA3: dH/dt = lambda2 cos t on nodes 0.5 apart (a degree-12 segment): PCHIP's
    integral was off by 0.056 and failed H; each segment's own polynomial through its nodes is
    what the collocation interpolates, exact for polynomials of that degree."""
    from ocdsl.solve import pchip
    from ocdsl.transcribe.nodes import legendre_gauss_radau

    b = np.array([0.0, 5.76, 2 * np.pi])
    t = np.concatenate([b[k] + (b[k + 1] - b[k]) * (np.asarray(legendre_gauss_radau(n)[0]) + 1) / 2
                        for k, n in ((0, 12), (1, 5))])
    t = np.sort(np.unique(np.round(np.concatenate([t, b[1:]]), 14)))
    t = t[t > 0]
    y = 0.3 * t ** 4 - t ** 2 + 1
    exact = lambda s: 0.06 * s ** 5 - s ** 3 / 3 + s   # noqa: E731
    seg = pchip.segment_integral_to_end(t, y, b)
    assert np.max(np.abs(seg - (exact(b[-1]) - exact(t)))) < 1e-9
    y = np.cos(t)
    truth = np.sin(b[-1]) - np.sin(t)
    poly_err = np.max(np.abs(pchip.segment_integral_to_end(t, y, b) - truth))
    assert poly_err < 1e-6 < 1e-2 < np.max(np.abs(pchip.integral_to_end(t, y) - truth))
    assert pchip.segment_integral_to_end(t, y, [0.0, 1.0]) is None      # nodes outside the breakpoints
