"""Symbolic equations solved with limits, for the flatness elimination: ``sympy.solve``
given up after a time, Cramer's rule keeping the factored form, and the unknown angle that
a set of equations holds only through sin() and cos()."""
from __future__ import annotations

from typing import Sequence

import sympy as sp

SOLVE_SECONDS = 3


def solve_limited(eqs, unknowns, seconds: int = SOLVE_SECONDS) -> list[dict]:
    """``sympy.solve(eqs, unknowns, dict=True)``, given up after ``seconds`` (on the
    main thread of a POSIX process; elsewhere without a limit) or when SymPy cannot."""
    import signal
    import threading

    def handler(signum, frame):
        raise TimeoutError

    limited = hasattr(signal, "SIGALRM") and threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGALRM, handler) if limited else None
    if limited:
        signal.alarm(seconds)
    try:
        return sp.solve(eqs, unknowns, dict=True)
    except (NotImplementedError, TimeoutError):
        return []
    finally:
        if limited:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)


def solve_linear(eqs: Sequence[sp.Expr], unknowns: Sequence[sp.Symbol]) -> dict | None:
    """Cramer's rule for a square linear system, keeping the factored form."""
    try:
        A, b = sp.linear_eq_to_matrix(list(eqs), list(unknowns))
    except (sp.polys.polyerrors.PolynomialError, ValueError):
        return None
    det = sp.factor_terms(A.det())
    if det == 0:
        return None
    adj = A.adjugate()
    sol = adj * b
    return {u: sp.factor_terms(sol[i] / det) for i, u in enumerate(unknowns)}


def trig_angle(eqs: Sequence[sp.Expr], unknowns: set) -> sp.Symbol | None:
    """An unknown that occurs in all ``eqs`` only through sin() and cos()."""
    for c in sorted(unknowns, key=lambda s: s.name):
        ok = True
        for e in eqs:
            stripped = e.replace(sp.sin, lambda a: sp.Symbol("__S") if a == c else sp.sin(a))
            stripped = stripped.replace(sp.cos, lambda a: sp.Symbol("__C") if a == c else sp.cos(a))
            if stripped.has(c) or not (stripped.has(sp.Symbol("__S")) or stripped.has(sp.Symbol("__C"))):
                ok = False
                break
        if ok:
            return c
    return None
