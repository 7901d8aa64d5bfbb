"""Generated NumPy functions of the direct NLP: which functions have a smooth NumPy form,
their first and second derivatives (``symbolic.engine``), the NumPy source (common subexpressions eliminated,
rows written in place), its disk cache, and the families of node functions built from them."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ...symbolic.engine import derivatives_cse, engine_id

INF = 1e20
# functions whose NumPy form and SymPy derivatives agree with the ASL's everywhere they are
# smooth; anything else (Abs, Min/Max, Piecewise, sign...) stays on the PyNumero route. The
# tables' truncated powers r2, r3 (max(z, 0)**p, ocdsl/symbolic/tables.py: a C2 spline's r3
# has derivatives 3 r2 and 6 r1, continuous) and safe_exp (exp kept whole,
# ocdsl/symbolic/numbers.py) are printed by _Printer below; r1 itself is not taken (its
# second derivative is a Dirac delta)
_SMOOTH = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
           "asinh", "acosh", "atanh", "exp", "log", "sqrt", "r2", "r3", "safe_exp"}


class Unsupported(Exception):
    pass


def _check_smooth(exprs, what: str) -> None:
    for e in exprs:
        for f in sp.sympify(e).atoms(sp.Function):
            if type(f).__name__ not in _SMOOTH:
                raise Unsupported(f"{what} uses {type(f).__name__}")
        if sp.sympify(e).has(sp.Piecewise):
            raise Unsupported(f"{what} is piecewise")


def _numpy_source(args, reps, red) -> str:
    """NumPy source of ``f(*args, _out)`` writing the expressions (``reps``, ``red``: their
    common-subexpression elimination) into the rows of ``_out``, as text that can be cached.
    Rows are assigned in place: a constant or a node array fills its row by broadcasting,
    without a per-entry ``broadcast_to`` and ``stack`` (which took half of a Hessian
    evaluation's time on seed 0)."""
    pr = _printer()
    # an objective of no variable (`minimize 0`) has no arguments but the output
    lines = [f"def f({', '.join([*(str(a) for a in args), '_out'])}):"]
    lines += [f"    {s} = {pr.doprint(e)}" for s, e in reps]
    lines += [f"    _out[{i}] = {pr.doprint(e)}" for i, e in enumerate(red)]
    lines.append("    return _out")
    return "\n".join(lines) + "\n"


_PRINTER: list = []


def _printer():
    """NumPy's printer, plus the functions of ocdsl's own that _SMOOTH admits."""
    if not _PRINTER:
        from sympy.printing.numpy import NumPyPrinter

        class _Printer(NumPyPrinter):
            def _ramp(self, e, power: int) -> str:
                base = f"numpy.maximum({self._print(e.args[0])}, 0.0)"
                return base if power == 1 else f"{base}**{power}"

            def _print_r1(self, e):
                return self._ramp(e, 1)

            def _print_r2(self, e):
                return self._ramp(e, 2)

            def _print_r3(self, e):
                return self._ramp(e, 3)

            def _print_Heaviside(self, e):     # r1's derivative (a third derivative of r3)
                return f"numpy.heaviside({self._print(e.args[0])}, 0.5)"

            def _print_safe_exp(self, e):
                return f"numpy.exp({self._print(e.args[0])})"

        _PRINTER.append(_Printer({"fully_qualified_modules": True, "inline": True,
                                  "allow_unknown_functions": False}))
    return _PRINTER[0]


def _function(source: str | None):
    if source is None:
        return None
    ns = {"numpy": np}
    exec(compile(source, "<ocdsl.transcribe.direct_nlp>", "exec"), ns)
    return ns["f"]


_GENERATOR: list[str] = []


def _generator_id() -> str:
    """What the generated code depends on besides the expressions: ocdsl's and SymPy's
    versions and the generators' own sources (an edited generator never meets old entries)."""
    if not _GENERATOR:
        from pathlib import Path

        from ... import __version__
        from ...cache import fingerprint

        here = Path(__file__).parent
        _GENERATOR.append(fingerprint(__version__, sp.__version__, (here / "codegen.py").read_text(),
                                      (here / "native.py").read_text(), engine_id()))
    return _GENERATOR[0]


def _generated(exprs, dvars, extra=(), native: bool = False) -> dict:
    """``exprs`` with their nonzero first and lower-triangle second derivatives in ``dvars``
    (further arguments ``extra``): {"n_out", "jac", "hess", "values", "first", "second", "c"},
    the three NumPy sources of functions of ``dvars + extra`` and, with ``native`` when they
    are long (``native.MIN_LINES``), their C twin (else None). Taken from the disk
    cache (ocdsl/cache.py, kind ``nlp``) when it holds them: the key is the expressions
    themselves, with the arguments renamed by position, so a study's points and a second
    run of a file skip SymPy's differentiation."""
    from ... import cache
    from . import native as _native

    args = list(dvars) + list(extra)
    stand = [sp.Symbol(f"_a{i}", **a.assumptions0) for i, a in enumerate(args)]
    norm = [sp.sympify(e).xreplace(dict(zip(args, stand))) for e in exprs]
    free = set().union(*(e.free_symbols for e in norm)) - set(stand) if norm else set()
    if free:
        raise Unsupported(f"the expressions use {', '.join(sorted(str(s) for s in free))}")
    key = cache.fingerprint(_generator_id(), str(len(dvars)), str(native), sp.srepr(stand), sp.srepr(norm))
    entry = cache.read_entry("nlp", key)
    if not (isinstance(entry, dict) and entry.get("n_out") == len(norm)):
        jac, hess, parts = derivatives_cse(norm, stand[:len(dvars)])
        entry = {"n_out": len(norm), "jac": jac, "hess": hess, "c": None}
        for name in ("values", "first", "second"):
            entry[name] = _numpy_source(stand, *parts[name]) if name in parts else None
        if native and sum(len(r) + len(e) for r, e in parts.values()) >= _native.MIN_LINES:
            entry["c"] = _native.module_source({name: _native.function_source(name, stand, *p)
                                                for name, p in parts.items()})
        cache.write_entry("nlp", key, entry)
    return entry


def _rows_of(fn):
    """A generated NumPy function ``f(*args, _out)`` called as ``f(Y, out)``, one row of Y per argument."""
    if fn is None:
        return None
    return lambda Y, out: fn(*Y, out)


@dataclass
class _Family:
    """Expressions of one node's local variables w (and the node's normalised time S),
    with their nonzero first and (lower-triangle) second derivatives, evaluated for many
    nodes at once."""

    n_out: int
    jac: np.ndarray       # (E1, 2): output, local variable
    hess: np.ndarray      # (E2, 3): output, local a, local b (b <= a)
    _values: Any
    _first: Any
    _second: Any
    evaluation: str = "NumPy"    # or "C", or "NumPy: why not C"

    @classmethod
    def compile(cls, exprs: list, wsyms: list, S: sp.Symbol) -> "_Family":
        from . import native

        g = _generated(exprs, wsyms, [S], native=True)
        fns, how = {k: _rows_of(_function(g[k])) for k in ("values", "first", "second")}, "NumPy"
        if g.get("c"):
            compiled, why = native.load(g["c"])
            if compiled is not None:
                fns, how = {k: compiled.get(k) for k in fns}, "C"
            else:
                how = f"NumPy: {why}"
        return cls(g["n_out"], np.array(g["jac"], int).reshape(-1, 2), np.array(g["hess"], int).reshape(-1, 3),
                   fns["values"], fns["first"], fns["second"], how)

    @staticmethod
    def _stack(fn, n_rows, cols, nodes, out=None) -> np.ndarray:
        """``cols``: the C-ordered float64 (arguments, nodes) array of w and S; ``out``, when
        given, the C-ordered (rows, nodes) array written (a view of the NLP's buffer)."""
        if fn is None or n_rows == 0:
            return np.zeros((0, nodes))
        return fn(cols, np.empty((n_rows, nodes)) if out is None else out)

    def values(self, cols, nodes, out=None):
        return self._stack(self._values, self.n_out, cols, nodes, out)

    def first(self, cols, nodes, out=None):
        return self._stack(self._first, len(self.jac), cols, nodes, out)

    def second(self, cols, nodes, out=None):
        return self._stack(self._second, len(self.hess), cols, nodes, out)


@dataclass
class _Scalars:
    """The objective (output 0) and the general boundary constraints (outputs 1..) as
    functions of the scalar symbols: y entries (boundary values, t0/tf, parameters) and
    integrals, which may only enter linearly (their coefficients are constants)."""

    n_out: int            # 1 + number of general boundary constraints
    symbols: list         # ("y", y index) or ("I", (phase, integral)) of each argument, y first
    jac: list             # (output, symbol position, ) nonzero first derivatives in y symbols
    hess: list            # (output, a, b) b <= a, y symbols only
    integral_coef: list   # (output, phase index, integral index, constant coefficient)
    _values: Any
    _first: Any
    _second: Any

    @property
    def y_of(self) -> list:
        """index in y of each non-integral symbol (the first arguments)"""
        return [ref for kind, ref in self.symbols if kind == "y"]

    def evaluate(self, z, which, out=None):
        fn = {"values": self._values, "first": self._first, "second": self._second}[which]
        if fn is None:
            return np.zeros(0)
        n = {"values": self.n_out, "first": len(self.jac), "second": len(self.hess)}[which]
        return fn(*z, np.empty(n) if out is None else out)
