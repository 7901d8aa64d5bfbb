"""Derivatives and common subexpressions of SymPy expressions, by SymEngine where it can.

Why: SymPy builds every intermediate expression through its assumptions system. On seed
0's 6-DOF dynamics (12 outputs, 20 symbols, 85 first and 248 second derivatives) the
derivatives take 1.6 s of CPU in SymPy against 0.012 s in SymEngine plus 0.15 s to bring
them back to SymPy, and the common-subexpression elimination of the second derivatives
0.52 s against 0.17 s. A run on a cold cache pays these once per family of expressions
(ocdsl/cache.py); the printing into NumPy source stays SymPy's.

SymEngine is used only for expressions made of numbers, symbols, +, *, ** and the
elementary functions both libraries differentiate alike (``_ENGINE``); anything else
(ocdsl's own functions such as a table's interpolant or ``safe_exp``, Abs, Piecewise,
dummies, two symbols of one name) goes to SymPy as before, as does everything when
SymEngine is not installed. Results are SymPy expressions in the caller's own symbols
(assumptions kept), equal to SymPy's as functions (tests/test_engine.py), not always in
the same printed form.
"""
from __future__ import annotations

import re
from typing import Sequence

import sympy as sp

# SymPy function classes SymEngine differentiates to the same functions
_ENGINE = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
           "asinh", "acosh", "atanh", "exp", "log"}
_ATOMS = (sp.Symbol, sp.Integer, sp.Rational, sp.Float, sp.core.numbers.Pi, sp.core.numbers.Exp1)
_OPS = (sp.Add, sp.Mul, sp.Pow)


def _engine_can(exprs: Sequence[sp.Expr]) -> bool:
    names: dict[str, sp.Symbol] = {}
    for e in exprs:
        for node in sp.preorder_traversal(e):
            if isinstance(node, sp.Dummy):
                return False
            if isinstance(node, sp.Symbol):
                if names.setdefault(node.name, node) != node:
                    return False        # two symbols of one name would become one
            elif isinstance(node, sp.Function):
                if type(node).__name__ not in _ENGINE or (type(node).__name__ == "log" and len(node.args) != 1):
                    return False
            elif not isinstance(node, _ATOMS + _OPS):
                return False
    return True


def engine_id() -> str:
    """What the derivatives depend on besides the expressions, for the disk cache's keys:
    this module's source and the SymEngine release used, read without importing it (loading
    its library costs 0.1-0.25 s, which a warm run, needing no derivative, never pays)."""
    import importlib.util
    from pathlib import Path

    release = "none"
    try:
        spec = importlib.util.find_spec("symengine")
        for folder in (spec.submodule_search_locations or []) if spec else []:
            version = Path(folder) / "_version.py"
            if version.is_file():
                release = version.read_text()
    except (ImportError, ValueError, OSError):
        pass
    return f"{Path(__file__).read_text()}|symengine {release}"


def _engine():
    try:
        import symengine
    except ImportError:      # an optional speed-up: SymPy alone gives the same derivatives
        return None
    return symengine


def derivative_table(exprs: Sequence, syms: Sequence[sp.Symbol]):
    """Nonzero first derivatives [(output, a)] with their expressions, and nonzero
    lower-triangle second derivatives [(output, a, b)] (b <= a) with theirs. Only the symbols
    an expression contains are tried (the others give 0)."""
    exprs = [sp.sympify(e) for e in exprs]
    se = _engine()
    if se is not None and _engine_can(exprs + list(syms)):
        jac, jexprs, hess, hexprs = _table_engine(se, exprs, list(syms))
        ours = _ours(se, exprs + list(syms))
        return (jac, [sp.sympify(d).xreplace(ours) for d in jexprs],
                hess, [sp.sympify(d).xreplace(ours) for d in hexprs])
    return _table(exprs, list(syms))


def _table(exprs, syms):
    """derivative_table's rows for expressions and symbols of one library, SymPy's or
    SymEngine's (both spell ``e.diff(s)``, ``free_symbols`` and ``== 0`` alike)."""
    pos = {s: i for i, s in enumerate(syms)}
    jac, jexprs, hess, hexprs = [], [], [], []
    for o, e in enumerate(exprs):
        for a in sorted(pos[s] for s in e.free_symbols if s in pos):
            d = e.diff(syms[a])
            if d == 0:
                continue
            jac.append((o, a))
            jexprs.append(d)
            for b in sorted(pos[s] for s in d.free_symbols if s in pos and pos[s] <= a):
                d2 = d.diff(syms[b])
                if d2 != 0:
                    hess.append((o, a, b))
                    hexprs.append(d2)
    return jac, jexprs, hess, hexprs


def _table_engine(se, exprs, syms):
    """derivative_table's rows, the expressions as SymEngine's."""
    return _table([se.sympify(e) for e in exprs], [se.sympify(s) for s in syms])


def _ours(se, originals) -> dict:
    """SymEngine's plain symbols, as SymPy's, -> the callers' (SymEngine's carry no assumptions)."""
    symbols = set().union(*(sp.sympify(e).free_symbols for e in originals)) if originals else set()
    return {sp.sympify(se.sympify(s)): s for s in symbols}


def _cse_engine(se, items, ours: dict, prefix: str):
    """SymEngine's CSE of SymEngine ``items``, as SymPy (replacements, reduced), the
    replacements named prefix0, ...: only these pieces are converted back, never the whole
    expressions (converting back costs more than the CSE)."""
    reps, red = se.cse(list(items))
    names = {**ours, **{sp.sympify(r): sp.Symbol(f"{prefix}{i}") for i, (r, _) in enumerate(reps)}}
    return ([(names[sp.sympify(r)], sp.sympify(v).xreplace(names)) for r, v in reps],
            [sp.sympify(v).xreplace(names) for v in red])


def _clashes(symbols) -> bool:
    """SymEngine names its replacements x0, x1, ...: a symbol of that name would be confused."""
    return any(re.fullmatch(r"x\d+", s.name) for s in symbols)


def derivatives_cse(exprs: Sequence, syms: Sequence[sp.Symbol], prefix: str = "_c"):
    """``derivative_table``'s sparsity (jac, hess) and, for the values, the first and the
    second derivatives, each list's ``cse`` ({"values", "first", "second"}; an empty list has
    no entry): what generated code is printed from."""
    exprs = [sp.sympify(e) for e in exprs]
    se = _engine()
    if se is None or not _engine_can(exprs + list(syms)) or _clashes(syms):
        jac, jexprs, hess, hexprs = derivative_table(exprs, syms)
        lists = {"values": exprs, "first": jexprs, "second": hexprs}
        return jac, hess, {name: cse(es, prefix) for name, es in lists.items() if es}
    jac, jexprs, hess, hexprs = _table_engine(se, exprs, list(syms))
    ours = _ours(se, exprs + list(syms))
    lists = {"values": [se.sympify(e) for e in exprs], "first": jexprs, "second": hexprs}
    return jac, hess, {name: _cse_engine(se, es, ours, prefix) for name, es in lists.items() if es}


def cse(exprs: Sequence, prefix: str = "_c"):
    """``sympy.cse(exprs)`` with the replacements named prefix0, prefix1, ...: (replacements
    [(symbol, expression)], reduced expressions), SymPy expressions."""
    exprs = [sp.sympify(e) for e in exprs]
    se = _engine() if exprs else None
    if se is None or not _engine_can(exprs) or _clashes(set().union(*(e.free_symbols for e in exprs))):
        return sp.cse(exprs, symbols=sp.numbered_symbols(prefix))
    return _cse_engine(se, [se.sympify(e) for e in exprs], _ours(se, exprs), prefix)


def jacobian(exprs: Sequence, syms: Sequence[sp.Symbol]) -> sp.Matrix:
    """d exprs[i] / d syms[j] as a len(exprs) x len(syms) matrix (also for no symbols)."""
    exprs = [sp.sympify(e) for e in exprs]
    if not syms:
        return sp.zeros(len(exprs), 0)
    se = _engine()
    if se is None or not _engine_can(exprs + list(syms)):
        return sp.Matrix(exprs).jacobian(list(syms))
    ours = _ours(se, exprs + list(syms))
    S = [se.sympify(s) for s in syms]
    return sp.Matrix([[sp.sympify(se.sympify(e).diff(s)).xreplace(ours) for s in S] for e in exprs])
