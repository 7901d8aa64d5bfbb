"""NumPy and ``math`` functions of SymPy expressions, printed once and kept in the disk cache.

Why: the certificate and the verification turn a phase's dynamics, its derivatives,
integrands and path constraints into about twenty functions per run. With
``sympy.lambdify`` every run pays the differentiation, the common-subexpression
elimination and the printing again, and lambdify's "numpy" namespace runs ``from numpy
import *``, which imports numpy.f2py and numpy.testing (0.2 s on its own). Here a family of
functions is derived and printed once; its source is stored under a key made of what it is
derived from (ocdsl/cache.py, kind ``numeric``), so a second run of a file (a study's
points, a warm run) execs the stored source and does no symbolic work at all.

A generated function takes the flat arguments positionally and returns the list of its
expressions' values (constants as numbers), as ``sympy.lambdify(args, exprs, cse=True)``
does. Expressions with functions the printers do not know (a table's interpolant with its
own implementation) are not cached: they get ``sympy.lambdify`` as before.
"""
from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from .engine import cse

_GENERATOR: list[str] = []
_NAMESPACE = {"numpy": np, "math": math, "functools": functools}


def _generator_id() -> str:
    if not _GENERATOR:
        from .. import __version__
        from ..cache import fingerprint

        from .engine import engine_id     # the families' derivatives and CSE

        _GENERATOR.append(fingerprint(__version__, sp.__version__, Path(__file__).read_text(), engine_id()))
    return _GENERATOR[0]


def _printer(module: str):
    settings = {"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False}
    if module == "numpy":
        from sympy.printing.numpy import NumPyPrinter

        return NumPyPrinter(settings)
    from sympy.printing.pycode import PythonCodePrinter

    return PythonCodePrinter(settings)


def source(args: Sequence[sp.Symbol], exprs: Sequence, module: str = "numpy") -> str:
    """Source of ``f(*args)`` returning ``[exprs]`` after common-subexpression elimination;
    raises ``PrintMethodNotImplementedError`` for a function the printer does not know."""
    stand = [sp.Symbol(f"_a{i}") for i in range(len(args))]     # names safe as Python identifiers
    ren = dict(zip(args, stand))
    exprs = [sp.sympify(e).xreplace(ren) for e in exprs]
    reps, red = cse(exprs) if exprs else ([], [])
    pr = _printer(module)
    lines = [f"def f({', '.join(str(s) for s in stand)}):"]
    lines += [f"    {s} = {pr.doprint(e)}" for s, e in reps]
    lines.append(f"    return [{', '.join(pr.doprint(e) for e in red)}]")
    return "\n".join(lines) + "\n"


def function(src: str) -> Callable:
    ns = dict(_NAMESPACE, __name__="ocdsl.symbolic.numeric.generated")   # its warnings are ocdsl's
    exec(compile(src, "<ocdsl.symbolic.numeric>", "exec"), ns)
    return ns["f"]


def family(args: Sequence[sp.Symbol], key: Sequence, make: Callable[[], Mapping[str, tuple[Sequence, str]]]
           ) -> dict[str, Callable]:
    """Functions of ``args`` by name. ``make()`` gives {name: (expressions, module)}, module
    "numpy" (vectorised over points) or "math" (one point, plain floats); it runs only when
    the cache has no entry for ``key`` (the expressions it derives from, and anything else
    that changes them), so its symbolic work is skipped on a hit."""
    from .. import cache

    k = cache.fingerprint(_generator_id(), sp.srepr(list(args)), *(sp.srepr(x) for x in key))
    entry = cache.read_entry("numeric", k)
    if not isinstance(entry, dict) or not all(isinstance(v, str) for v in entry.values()):
        from sympy.printing.codeprinter import PrintMethodNotImplementedError

        made = make()
        try:
            entry = {name: source(args, exprs, module) for name, (exprs, module) in made.items()}
        except PrintMethodNotImplementedError:
            return {name: sp.lambdify(list(args), list(exprs), module, cse=True)
                    for name, (exprs, module) in made.items()}
        cache.write_entry("numeric", k, entry)
    return {name: function(src) for name, src in entry.items()}
