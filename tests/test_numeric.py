"""ocdsl/symbolic/numeric.py: families of generated functions through the disk cache.

A second ``family`` call with the same key execs the stored source without deriving again
(``make`` is not called), gives the same numbers as ``sympy.lambdify`` at the same
arguments, a changed key misses, and expressions with a function the printers do not know
(a table's ramp with its own implementation) fall back to ``sympy.lambdify`` uncached.
"""
import numpy as np
import pytest
import sympy as sp

from ocdsl import cache
from ocdsl.symbolic import numeric
from ocdsl.symbolic.tables import r2


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_DIR, str(d))
    monkeypatch.delenv(cache.ENV_OFF, raising=False)
    return d


t, x, lam = sp.symbols("t x lambda", real=True)      # "lambda": a Python keyword as a name
F = [sp.sin(x) * sp.exp(-t) + lam ** 2, sp.sqrt(1 + x ** 2) * lam, sp.Integer(3), sp.Max(x, 0.5)]


def _make(calls, exprs=F):
    def make():
        calls.append(1)
        J = sp.Matrix(exprs).jacobian([x, lam])
        return {"f": (exprs, "numpy"), "J": (list(J), "numpy"), "point": (exprs, "math")}
    return make


def test_second_call_reads_the_cache_and_agrees_with_lambdify(cache_dir):
    calls = []
    args = [t, x, lam]
    first = numeric.family(args, ("test", *F), _make(calls))
    again = numeric.family(args, ("test", *F), _make(calls))
    assert calls == [1]
    assert list((cache_dir / "numeric").glob("*.json"))
    T, X, L = np.linspace(0, 1, 5), np.linspace(-1, 2, 5), np.linspace(0.3, 0.9, 5)
    ref = sp.lambdify(args, F, "numpy", cse=True)(T, X, L)
    for fam in (first, again):
        got = fam["f"](T, X, L)
        for a, b in zip(got, ref):
            np.testing.assert_array_equal(np.broadcast_to(a, T.shape), np.broadcast_to(b, T.shape))
        assert fam["point"](0.2, -0.4, 0.7) == pytest.approx(
            sp.lambdify(args, F, "math", cse=True)(0.2, -0.4, 0.7), rel=1e-15)
    J = sp.lambdify(args, list(sp.Matrix(F).jacobian([x, lam])), "numpy")(T, X, L)
    for a, b in zip(again["J"](T, X, L), J):
        np.testing.assert_allclose(np.broadcast_to(a, T.shape), np.broadcast_to(b, T.shape), rtol=1e-15)


def test_changed_key_misses(cache_dir):
    calls = []
    numeric.family([t, x, lam], ("test", *F), _make(calls))
    G = F[:-1] + [sp.Max(x, 0.25)]
    fam = numeric.family([t, x, lam], ("test", *G), _make(calls, G))
    assert calls == [1, 1]
    assert fam["f"](0.0, 0.3, 1.0)[3] == 0.3


def test_unknown_function_falls_back_uncached(cache_dir):
    calls = []
    H = [r2(x - 1) + lam]
    fam = numeric.family([t, x, lam], ("test", *H), lambda: (calls.append(1), {"f": (H, "numpy")})[1])
    assert fam["f"](0.0, np.array([0.0, 3.0]), 1.0)[0].tolist() == [1.0, 5.0]
    numeric.family([t, x, lam], ("test", *H), lambda: (calls.append(1), {"f": (H, "numpy")})[1])
    assert calls == [1, 1]          # nothing stored: derived again
    assert not (cache_dir / "numeric").exists() or not list((cache_dir / "numeric").glob("*.json"))


def test_cache_off_derives_every_time(cache_dir, monkeypatch):
    monkeypatch.setenv(cache.ENV_OFF, "1")
    calls = []
    numeric.family([t, x, lam], ("test", *F), _make(calls))
    numeric.family([t, x, lam], ("test", *F), _make(calls))
    assert calls == [1, 1]


@pytest.mark.ipopt
def test_a_second_run_prints_nothing_for_certificate_and_verification(configs, cache_dir, monkeypatch):
    """Two solves of a freshly compiled file: the second one's certificate and verification
    functions all come from the disk cache (nothing printed), and its records are the first's."""
    import ocdsl

    printed = []
    real = numeric.source
    monkeypatch.setattr(numeric, "source", lambda *a, **k: (printed.append(1), real(*a, **k))[1])
    first = ocdsl.load(configs / "brachistochrone.yaml").solve()
    assert printed and first.certificate.get("passed") is True
    n = len(printed)
    second = ocdsl.load(configs / "brachistochrone.yaml").solve()
    assert len(printed) == n
    assert second.certificate == first.certificate

    def checks(v):
        return {k: x for k, x in v.items() if "time" not in k}

    assert first.verification["status"] == "verified"
    assert checks(second.verification) == checks(first.verification)
