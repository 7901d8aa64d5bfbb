"""Nodes, weights and matrices of ocdsl.transcribe.nodes (pure NumPy, no solver)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import legendre as npleg

from ocdsl.transcribe import nodes
from ocdsl.transcribe.nodes import (
    SCHEME_NAMES,
    Scheme,
    differentiation_matrix,
    lagrange_matrix,
    legendre_gauss,
    legendre_gauss_lobatto,
    legendre_gauss_radau,
    scheme,
)

DEGREES = range(1, 31)
# Polynomial degree each rule integrates exactly, as a function of n.
EXACT_DEGREE = {"LG": lambda n: 2 * n - 1, "LGR": lambda n: 2 * n - 2,
                "LGR-start": lambda n: 2 * n - 2, "LGL": lambda n: 2 * n - 3}


def _all_schemes(degrees=DEGREES):
    for name in SCHEME_NAMES:
        for n in degrees:
            if name == "LGL" and n < 2:
                continue
            yield name, n


def _random_legendre_series(rng, degree):
    # Legendre-basis coefficients keep random polynomials well scaled on [-1, 1] even at
    # degree 60, where monomial coefficients would make the reference values meaningless.
    return npleg.Legendre(rng.standard_normal(degree + 1))


# ---------------------------------------------------------------------------- known nodes

def test_known_lg_nodes_and_weights():
    x, w = legendre_gauss(3)
    np.testing.assert_allclose(x, [-np.sqrt(0.6), 0.0, np.sqrt(0.6)], rtol=0, atol=1e-14)
    np.testing.assert_allclose(w, [5 / 9, 8 / 9, 5 / 9], rtol=0, atol=1e-14)
    assert x[1] == 0.0  # symmetry is imposed exactly


def test_known_lgl_nodes_and_weights():
    x, w = legendre_gauss_lobatto(4)
    r = 1 / np.sqrt(5)
    np.testing.assert_allclose(x, [-1, -r, r, 1], rtol=0, atol=1e-14)
    np.testing.assert_allclose(w, [1 / 6, 5 / 6, 5 / 6, 1 / 6], rtol=0, atol=1e-14)
    x, w = legendre_gauss_lobatto(2)  # trapezoid rule
    np.testing.assert_array_equal(x, [-1, 1])
    np.testing.assert_allclose(w, [1, 1], atol=1e-15)


def test_known_radau_nodes_both_conventions():
    x, w = legendre_gauss_radau(2)  # flipped by default
    np.testing.assert_allclose(x, [-1 / 3, 1], rtol=0, atol=1e-14)
    np.testing.assert_allclose(w, [3 / 2, 1 / 2], rtol=0, atol=1e-14)
    xl, wl = legendre_gauss_radau(2, end="left")
    np.testing.assert_allclose(xl, [-1, 1 / 3], rtol=0, atol=1e-14)
    np.testing.assert_allclose(wl, [1 / 2, 3 / 2], rtol=0, atol=1e-14)

    # Radau IIA, three stages: c and b from the Butcher tableau, mapped to [-1, 1].
    s6 = np.sqrt(6)
    c = np.array([(4 - s6) / 10, (4 + s6) / 10, 1.0])
    b = np.array([(16 - s6) / 36, (16 + s6) / 36, 1 / 9])
    x, w = legendre_gauss_radau(3)
    np.testing.assert_allclose(x, 2 * c - 1, rtol=0, atol=1e-14)
    np.testing.assert_allclose(w, 2 * b, rtol=0, atol=1e-14)


@pytest.mark.parametrize("n", [1, 2, 5, 17, 30, 64, 100])
def test_lg_matches_numpy_reference(n):
    x, w = legendre_gauss(n)
    xr, wr = npleg.leggauss(n)
    np.testing.assert_allclose(x, xr, rtol=0, atol=1e-14)
    # rtol 1e-11, not tighter: against 40-digit references, numpy's own weights nearest
    # +-1 are off by 2e-12 relative at n = 100 (ours by 1.3e-13, the limit set by rounding
    # the node itself), so a tighter bound would test numpy.
    np.testing.assert_allclose(w, wr, rtol=1e-11, atol=0)


@pytest.mark.parametrize("n", [2, 5, 17, 30, 64])
def test_radau_and_lobatto_are_roots_of_their_polynomials(n):
    # Left Radau: roots of P_{n-1} + P_n; Lobatto interior: roots of P'_{n-1}.
    xl, _ = legendre_gauss_radau(n, end="left")
    radau_poly = npleg.Legendre.basis(n - 1) + npleg.Legendre.basis(n)
    slope = np.abs(radau_poly.deriv()(xl))
    assert np.all(np.abs(radau_poly(xl)) / slope < 1e-14)  # Newton step ~ node error
    xr, wr = legendre_gauss_radau(n)
    np.testing.assert_array_equal(xr, -xl[::-1])
    assert xr[-1] == 1.0 and xl[0] == -1.0

    xg, _ = legendre_gauss_lobatto(n)
    if n > 2:
        inner = xg[1:-1]
        dp = npleg.Legendre.basis(n - 1).deriv()
        assert np.all(np.abs(dp(inner)) / np.abs(dp.deriv()(inner)) < 1e-14)
    assert xg[0] == -1.0 and xg[-1] == 1.0


@pytest.mark.parametrize("name,n", list(_all_schemes(range(1, 61))))
def test_structure_of_every_scheme(name, n):
    s = scheme(name, n)
    assert isinstance(s, Scheme) and s.name == name and s.degree == n
    assert s.colloc.shape == (n,) and s.weights.shape == (n,)
    assert s.D.shape == (n, s.support.size)
    assert s.support[0] == -1.0
    assert np.all(np.diff(s.support) > 0) and np.all(np.diff(s.colloc) > 0)
    assert np.all(s.weights > 0)
    assert abs(s.weights.sum() - 2) < 1e-13
    assert s.end_from_support == (name != "LG")
    assert s.end_from_support == (s.support[-1] == 1.0)
    idx = s.colloc_in_support
    assert idx.dtype.kind == "i"
    np.testing.assert_array_equal(s.support[idx[idx >= 0]], s.colloc[idx >= 0])
    expected_m = n if name == "LGL" else n + 1
    assert s.support.size == expected_m
    if name == "LGR":
        assert s.colloc[-1] == 1.0
    if name == "LGR-start":
        assert s.colloc[0] == -1.0 and s.support[-1] == 1.0
    # D annihilates constants and differentiates tau exactly.
    np.testing.assert_allclose(s.D.sum(axis=1), 0.0, atol=1e-12 * max(1, n * n))
    np.testing.assert_allclose(s.D @ s.support, 1.0, rtol=0, atol=1e-11)


def test_scheme_is_cached_and_read_only():
    s = scheme("LGR", 4)
    assert scheme("LGR", 4) is s
    assert {s: 1}[s] == 1  # usable as a key despite holding arrays
    for arr in (s.support, s.colloc, s.D, s.weights, s.colloc_in_support):
        with pytest.raises(ValueError):
            arr[0] = 0  # the cached arrays must not be editable by a caller
    with pytest.raises(AttributeError):
        s.degree = 5


# ------------------------------------------------------------------- exactness of D and w

@pytest.mark.parametrize("name", SCHEME_NAMES)
def test_D_differentiates_polynomials_of_support_degree_exactly(name):
    rng = np.random.default_rng(1)
    for _, n in _all_schemes():
        if _ != name:
            continue
        s = scheme(name, n)
        for _trial in range(3):
            p = _random_legendre_series(rng, s.support.size - 1)
            exact = p.deriv()(s.colloc)
            got = s.D @ p(s.support)
            scale = max(1.0, np.max(np.abs(exact)))
            assert np.max(np.abs(got - exact)) / scale < 1e-11, (name, n)


def test_D_is_not_exact_one_degree_above_support():
    # Guards against a D built on the wrong support (e.g. one that silently includes an
    # extra point): a polynomial one degree too high must not be differentiated exactly.
    rng = np.random.default_rng(2)
    for name, n in _all_schemes(range(1, 8)):
        s = scheme(name, n)
        p = _random_legendre_series(rng, s.support.size)
        err = np.max(np.abs(s.D @ p(s.support) - p.deriv()(s.colloc)))
        assert err > 1e-6, (name, n)


def _node_polynomial_integrand(s):
    """Non-negative polynomial of degree (exact degree + 1) vanishing at every node.

    Squares of (x - x_i) at interior nodes, single factors (1 -+ x) at endpoints: the
    quadrature gives exactly 0 while the integral is positive, so the rule cannot be exact
    one degree above its claimed degree.
    """
    inner = s.colloc[np.abs(s.colloc) < 1]
    ends = s.colloc[np.abs(s.colloc) == 1]

    def f(x):
        x = np.asarray(x, dtype=float)
        v = np.prod((x[..., None] - inner) ** 2, axis=-1)
        for e in ends:
            v = v * (1 - e * x)
        return v

    degree = 2 * inner.size + ends.size
    return f, degree


@pytest.mark.parametrize("name", SCHEME_NAMES)
def test_quadrature_exact_to_its_degree_and_not_beyond(name):
    rng = np.random.default_rng(3)
    for _, n in _all_schemes():
        if _ != name:
            continue
        s = scheme(name, n)
        k = EXACT_DEGREE[name](n)
        for _trial in range(3):
            p = _random_legendre_series(rng, k)
            exact = 2 * p.coef[0]  # only P_0 has a non-zero integral over [-1, 1]
            assert abs(s.weights @ p(s.colloc) - exact) < 1e-12 * max(1, np.abs(p.coef).sum())

        f, degree = _node_polynomial_integrand(s)
        assert degree == k + 1
        xr, wr = npleg.leggauss(n + 2)  # exact for degree 2n + 3 >= k + 1
        integral = wr @ f(xr)
        quad = s.weights @ f(s.colloc)
        assert integral > 0
        assert abs(quad - integral) > 0.5 * integral, (name, n, quad, integral)


@pytest.mark.parametrize("n", DEGREES)
def test_lg_end_state_from_quadrature_is_exact(n):
    rng = np.random.default_rng(100 + n)
    s = scheme("LG", n)
    assert not s.end_from_support and s.support[-1] < 1
    for _trial in range(3):
        p = _random_legendre_series(rng, s.support.size - 1)
        x_support = p(s.support)
        x_end = x_support[0] + s.weights @ (s.D @ x_support)
        assert abs(x_end - p(1.0)) < 1e-11 * max(1.0, np.abs(p.coef).sum())


# -------------------------------------------------------- interpolation and differentiation

def test_differentiation_matrix_small_case():
    D = differentiation_matrix([-1.0, 0.0, 1.0])
    np.testing.assert_allclose(D, [[-1.5, 2, -0.5], [-0.5, 0, 0.5], [0.5, -2, 1.5]],
                               atol=1e-15)
    assert differentiation_matrix([0.3]).tolist() == [[0.0]]


@pytest.mark.parametrize("m", [1, 2, 7, 31, 61])
def test_lagrange_matrix_identity_at_nodes_and_exact_for_degree_m_minus_1(m):
    nodes = legendre_gauss_lobatto(m)[0] if m >= 2 else np.array([0.25])
    np.testing.assert_array_equal(lagrange_matrix(nodes, nodes), np.eye(m))
    rng = np.random.default_rng(m)
    p = _random_legendre_series(rng, m - 1)
    pts = np.concatenate((np.linspace(-1, 1, 101), rng.uniform(-1, 1, 50)))
    L = lagrange_matrix(nodes, pts)
    assert L.shape == (pts.size, m)
    np.testing.assert_allclose(L.sum(axis=1), 1.0, atol=1e-13)
    err = np.max(np.abs(L @ p(nodes) - p(pts)))
    assert err < 1e-12 * np.abs(p.coef).sum()
    # Derivative matrix at degree 60 too (the range the builder may use).
    dp_err = np.max(np.abs(differentiation_matrix(nodes) @ p(nodes) - p.deriv()(nodes)))
    assert dp_err < 1e-10 * max(1.0, np.max(np.abs(p.deriv()(nodes))))


@settings(max_examples=60, deadline=None)
@given(
    family=st.sampled_from(["LG", "LGL", "cheb"]),
    m=st.integers(2, 45),
    seed=st.integers(0, 2**32 - 1),
    include_nodes=st.booleans(),
)
def test_lagrange_matrix_property(family, m, seed, include_nodes):
    rng = np.random.default_rng(seed)
    if family == "LG":
        nodes = legendre_gauss(m)[0]
    elif family == "LGL":
        nodes = legendre_gauss_lobatto(m)[0]
    else:
        nodes = np.cos(np.pi * (np.arange(m) + 0.5) / m)[::-1]
    # Interpolation is exact for any node order: shuffle to check nothing assumes sorting.
    nodes = rng.permutation(nodes)
    pts = rng.uniform(-1, 1, 20)
    if include_nodes:
        pts = np.concatenate((pts, nodes[: m // 2]))
    p = _random_legendre_series(rng, m - 1)
    L = lagrange_matrix(nodes, pts)
    assert np.all(np.isfinite(L))
    assert np.max(np.abs(L @ p(nodes) - p(pts))) < 1e-11 * np.abs(p.coef).sum()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-3, 3, allow_nan=False), min_size=1, max_size=8, unique=True),
       st.integers(0, 2**32 - 1))
def test_lagrange_and_D_arbitrary_well_separated_nodes(raw, seed):
    nodes = np.array(raw)
    if nodes.size > 1 and np.min(np.diff(np.sort(nodes))) < 0.1:
        nodes = np.linspace(-3, 3, nodes.size)  # keep the test about the formula, not conditioning
    m = nodes.size
    rng = np.random.default_rng(seed)
    coef = rng.standard_normal(m)
    p = np.polynomial.Polynomial(coef, domain=[-3, 3], window=[-1, 1])
    pts = rng.uniform(-3, 3, 10)
    assert np.max(np.abs(lagrange_matrix(nodes, pts) @ p(nodes) - p(pts))) < 1e-8 * (
        1 + np.abs(coef).sum()) * 10 ** m
    D = differentiation_matrix(nodes)
    np.testing.assert_allclose(D.sum(axis=1), 0.0, atol=1e-12 * (1 + np.abs(D).max()))
    np.testing.assert_allclose(D @ p(nodes), p.deriv()(nodes),
                               rtol=0, atol=1e-7 * (1 + np.abs(coef).sum()) * 10 ** m)


def test_lagrange_and_D_reject_bad_nodes():
    with pytest.raises(ValueError, match="distinct"):
        lagrange_matrix([0.0, 0.5, 0.5], [0.1])
    with pytest.raises(ValueError, match="distinct"):
        differentiation_matrix([1.0, 1.0])
    with pytest.raises(ValueError, match="non-empty"):
        differentiation_matrix([])


# -------------------------------------------------------------------------------- errors

@pytest.mark.parametrize("name", ["lgr", "Radau", "", "LGR_start", "CGL"])
def test_bad_scheme_name(name):
    with pytest.raises(ValueError, match=r"unknown collocation scheme.*LG, LGR, LGR-start, LGL"):
        scheme(name, 3)


@pytest.mark.parametrize("name,degree,needle", [
    ("LG", 0, ">= 1"), ("LGR", -2, ">= 1"), ("LGR-start", 0, ">= 1"),
    ("LGL", 1, ">= 2"), ("LGL", 0, "both segment ends"),
    ("LG", 3.0, "integer"), ("LGR", True, "integer"), ("LG", "3", "integer"),
])
def test_bad_degree(name, degree, needle):
    scheme("LG", 3)  # a cached ("LG", 3) must not answer for ("LG", 3.0)
    with pytest.raises(ValueError, match=needle):
        scheme(name, degree)


def test_rule_functions_validate():
    with pytest.raises(ValueError, match="at least 1"):
        legendre_gauss(0)
    with pytest.raises(ValueError, match="at least 2"):
        legendre_gauss_lobatto(1)
    with pytest.raises(ValueError, match="'left' or 'right'"):
        legendre_gauss_radau(3, end="start")


@pytest.mark.parametrize("rule", [nodes.legendre_gauss, nodes.legendre_gauss_radau, nodes.legendre_gauss_lobatto])
def test_memoised_rules_hand_out_copies(rule):
    """The rules are memoised (mesh refinement asks for the same few hundreds of times): a
    caller that writes into what it got must not change what the next caller gets."""
    x, w = rule(5)
    x_again, w_again = rule(5)
    x[:] = 0.0
    w[:] = 0.0
    x3, w3 = rule(5)
    assert np.array_equal(x3, x_again) and np.array_equal(w3, w_again)
    assert abs(w3.sum() - 2.0) < 1e-14
    with pytest.raises(ValueError):
        rule(True)
