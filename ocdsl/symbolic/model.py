"""SymPy models: states, controls, parameters, named expressions and dynamics.

A :class:`Model` is the symbolic description every back end starts from. Models are
either declared inline in a problem file or registered in ``models/`` with
:func:`ocdsl.symbolic.registry.register`.

Convention: every symbol is real (``sym(name)``), so that a model written in Python
and a problem file parsed by :mod:`ocdsl.spec` refer to the very same SymPy symbols.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import sympy as sp

TIME = sp.Symbol("t", real=True)


def sym(name: str) -> sp.Symbol:
    """The one way to make a model symbol (real, so parser and models agree)."""
    return sp.Symbol(name, real=True)


def syms(names: str) -> tuple[sp.Symbol, ...]:
    """Several symbols from a space- or comma-separated string."""
    return tuple(sym(n) for n in names.replace(",", " ").split())


@dataclass(frozen=True)
class Model:
    """A controlled dynamical system ``dx/dt = f(x, u, p, t)``.

    Attributes
    ----------
    name : registered or file-given name.
    states, controls : ordered symbols.
    dynamics : state symbol -> right-hand side (SymPy expression in states, controls,
        parameters, named expressions and ``TIME``).
    parameters : parameter symbol -> default value (None when it has no default).
    expressions : named intermediate quantities, symbol -> expression; dynamics may use
        them, :meth:`rhs` substitutes them.
    units : symbol name -> unit string (for reports); ``description`` one line.
    positions : names of states that form a position vector (for trajectory plots).
    time_state : the state that is physical time when the independent variable is another
        one (a Sundman-transformed model's clock); reports put it on their time axes.
    vectors : name -> column of symbols or expressions: declared vector groups (``r`` for
        the states ``x, y, z``) and vector-valued named expressions, usable by name in
        expressions (``norm(r)``, ``cross(r, v)``, ``r(tf)``).
    frame : the frame the positions are drawn in, as a function of the parameter values
        (name -> value) returning ``{"name", "coordinates": "cartesian" | "cylindrical"
        ((r, theta, z) drawn as x = r cos theta, y = r sin theta), "bodies": [{"name",
        "at": [x, y, z], "radius"}], "points": [{"name", "at"}]}``: reports mark the bodies
        and points (the Moon, L1) beside the trajectory. None: no declared frame.
    """

    name: str
    states: tuple[sp.Symbol, ...]
    controls: tuple[sp.Symbol, ...]
    dynamics: Mapping[sp.Symbol, sp.Expr]
    parameters: Mapping[sp.Symbol, float | None] = field(default_factory=dict)
    expressions: Mapping[sp.Symbol, sp.Expr] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    description: str = ""
    positions: tuple[str, ...] = ()
    vectors: Mapping[str, sp.ImmutableMatrix] = field(default_factory=dict)
    time_state: str = ""    # the state that is physical time when the independent variable is not (Sundman)
    frame: Callable[[Mapping[str, float]], dict[str, Any]] | None = None

    def __post_init__(self) -> None:
        missing = [s for s in self.states if s not in self.dynamics]
        extra = [s for s in self.dynamics if s not in self.states]
        if missing or extra:
            raise ValueError(
                f"model {self.name!r}: states without dynamics {[str(s) for s in missing]}, "
                f"dynamics for unknown states {[str(s) for s in extra]}"
            )

    @property
    def n_states(self) -> int:
        return len(self.states)

    @property
    def n_controls(self) -> int:
        return len(self.controls)

    def expand(self, expr: sp.Expr) -> sp.Expr:
        """Substitute named expressions (innermost last, so later names may use earlier ones)."""
        for name, value in reversed(list(self.expressions.items())):
            expr = expr.xreplace({name: value})
        return expr

    def rhs(self, parameter_values: Mapping[sp.Symbol, float] | None = None) -> sp.Matrix:
        """f(x, u, p, t) as a column, ordered like ``states``, named expressions substituted.

        ``parameter_values`` substitutes numbers for parameters (others stay symbols).
        """
        # kept per parameter values: a mesh refinement asks once per mesh built (hang glider:
        # 15 substitutions, a tenth of its builds); a copy is returned, the Matrix is mutable
        try:
            key = tuple((parameter_values or {}).items())
            made = self.__dict__.setdefault("_rhs_made", {})
            if key in made:
                return made[key].copy()
        except TypeError:       # an unhashable value: made afresh
            key, made = None, {}
        f = sp.Matrix([self.expand(self.dynamics[s]) for s in self.states])
        if parameter_values:
            from .numbers import substitute_numbers

            f = substitute_numbers(f, {k: sp.Float(v) if not isinstance(v, sp.Basic) else v
                                       for k, v in parameter_values.items()})
        if key is not None:
            if len(made) >= 16:
                made.clear()
            made[key] = f
        return f.copy()

    def default_parameters(self) -> dict[sp.Symbol, float]:
        return {k: v for k, v in self.parameters.items() if v is not None}

    def symbols(self) -> dict[str, sp.Symbol]:
        """Name -> symbol of every state, control, parameter and named expression (the first
        of a name, in that order)."""
        out: dict[str, sp.Symbol] = {}
        for group in (self.states, self.controls, tuple(self.parameters), tuple(self.expressions)):
            for s in group:
                out.setdefault(s.name, s)
        return out

    def symbol(self, name: str) -> sp.Symbol:
        """Look up any model symbol (state, control, parameter, expression) by name."""
        return self.symbols()[name]
