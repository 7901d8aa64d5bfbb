"""The mesh locators' Brent root finder (ocdsl/solve/mesh/roots.py) against SciPy's brentq."""
import math

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st
from scipy.optimize import brentq as scipy_brentq

from ocdsl.solve.mesh.roots import brentq

CASES = [
    (lambda x: x ** 3 - 2 * x - 5, 2.0, 3.0),
    (math.cos, 0.0, 3.0),
    (lambda x: math.exp(x) - 1e4, 0.0, 20.0),
    (lambda x: (x - 0.3) ** 3, 0.0, 1.0),            # a triple root: slow for interpolation
    (lambda x: math.copysign(1.0, x - 0.7123), 0.0, 1.0),   # a jump: bisection only
    (lambda x: math.atan(1e6 * (x - 1e-3)), -1.0, 1.0),
]


@pytest.mark.parametrize("f, a, b", CASES)
@pytest.mark.parametrize("xtol", [1e-14, 1e-15, 2e-12])
def test_same_root_as_scipy(f, a, b, xtol):
    try:
        ref = scipy_brentq(f, a, b, xtol=xtol)
    except RuntimeError:         # the triple root at 1e-14: neither reaches it in 100 steps
        with pytest.raises(RuntimeError):
            brentq(f, a, b, xtol=xtol)
        return
    ours = brentq(f, a, b, xtol=xtol)
    assert abs(ours - ref) <= 4 * (xtol + 4 * np.finfo(float).eps * abs(ref))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-5, 5), min_size=2, max_size=6), st.floats(-3, 3), st.floats(0.1, 4))
@example(coefs=[0.0, 2.2250738585e-313], a=-1.0, width=1.5)    # found by CI: a subnormal slope
def test_random_polynomials(coefs, a, width):
    p = np.polynomial.Polynomial(coefs)
    b = a + width
    sa, sb = np.sign(p(a)), np.sign(p(b))
    if sa * sb > 0:
        with pytest.raises(ValueError):
            brentq(p, a, b)
        return
    if sa * sb == 0:
        assert p(brentq(p, a, b)) == 0
        return
    try:
        ref = scipy_brentq(p, a, b, xtol=1e-14)
    except RuntimeError:        # a multiple root (x**3): neither converges in 100 steps
        with pytest.raises(RuntimeError):
            brentq(p, a, b, xtol=1e-14)
        return
    x = brentq(p, a, b, xtol=1e-14)
    assert a <= x <= b
    # SciPy's own root, or a better one: with a subnormal slope (2.2e-313 x) SciPy's products
    # of function values underflow to 0 and it stops at -7.4e-12, where ours finds 0 exactly
    # (both values there are 0 in floating point: both are roots)
    assert abs(x - ref) <= 4e-14 + 4 * 4 * np.finfo(float).eps * abs(x) or abs(p(x)) <= abs(p(ref))


def test_no_sign_change_and_an_endpoint_root():
    with pytest.raises(ValueError):
        brentq(lambda x: x * x + 1, -1.0, 1.0)
    assert brentq(lambda x: x - 2.0, 2.0, 5.0) == 2.0
