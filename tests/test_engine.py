"""ocdsl.symbolic.engine: derivatives and common subexpressions by SymEngine where it can,
equal as functions to SymPy's own, and SymPy's wherever SymEngine cannot stand in."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ocdsl.symbolic import engine
from ocdsl.symbolic.numbers import safe_exp

pytest.importorskip("symengine")

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


def _sympy_table(exprs, syms):
    """The reference: every derivative by SymPy alone (the module's own path without SymEngine)."""
    real = engine._engine
    engine._engine = lambda: None
    try:
        return engine.derivative_table(exprs, syms)
    finally:
        engine._engine = real


def _values(exprs, syms, points):
    f = sp.lambdify(syms, list(exprs), "numpy")
    return np.array([[complex(v) for v in np.broadcast_arrays(*f(*p))] for p in points])


def _agree(a, b, syms, rng, n=5, lo=0.3, hi=1.7):
    points = rng.uniform(lo, hi, size=(n, len(syms)))
    va, vb = _values(a, syms, points), _values(b, syms, points)
    ok = np.isfinite(va) & np.isfinite(vb)
    assert ok.any()
    np.testing.assert_allclose(va[ok], vb[ok], rtol=1e-11, atol=1e-11)


def _used_engine(monkeypatch):
    """Count the calls that went through SymEngine."""
    calls = []
    real = engine._table_engine

    def spy(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(engine, "_table_engine", spy)
    return calls


def _model_rows():
    from ocdsl.spec.compile import load

    rows = []
    for name in ("seed0_rendezvous", "goddard", "moon_landing", "lit_orbit_raising", "lit_free_flying_robot",
                 "lit_delta_iii", "brachistochrone"):
        path = CONFIGS / f"{name}.yaml"
        if not path.exists():
            continue
        file = load(path)
        for ph in file.problem.phases:
            rhs = [sp.sympify(e) for e in ph.rhs()]
            syms = sorted(set().union(*(e.free_symbols for e in rhs)), key=str)
            rows.append((name, rhs, syms))
    return rows


@pytest.mark.parametrize("name,rhs,syms", _model_rows(), ids=lambda v: v if isinstance(v, str) else "")
def test_derivatives_of_published_models_equal_sympys(name, rhs, syms, monkeypatch):
    calls = _used_engine(monkeypatch)
    jac, jexprs, hess, hexprs = engine.derivative_table(rhs, syms)
    ref = _sympy_table(rhs, syms)
    assert (jac, hess) == (ref[0], ref[2])          # the same sparsity
    rng = np.random.default_rng(1)
    _agree(jexprs, ref[1], syms, rng)
    _agree(hexprs, ref[3], syms, rng)
    if engine._engine_can(rhs + syms):
        assert calls, f"{name}: SymEngine was not used"
        # the caller's symbols come back, with their assumptions
        assert set().union(*(e.free_symbols for e in jexprs)) <= set(syms)


def test_functions_symengine_cannot_take_stay_with_sympy(monkeypatch):
    calls = _used_engine(monkeypatch)
    x, y = sp.symbols("x y", real=True)
    exprs = [safe_exp(x * y), sp.Abs(x) * y, sp.Piecewise((x, x > 0), (y, True)), sp.Function("g")(x)]
    for e in exprs:
        got = engine.derivative_table([e], [x, y])
        assert got[1] == _sympy_table([e], [x, y])[1]      # SymPy's own expressions
    assert not calls
    d = sp.Dummy("d")
    assert not engine._engine_can([x + d])
    assert not engine._engine_can([sp.Symbol("x") + x])       # two symbols named x


def test_jacobian_keeps_symbols_and_shapes():
    x, u = sp.symbols("x u", real=True)
    t = sp.Symbol("t", real=True)
    J = engine.jacobian(sp.Matrix([x * sp.sin(u), u ** 2 * t]), [x, u])
    assert J.shape == (2, 2)
    assert J[0, 1] == x * sp.cos(u) and J[1, 1] == 2 * u * t
    assert all(s.is_real for s in J.free_symbols)
    assert engine.jacobian([x, u], []).shape == (2, 0)
    assert engine.jacobian(sp.Matrix([x * t]), [t])[0, 0] == x


def test_cse_rebuilds_its_expressions_and_avoids_symengines_names():
    x, y = sp.symbols("x y", real=True)
    exprs = [sp.sin(x * y) ** 2 + sp.cos(x * y), sp.exp(sp.sin(x * y)) / (1 + x ** 2), sp.Integer(3)]
    reps, red = engine.cse(exprs)
    assert reps and all(s.name.startswith("_c") for s, _ in reps)
    subs = {}
    for s, v in reps:
        subs[s] = v.xreplace(subs)
    rebuilt = [r.xreplace(subs) for r in red]
    assert [sp.simplify(a - b) for a, b in zip(rebuilt, exprs)] == [0, 0, 0]
    x0 = sp.Symbol("x0", real=True)        # SymEngine's own replacement names: SymPy's cse
    reps, red = engine.cse([sp.sin(x0 * y) + sp.cos(x0 * y)])
    assert reps and red[0].free_symbols <= {s for s, _ in reps} | {x0, y}


_leaves = st.sampled_from(["x", "y", "z", "2", "3", "sp.Rational(1, 3)", "0.7", "sp.pi"])


def _tree(children):
    binary = st.tuples(st.sampled_from(["+", "-", "*", "/"]), children, children).map(
        lambda t: f"({t[1]} {t[0]} {t[2]})")
    power = st.tuples(children, st.sampled_from(["2", "3", "sp.Rational(1, 2)", "-1"])).map(
        lambda t: f"({t[0]})**{t[1]}")
    unary = st.tuples(st.sampled_from(["sin", "cos", "exp", "atan", "tanh", "asinh"]), children).map(
        lambda t: f"sp.{t[0]}({t[1]})")
    logs = children.map(lambda c: f"sp.log(1 + ({c})**2)")
    angle = st.tuples(children, children).map(lambda t: f"sp.atan2({t[0]}, 1 + ({t[1]})**2)")
    return binary | power | unary | logs | angle


@settings(max_examples=60, deadline=None)
@given(st.recursive(_leaves, _tree, max_leaves=10))
def test_random_expressions_differentiate_as_in_sympy(text):
    x, y, z = sp.symbols("x y z", real=True)
    try:
        e = sp.sympify(eval(text, {"sp": sp, "x": x, "y": y, "z": z}))
    except (ZeroDivisionError, OverflowError, ValueError, TypeError):
        assume(False)       # the constant part alone is undefined, as in (2 - 2)**-1
    # SymPy writes sqrt(x**2) of a real x as Abs(x): not smooth, and its second derivative a
    # DiracDelta no numeric module evaluates; such expressions stay with SymPy anyway
    assume(not e.has(sp.Abs, sp.sign))
    syms = [x, y, z]
    got = engine.derivative_table([e], syms)
    ref = _sympy_table([e], syms)
    rng = np.random.default_rng(0)
    points = rng.uniform(0.3, 1.7, size=(4, 3))
    # entry by entry, an entry one side found to vanish counted as 0
    for mine, theirs in ((dict(zip(got[0], got[1])), dict(zip(ref[0], ref[1]))),
                         (dict(zip(got[2], got[3])), dict(zip(ref[2], ref[3])))):
        for key in set(mine) | set(theirs):
            fm = sp.lambdify(syms, mine.get(key, sp.Integer(0)), "math")
            ft = sp.lambdify(syms, theirs.get(key, sp.Integer(0)), "math")
            for p in points:
                try:
                    a, b = complex(fm(*p)), complex(ft(*p))
                except (ZeroDivisionError, OverflowError, ValueError):
                    continue
                if math.isfinite(abs(a)) and math.isfinite(abs(b)):
                    assert abs(a - b) <= 1e-9 * (1 + abs(b)), (text, key)


def _rebuilt(part):
    reps, red = part
    subs = {}
    for s, v in reps:
        subs[s] = v.xreplace(subs)
    return [r.xreplace(subs) for r in red]


@pytest.mark.parametrize("name,rhs,syms", [r for r in _model_rows() if r[0] in ("seed0_rendezvous", "goddard")],
                         ids=lambda v: v if isinstance(v, str) else "")
def test_generated_codes_pieces_rebuild_sympys_derivatives(name, rhs, syms, monkeypatch):
    """What the direct NLP prints from (each list's CSE) is SymPy's values and derivatives."""
    calls = _used_engine(monkeypatch)
    jac, hess, parts = engine.derivatives_cse(rhs, syms)
    ref = _sympy_table(rhs, syms)
    assert calls and (jac, hess) == (ref[0], ref[2])
    assert all(s.name.startswith("_c") for part in parts.values() for s, _ in part[0])
    rng = np.random.default_rng(2)
    _agree(_rebuilt(parts["values"]), rhs, syms, rng)
    _agree(_rebuilt(parts["first"]), ref[1], syms, rng)
    _agree(_rebuilt(parts["second"]), ref[3], syms, rng)
