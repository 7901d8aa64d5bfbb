"""The symbolic optimal-control Problem every back end consumes.

A Problem has one or more Phases. Each phase has a model (states, controls,
dynamics), its time interval, box bounds (which back ends turn into variable bounds),
path constraints (in states, controls, ``t`` and free parameters), integrals, and a
guess. Boundary values ``x(t0)``/``x(tf)`` of every phase, the phases' ``t0``/``tf``,
integrals and free parameters are scalar symbols; boundary constraints, links and the
objective are expressions in them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

import sympy as sp

from .model import TIME, Model

INF = float("inf")


@dataclass(frozen=True)
class BoundaryValue:
    """What a boundary symbol stands for: ``var`` of ``phase`` at ``which`` (t0 or tf)."""

    phase: str
    var: sp.Symbol
    which: Literal["t0", "tf"]


@dataclass
class Constraint:
    """``lower <= expr <= upper`` (equal bounds for an equality), with where it came from."""

    expr: sp.Expr
    lower: float
    upper: float
    text: str = ""
    line: int | None = None

    @property
    def is_equality(self) -> bool:
        return self.lower == self.upper


@dataclass
class FreeParameter:
    symbol: sp.Symbol
    lower: float = -INF
    upper: float = INF
    guess: float = 0.0


@dataclass
class Phase:
    """One phase. ``model.rhs(constants)`` gives the dynamics with constants substituted."""

    name: str
    model: Model
    constants: dict[sp.Symbol, float]
    t0: float | None                       # None: free
    tf: float | None                       # None: free
    t0_symbol: sp.Symbol
    tf_symbol: sp.Symbol
    t0_bounds: tuple[float, float] = (-INF, INF)
    tf_bounds: tuple[float, float] = (-INF, INF)
    state_bounds: dict[sp.Symbol, tuple[float, float]] = field(default_factory=dict)
    control_bounds: dict[sp.Symbol, tuple[float, float]] = field(default_factory=dict)
    path: list[Constraint] = field(default_factory=list)
    integrals: dict[sp.Symbol, sp.Expr] = field(default_factory=dict)  # symbol -> integrand
    guess: dict[str, Any] = field(default_factory=dict)

    @property
    def states(self) -> tuple[sp.Symbol, ...]:
        return self.model.states

    @property
    def controls(self) -> tuple[sp.Symbol, ...]:
        return self.model.controls

    def rhs(self) -> sp.Matrix:
        """Dynamics with constant parameters substituted (free parameters stay symbols)."""
        return self.model.rhs(self.constants)

    def substitute(self, expr: sp.Expr) -> sp.Expr:
        """Named expressions expanded and constants substituted, as in :meth:`rhs`."""
        from .numbers import substitute_numbers

        return substitute_numbers(self.model.expand(expr), {k: sp.Float(v) for k, v in self.constants.items()})

    def bounds_of(self, s: sp.Symbol) -> tuple[float, float]:
        return self.state_bounds.get(s) or self.control_bounds.get(s) or (-INF, INF)

    @property
    def time_symbol(self) -> sp.Symbol:
        return TIME


@dataclass
class Objective:
    sense: Literal["minimize", "maximize"]
    expr: sp.Expr          # in boundary symbols, phase t0/tf, integrals, free parameters
    text: str = ""


@dataclass
class Problem:
    name: str
    phases: list[Phase]
    objective: Objective
    boundary: list[Constraint] = field(default_factory=list)   # includes links
    free_parameters: dict[sp.Symbol, FreeParameter] = field(default_factory=dict)
    boundary_values: dict[sp.Symbol, BoundaryValue] = field(default_factory=dict)
    description: dict[str, Any] = field(default_factory=dict)  # what the report typesets

    def phase(self, name: str) -> Phase:
        for p in self.phases:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def integrals(self) -> dict[sp.Symbol, tuple[str, sp.Expr]]:
        return {s: (p.name, e) for p in self.phases for s, e in p.integrals.items()}

    @cached_property
    def objective_constant(self) -> float:
        """C: what J holds that nothing the solve decides moves, from the terms as written (not
        expanded): J's terms in numbers and fixed phase times alone, plus, for an integral that
        J holds with a constant coefficient, that coefficient times its integrand's terms in t
        alone integrated over its phase where both its times are fixed. J's size leaves it out
        (verify/objective_size.own_size): ``minimize 1e8 + integral(u**2/2 + t*x)`` on a mesh
        1.2e-4 off its optimum was "optimal", the bisection's change 8e-14 of 1e8 (unseen59
        F2). Computed once per Problem: every comparison of J in a run asks for it."""
        fixed = {}
        for ph in self.phases:
            if ph.t0 is not None:
                fixed[ph.t0_symbol] = float(ph.t0)
            if ph.tf is not None:
                fixed[ph.tf_symbol] = float(ph.tf)
        J = sp.sympify(self.objective.expr)
        total = 0.0
        for term in sp.Add.make_args(J):
            if term.free_symbols <= set(fixed):
                total += float(term.subs(fixed))
        for s, (name, L) in self.integrals.items():
            ph, coefficient = self.phase(name), sp.diff(J, s)
            if ph.t0 is None or ph.tf is None or not coefficient.free_symbols <= set(fixed):
                continue
            of_t = [term for term in sp.Add.make_args(ph.substitute(L)) if term.free_symbols <= {TIME}]
            if of_t:
                from scipy.integrate import quad

                f = sp.lambdify(TIME, sp.Add(*of_t), "math")
                total += float(coefficient.subs(fixed)) * quad(lambda t: float(f(t)), float(ph.t0), float(ph.tf),
                                                               limit=200)[0]
        return float(total) if math.isfinite(total) else 0.0
