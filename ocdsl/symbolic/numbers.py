"""Substituting numbers without overflow: ``exp(c + g)`` kept whole when ``c`` is large.

SymPy evaluates ``exp(885.8 - r/7200)`` into ``5.3e384*exp(-r/7200)``: a float overflow
(inf * 0 = NaN at r = 6.4e6 m) that an atmosphere ``rho0*exp(-(r - Re)/H)`` in SI units
meets as soon as ``Re`` and ``H`` are numbers. Where substituting numbers would pull out
such a factor, the exponential becomes :class:`safe_exp`, which SymPy leaves whole: the same
function, with its own derivative and a numeric form for floats, NumPy and Pyomo.
"""
from __future__ import annotations

import math

import sympy as sp

LARGE = 600.0      # exp(600) = 3.8e260: a factor still far from overflow (exp(709.8)); Goddard's
                   # exp(500 - 500 r) stays a plain exp (and on the NumPy NLP route)


class safe_exp(sp.Function):
    nargs = 1

    def fdiff(self, argindex=1):
        return self

    @staticmethod
    def _imp_(z):
        try:
            return math.exp(z)
        except TypeError:
            pass
        if type(z).__module__.startswith("pyomo"):
            import pyomo.core as pyo

            return pyo.exp(z)
        import numpy as np

        return np.exp(z)

    def _latex(self, printer):
        return r"e^{%s}" % printer._print(self.args[0])


def exp_of(arg: sp.Expr) -> sp.Expr:
    """``exp(arg)``, or ``safe_exp(arg)`` when SymPy would pull a large constant out of it."""
    if arg.is_Add and any(t.is_Number and abs(float(t)) > LARGE for t in arg.args):
        return safe_exp(arg)
    return sp.exp(arg)


class _held(sp.Function):
    """An exponential while numbers are substituted into its argument."""


def substitute_numbers(expr, mapping: dict):
    """``expr.xreplace(mapping)`` with every exponential rebuilt by :func:`exp_of`."""
    if not getattr(expr, "has", None) or not expr.has(sp.exp):
        return expr.xreplace(mapping)
    held = expr.replace(sp.exp, _held)
    return held.xreplace(mapping).replace(_held, exp_of)
