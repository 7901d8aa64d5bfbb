"""The compiled DOP853 layer: accuracy, dense output/events, batches, Sundman form.

Cold compile of one model's kernel: ~17-30 s (see ocdsl/simulate/__init__.py); from
Numba's disk cache: ~1 s.
"""
import math

import numpy as np
import pytest

from ocdsl.simulate import (ControlLayout, Event, compile_model, evaluate_controls, final_states,
                            scipy_final_state, simulate, table_coefficients)
from ocdsl.simulate.sundman import sundman
from ocdsl.symbolic.model import Model, syms
from ocdsl.symbolic.registry import build_model


@pytest.fixture(scope="module")
def osc():
    # forced oscillator x'' = -w^2 x + u, plus a clock-free control channel
    x, v, w, u = *syms("x v"), *syms("w u")
    return compile_model(Model("osc", (x, v), (u,), {x: v, v: -w**2 * x + u}, {w: 2.0}))


def test_accuracy_against_exact(osc):
    tr = simulate(osc, [1.0, 0.0], 10.0, rtol=1e-12, atol=1e-14)
    assert tr.status == 0
    assert abs(tr.t[-1] - 10.0) < 1e-15
    assert abs(tr.final[0] - math.cos(20.0)) < 1e-10
    assert abs(tr.final[1] + 2 * math.sin(20.0)) < 1e-10
    loose = simulate(osc, [1.0, 0.0], 10.0, rtol=1e-6, atol=1e-8)
    assert loose.n_steps < tr.n_steps  # the step size adapts to the tolerance


def test_dense_output_and_events(osc):
    tr = simulate(osc, [1.0, 0.0], 4.0, rtol=1e-12, atol=1e-14, n_dense=5,
                  events=[Event("x", 0.0, -1, False), Event("v", 0.0, +1, True)])
    t = tr.t
    assert np.all(np.diff(t) > 0)
    assert np.max(np.abs(tr["x"] - np.cos(2 * t))) < 1e-9  # dense points are accurate too
    down = [s for i, s, y in tr.events if i == 0]
    assert abs(down[0] - math.pi / 4) < 1e-11          # x = cos 2t falls through 0 at pi/4
    # v = -2 sin 2t crosses 0 upward at t = pi/2: terminal, run ends there exactly
    assert tr.status == 2
    assert abs(tr.t[-1] - math.pi / 2) < 1e-10
    assert abs(tr.final[0] + 1.0) < 1e-10


def test_series_and_table_controls(osc):
    lay = ControlLayout(("fourier",), (2,))
    c = np.array([0.6, 0.1, -0.2, 0.05, 0.3])
    t = np.linspace(0, 3, 7)
    u = evaluate_controls(lay, c, t, 3.0)[:, 0]
    ref = 0.3 + 0.1 * np.cos(np.pi * t / 3) - 0.2 * np.cos(2 * np.pi * t / 3) \
        + 0.05 * np.sin(np.pi * t / 3) + 0.3 * np.sin(2 * np.pi * t / 3)
    assert np.allclose(u, ref, atol=1e-15)
    # the compiled kernel uses the same series: compare with SciPy on the same RHS
    y_mine = simulate(osc, [0.0, 0.0], 3.0, None, lay, c, rtol=1e-12, atol=1e-14).final
    y_ref, _ = scipy_final_state(osc, [0.0, 0.0], 3.0, osc.default_p, lay, c, rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(y_mine - y_ref)) < 1e-10
    poly = ControlLayout(("polynomial",), (2,))
    assert np.allclose(evaluate_controls(poly, np.array([1.0, 2.0, 3.0]), [1.5], 3.0), 1 + 1 + 0.75)
    tab = ControlLayout.table(1, 3)
    cd = table_coefficients(np.array([0.0, 1.0, 3.0]), np.array([0.0, 2.0, 0.0]))
    y_tab = simulate(osc, [0.0, 0.0], 3.0, None, tab, cd, rtol=1e-12, atol=1e-14).final
    y_tref, _ = scipy_final_state(osc, [0.0, 0.0], 3.0, osc.default_p, tab, cd, rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(y_tab - y_tref)) < 1e-8


def test_batch_equals_single_runs(osc):
    rng = np.random.default_rng(3)
    lay = ControlLayout(("fourier",), (1,))
    CD = rng.normal(size=(6, 3))
    T = rng.uniform(1, 4, 6)
    P = np.column_stack([rng.uniform(1, 3, 6)])
    Yf, st, steps = final_states(osc, [1.0, 0.0], T, P, lay, CD, rtol=1e-11, atol=1e-13)
    for b in range(6):
        one = simulate(osc, [1.0, 0.0], T[b], P[b], lay, CD[b], rtol=1e-11, atol=1e-13, record=False)
        assert np.array_equal(one.final, Yf[b])
    assert np.all(st == 0)
    # the rows split over threads give the same bits, row for row
    threaded = final_states(osc, [1.0, 0.0], T, P, lay, CD, rtol=1e-11, atol=1e-13, parallel=True)
    for a, b in zip(threaded, (Yf, st, steps)):
        assert np.array_equal(a, b)


def test_one_compilation_per_entry_point(osc):
    """unseen35 F11: a new model's first parametric run took 38 s, 29 s of it compiling the
    same kernels again for read-only arrays, literal arguments and a parallel batch. Whatever
    the callers pass (read-only broadcasts, views, serial or threaded batches, single runs),
    each entry point has one signature."""
    lay = ControlLayout(("fourier",), (1,))
    T = np.array([1.0, 2.0, 3.0])
    CD = np.zeros((3, 3))
    P = np.broadcast_to(osc.default_p, (3, 1))           # read-only
    y0 = np.broadcast_to(np.array([1.0, 0.0]), (3, 2))   # read-only
    final_states(osc, y0, T, P, lay, CD)
    final_states(osc, y0[0], T, P, lay, CD, parallel=True)
    simulate(osc, y0[0], 1.0, P[0], lay, CD[0], record=False)
    simulate(osc, [1.0, 0.0], 1.0, None, lay, CD[0], n_dense=3)
    assert len(osc.module.integrate.signatures) == 1
    assert len(osc.module.final_batch.signatures) == 1


def test_sundman_form_matches_time_form():
    base = build_model("cr3bp_polar", {})
    reg = compile_model(sundman(base, base.symbol("R_SE"), 1.5))
    plain = compile_model(base)
    assert reg.clock == reg.state_names.index("time")
    y0 = np.array([0.017632822153718267, 2 * math.pi - 2, 0, 0, 556.2661398665742, 0, 1.0])
    lay = ControlLayout(("fourier", "fourier"), (1, 1))
    cd = np.array([0.2, 0.1, -0.1, math.pi, 0.05, 0.0])
    a = simulate(plain, y0, 0.5, plain.params({"thrust": 10}), lay, cd, rtol=1e-12, atol=1e-14)
    b = simulate(reg, np.append(y0, 0.0), 0.5, reg.params({"thrust": 10}), lay, cd, rtol=1e-12, atol=1e-14)
    assert b.status == 1 and abs(b.final[-1] - 0.5) < 1e-14
    assert np.max(np.abs(a.final - b.final[:-1]) / np.maximum(1, np.abs(a.final))) < 1e-8
    assert b.n_steps < a.n_steps  # perigee passages no longer dominate the step count
