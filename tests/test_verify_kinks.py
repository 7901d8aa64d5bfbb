"""The verification's integrator steps to the kinks of the clipped control (a polynomial
crossing a bound inside a segment) and caps its first step: across a kink inside a step,
and from a first step near the whole span, DOP853's error estimate accepted errors far above
its rtol (Goddard's mass, a plain quadrature of the control, 2.4e-5 off at rtol 1e-10)."""
from __future__ import annotations

import math

import numpy as np

from ocdsl.verify.integrate import dop853_split
from ocdsl.verify.interpolate import SegmentPolynomials

# u = 1.3 - 8 (t - 1/2)^2 clipped to [0, 1]: at its bounds where |t - 1/2| = sqrt(0.3/8), sqrt(1.3/8)
UPPER, LOWER = math.sqrt(0.3 / 8), math.sqrt(1.3 / 8)
KINKS = [0.5 - LOWER, 0.5 - UPPER, 0.5 + UPPER, 0.5 + LOWER]


def _control():
    t = np.array([0.1, 0.3, 0.5, 0.7, 0.9])
    return SegmentPolynomials(t, (1.3 - 8 * (t - 0.5) ** 2)[:, None], [(0.0, 1.0)], segments=[0.0, 1.0])


def _exact_integral(t1: float) -> float:
    """The integral of the clipped control from 0 to t1, arc by arc."""
    p = np.polynomial.Polynomial([1.3 - 2.0, 8.0, -8.0])        # 1.3 - 8 (t - 1/2)^2
    arcs = [(0.0, KINKS[0], 0.0), (KINKS[0], KINKS[1], None), (KINKS[1], KINKS[2], 1.0),
            (KINKS[2], KINKS[3], None), (KINKS[3], 1.0, 0.0)]
    total = 0.0
    for a, b, value in arcs:
        b = min(b, t1)
        if b <= a:
            break
        total += value * (b - a) if value is not None else float(p.integ()(b) - p.integ()(a))
    return total


def test_the_kinks_of_a_clipped_polynomial_are_found_where_it_meets_its_bounds():
    uf = _control()
    found = uf.kinks(0.0, 1.0)
    assert len(found) == 4 and np.max(np.abs(np.array(found) - KINKS)) < 1e-12, found
    assert uf.kinks(0.45, 0.55) == []            # inside the upper arc: no kink
    assert len(uf.kinks(0.0, 0.2)) == 1


def test_integrating_the_clipped_control_meets_the_integrator_tolerance():
    uf = _control()
    u_of = uf.piece(0.5)
    t_eval = np.linspace(0.0, 1.0, 11)

    def fun(t, y):
        return np.array([u_of(t)[0]])

    rtol = 1e-10
    sol = dop853_split(fun, 0.0, 1.0, np.zeros(1), t_eval, rtol, np.array([rtol]), uf.kinks(0.0, 1.0))
    exact = np.array([_exact_integral(t) for t in t_eval])
    assert sol.success and sol.y.shape == (1, 11)
    assert np.max(np.abs(sol.y[0] - exact)) < 1e-12, np.abs(sol.y[0] - exact)
    # without the cuts the kinks sit inside steps, and the error is several times rtol (8.7x here)
    plain = dop853_split(fun, 0.0, 1.0, np.zeros(1), t_eval, rtol, np.array([rtol]), [])
    assert np.max(np.abs(plain.y[0] - exact)) > 5 * rtol


def test_the_straight_line_control_is_the_reference_evaluation_bit_for_bit():
    """``piece(t)`` (a template compiled per shape, numbers bound per segment) against
    ``__call__`` (NumPy Horner and clip) on random segment polynomials, bounds finite and not."""
    rng = np.random.default_rng(3)
    for degree in (1, 3, 5):
        segments = np.linspace(0.0, 2.0, 5)
        t = np.concatenate([a + (b - a) * np.sort(rng.uniform(0.05, 0.95, degree + 1))
                            for a, b in zip(segments[:-1], segments[1:])])
        U = rng.normal(size=(len(t), 3)) * 2
        uf = SegmentPolynomials(t, U, [(-1.0, 1.0), (-math.inf, 0.5), (-math.inf, math.inf)], segments=segments)
        for s in rng.uniform(0.0, 2.0, 200):
            assert uf.piece(s)(s) == uf(s).tolist()
