"""Clamped B-spline basis and derivative matrices against scipy.interpolate.BSpline."""
import numpy as np
import pytest
from scipy.interpolate import BSpline

from ocdsl.transcribe.bspline import basis_matrix, clamped_knots, greville, n_pieces


@pytest.mark.parametrize("degree,n_ctrl", [(0, 4), (1, 5), (3, 7), (5, 15), (6, 16)])
@pytest.mark.parametrize("deriv", [0, 1, 2, 3])
def test_basis_matches_scipy(degree, n_ctrl, deriv):
    a, b = -0.5, 2.0
    x = np.concatenate([np.linspace(a, b, 37), [a, b]])
    M = basis_matrix(degree, n_ctrl, x, deriv, a, b)
    t = clamped_knots(degree, n_ctrl, a, b)
    rng = np.random.default_rng(degree * 10 + deriv)
    c = rng.normal(size=n_ctrl)
    ref = BSpline(t, c, degree, extrapolate=False)
    expected = ref.derivative(deriv)(x) if deriv <= degree else np.zeros_like(x)
    if deriv > degree - 1 and degree > 0:
        # derivative of order degree is piecewise constant: compare away from knots
        keep = ~np.isclose(x[:, None], t[None, :]).any(axis=1)
        np.testing.assert_allclose((M @ c)[keep], np.asarray(expected)[keep], rtol=1e-10, atol=1e-10)
    elif degree == 0:
        keep = ~np.isclose(x[:, None], t[None, :]).any(axis=1)
        np.testing.assert_allclose((M @ c)[keep], np.asarray(expected)[keep], atol=1e-12)
    else:
        np.testing.assert_allclose(M @ c, expected, rtol=1e-10, atol=1e-10)


def test_partition_of_unity_and_clamping():
    x = np.linspace(0, 1, 101)
    M = basis_matrix(5, 15, x)
    np.testing.assert_allclose(M.sum(axis=1), 1.0, atol=1e-13)
    assert M[0, 0] == 1.0 and M[-1, -1] == 1.0
    D = basis_matrix(5, 15, x, 1)
    np.testing.assert_allclose(D.sum(axis=1), 0.0, atol=1e-10)
    assert n_pieces(5, 15) == 10          # seed: 10 pieces of order 6, smoothness 5 -> 15 points


def test_reproduces_polynomials_exactly():
    """A degree-5 spline reproduces x^5 on [0, 3]; fit through the Greville points."""
    x = np.linspace(0, 3, 50)
    g = greville(5, 12, 0, 3)
    A = basis_matrix(5, 12, np.linspace(0, 3, 40), 0, 0, 3)
    c, *_ = np.linalg.lstsq(A, np.linspace(0, 3, 40) ** 5, rcond=None)
    for d, f in enumerate([x ** 5, 5 * x ** 4, 20 * x ** 3, 60 * x ** 2]):
        np.testing.assert_allclose(basis_matrix(5, 12, x, d, 0, 3) @ c, f, rtol=1e-8, atol=1e-8)
    assert g[0] == 0 and g[-1] == 3 and np.all(np.diff(g) > 0)


def test_rejects_bad_arguments():
    with pytest.raises(ValueError, match="control points"):
        clamped_knots(5, 4)
    with pytest.raises(ValueError, match="outside"):
        basis_matrix(3, 6, [1.2])
    assert not basis_matrix(2, 5, [0.3], deriv=3).any()


def test_the_cached_derivative_operator_is_read_only():
    """It is shared by every later call with the same basis: a caller must not be able to
    change what the next one gets."""
    from ocdsl.transcribe.bspline import _derivative_operator

    op = _derivative_operator(3, 6, 1, 0.0, 1.0)
    assert not op.flags.writeable and _derivative_operator(3, 6, 1, 0.0, 1.0) is op
