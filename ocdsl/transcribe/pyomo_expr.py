"""SymPy expressions -> Pyomo expressions, through one lambdified function per expression set.

``sympy.lambdify`` with common-subexpression elimination turns a vector of expressions
into Python code once; calling it with Pyomo variables builds Pyomo expressions, with
shared subexpressions built once per call (once per node).
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import pyomo.core as pyo
import sympy as sp


def _atan2(y, x):
    # Pyomo has no atan2; this half-angle form is smooth away from the negative x axis.
    return 2 * pyo.atan(y / (pyo.sqrt(x**2 + y**2) + x))


def _sign_error(*_):
    raise ValueError("sign() is not differentiable and cannot be used in an NLP")


PYOMO_FUNCTIONS = {
    "sin": pyo.sin, "cos": pyo.cos, "tan": pyo.tan, "asin": pyo.asin, "acos": pyo.acos,
    "atan": pyo.atan, "atan2": _atan2, "sinh": pyo.sinh, "cosh": pyo.cosh, "tanh": pyo.tanh,
    "asinh": pyo.asinh, "acosh": pyo.acosh, "atanh": pyo.atanh,
    "exp": pyo.exp, "log": pyo.log, "sqrt": pyo.sqrt, "Abs": abs, "abs": abs,
    "pi": math.pi, "E": math.e, "sign": _sign_error,
}


# a mesh refinement builds the same phase's functions once per mesh (Rayleigh: 39 lambdify
# calls, 0.08 s of 12 builds); the functions are pure, so one per expression set is kept
_MADE: dict[tuple, Callable[..., list]] = {}
_MADE_LIMIT = 256


def pyomo_function(args: Sequence[sp.Symbol], exprs: Sequence[sp.Expr]) -> Callable[..., list]:
    """A function of ``args`` returning the list of ``exprs`` as Pyomo expressions (or floats)."""
    exprs = [sp.sympify(e) for e in exprs]
    key = (tuple(args), tuple(exprs))
    fn = _MADE.get(key)
    if fn is None:
        fn = sp.lambdify(list(args), exprs, modules=[PYOMO_FUNCTIONS], cse=True, docstring_limit=0)
        if len(_MADE) >= _MADE_LIMIT:
            _MADE.clear()
        _MADE[key] = fn
    return fn
