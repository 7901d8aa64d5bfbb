"""LaTeX of the problem's expressions for the report, with the names a paper prints: a phase's
final time ``tf`` as t_f (SymPy writes the symbol "tf", which mathtext sets as the product
t f), a boundary value ``x(tf)`` as x(t_f), and a multi-letter name that is not a Greek letter
(``Dc``, ``hc``) upright, one symbol, not the product D c (unseen33 F11)."""
from __future__ import annotations

import re

import sympy as sp
from sympy.printing.latex import greek_letters_set

_TIMES = {"t0": "t_{0}", "tf": "t_{f}"}


def latex(expr) -> str:
    expr = sp.sympify(expr)
    names = {s: _name(s.name) for s in expr.free_symbols if isinstance(s, sp.Symbol)}
    return sp.latex(expr, symbol_names={s: n for s, n in names.items() if n is not None})


def _name(name: str) -> str | None:
    """The LaTeX of a symbol's name where SymPy's would mislead; None to keep SymPy's."""
    phase, _, bare = name.rpartition(".")
    if bare in _TIMES:
        return _TIMES[bare] + (r"^{\mathrm{%s}}" % phase if phase else "")
    m = re.fullmatch(r"([A-Za-z_]\w*)\((t0|tf)\)", bare)
    if m:
        inner = _name(m.group(1)) or sp.latex(sp.Symbol(m.group(1)))
        return f"{inner}({_TIMES[m.group(2)]})" + (r"^{\mathrm{%s}}" % phase if phase else "")
    if phase:
        return None
    if re.fullmatch(r"[A-Za-z]{2,}", bare) and bare.lower() not in greek_letters_set \
            and bare not in ("lambda", "Lambda"):
        return r"\mathrm{%s}" % bare
    return None
