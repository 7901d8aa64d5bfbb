"""The certificate's fast paths (``certificate.FAST``, issue 11) against the reference paths.

- ``global_shooting``: the global re-integration by multiple shooting over all pieces at
  once, instead of one SciPy ``solve_ivp`` per piece in sequence (kept as the reference,
  ``_reintegrate_batched(..., "sequential")``);
- ``batched_expm``: the switch-resolution exponentials in one batch instead of
  ``scipy.linalg.expm`` per interval.

Same verdicts and the same numbers: every check's pass/fail and every number but the
global errors identical to rounding; the global errors to a tolerance far below what they
measure (they differ only by the integrator's own noise, see ``_global_shooting``).
"""
import math

import numpy as np
import pytest
from scipy.linalg import expm

import ocdsl
from ocdsl.solve import certificate as C
from ocdsl.solve.certify import certify_result


def _flat(d, prefix=""):
    """Leaves of a nested dict/list as {path: value}."""
    out = {}
    if isinstance(d, dict):
        for k, v in d.items():
            out.update(_flat(v, f"{prefix}/{k}"))
    elif isinstance(d, (list, tuple)):
        for i, v in enumerate(d):
            out.update(_flat(v, f"{prefix}/{i}"))
    else:
        out[prefix] = d
    return out


def _certify(problem, res, fast: bool, monkeypatch):
    monkeypatch.setitem(C.FAST, "global_shooting", fast)
    monkeypatch.setitem(C.FAST, "batched_expm", fast)
    return certify_result(problem, res)


def _same(ref: dict, new: dict):
    a, b = _flat(ref), _flat(new)
    assert a.keys() == b.keys()
    for k, va in a.items():
        vb = b[k]
        if isinstance(va, float) and isinstance(vb, float):
            if "global" in k:      # global re-integration error: integrator noise apart
                assert vb == pytest.approx(va, rel=1e-5, abs=1e-9), k
            else:                  # everything else (switch allowances via expm): rounding
                assert vb == pytest.approx(va, rel=1e-12, abs=1e-300), k
        else:
            assert va == vb, k


@pytest.mark.ipopt
@pytest.mark.parametrize("name", ["moon_landing", "goddard", "double_integrator"])
def test_fast_certificate_gives_the_reference_verdicts_and_numbers(configs, name, monkeypatch):
    """moon landing (bang-bang, smooth states), Goddard (a chattering singular arc: the
    shooting stops at the integrator's noise floor), double integrator (switch intervals:
    the batched expm)."""
    loaded = ocdsl.load(configs / f"{name}.yaml")
    res = loaded.solve()
    assert res.status == "optimal"
    ref = _certify(loaded.problem, res, False, monkeypatch)
    new = _certify(loaded.problem, res, True, monkeypatch)
    assert ref["passed"] == new["passed"] and ref["failed"] == new["failed"]
    _same(ref, new)


def test_shooting_matches_the_sequential_pass_on_a_nonlinear_chain():
    """Pendulum-like nonlinear dynamics, perturbed node states (large defects), segment
    boundaries between nodes (LG-like chains): the shooting's ends equal the sequential
    solve_ivp's to the integrator's accuracy, and with no iterations allowed it falls back
    to the sequential pass exactly."""
    import sympy as sp

    from ocdsl.symbolic.model import Model, sym

    th, om, u = sym("th"), sym("om"), sym("u")
    model = Model("pend", (th, om), (u,), {th: om, om: -sp.sin(th) + u})
    K, p, T = 12, 3, 6.0
    edges = np.linspace(0, T, K + 1)
    tau = (np.polynomial.legendre.leggauss(p)[0] + 1) / 2
    t = np.concatenate([[0.0]] + [a + (b - a) * tau for a, b in zip(edges[:-1], edges[1:])] + [[T]])
    U = 0.3 * np.cos(t)[:, None]
    X = np.column_stack([np.sin(0.8 * t), 0.8 * np.cos(0.8 * t)]) + 1e-3 * np.sin(5 * t)[:, None]
    num = C._Numeric(model, {}, 0)
    uf = C._ControlInterp(t, U, [(-1.0, 1.0)], edges)
    breaks = np.array(sorted(set(t.tolist()) | {float(s) for s in edges if 0 < s < T}))
    scale = np.ptp(X, axis=0)
    tol = C.Tolerances()
    lo, go = C._reintegrate_pieces(num, uf, t, X, breaks, scale, tol)
    ls, gs = C._reintegrate_batched(num, uf, t, X, breaks, scale, tol, "sequential")
    lf, gf = C._reintegrate_batched(num, uf, t, X, breaks, scale, tol, "shooting")
    assert go.max() > 1e-2                                # a real global drift to find
    assert np.array_equal(gs, go)                         # the reference is the old pass
    assert np.array_equal(lf, ls)                         # the local pass is untouched
    assert np.allclose(gf, go, rtol=1e-6, atol=1e-8)
    old = dict(C.SHOOTING)
    try:
        C.SHOOTING["max_iterations"] = 0                  # no convergence: the fallback
        _, gz = C._reintegrate_batched(num, uf, t, X, breaks, scale, tol, "shooting")
    finally:
        C.SHOOTING.update(old)
    assert np.array_equal(gz, go)


def test_batched_expm_matches_scipy():
    rng = np.random.default_rng(3)
    M = rng.normal(size=(50, 6, 6)) * np.logspace(-6, 2.5, 50)[:, None, None]
    E = C._expm_batch(M)
    ref = np.array([expm(m) for m in M])
    assert np.allclose(E, ref, rtol=1e-11, atol=1e-13 * np.abs(ref).max())
    assert math.isclose(float(C._expm_batch(np.zeros((1, 2, 2)))[0, 0, 0]), 1.0)
