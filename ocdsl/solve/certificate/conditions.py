"""Hamiltonian and first-order conditions of a model, symbolically."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import sympy as sp

from ocdsl.symbolic.model import TIME, Model, sym

@dataclass(frozen=True)
class SymbolicConditions:
    """Hamiltonian and first-order conditions of a model, symbolically.

    ``hamiltonian`` keeps the model's named expressions (for display);
    ``hamiltonian_expanded`` has them substituted. ``dH_du``/``costate_rhs`` are expanded.
    """

    hamiltonian: sp.Expr
    hamiltonian_expanded: sp.Expr
    costates: dict[sp.Symbol, sp.Symbol]        # state -> lambda_<state>
    dH_du: dict[sp.Symbol, sp.Expr]             # control -> dH/du
    costate_rhs: dict[sp.Symbol, sp.Expr]       # state -> d(lambda)/dt = -dH/dx
    time_dependent: bool

    def latex(self) -> dict[str, Any]:
        return {"hamiltonian": sp.latex(self.hamiltonian),
                "dH_du": {u.name: sp.latex(e) for u, e in self.dH_du.items()},
                "costate_rhs": {x.name: sp.latex(e) for x, e in self.costate_rhs.items()}}


def _param_subs(model: Model, parameter_values: Mapping | None) -> dict[sp.Symbol, sp.Expr]:
    subs: dict[sp.Symbol, Any] = dict(model.default_parameters())
    for k, v in (parameter_values or {}).items():
        if isinstance(k, str):     # a model parameter, or a file-level one (a free parameter)
            try:
                k = model.symbol(k)
            except KeyError:
                k = sym(k)
        subs[k] = v
    return {k: (v if isinstance(v, sp.Basic) else sp.Float(v)) for k, v in subs.items()}


def symbolic_conditions(model: Model, lagrange: sp.Expr | float = 0,
                        parameter_values: Mapping | None = None) -> SymbolicConditions:
    """``H = L + lambda^T f`` and ``dH/du``, ``-dH/dx`` for ``model``.

    ``lagrange`` may use states, controls, parameters, named expressions and ``TIME``.
    ``parameter_values`` (name or symbol -> number) are substituted when given.
    """
    lams = {x: sym(f"lambda_{x.name}") for x in model.states}
    L = sp.sympify(lagrange)
    H_disp = L + sum((lams[x] * model.dynamics[x] for x in model.states), sp.Integer(0))
    f = model.rhs()
    H = model.expand(L) + sum((lams[x] * f[i] for i, x in enumerate(model.states)), sp.Integer(0))
    if parameter_values is not None:
        from ...symbolic.numbers import substitute_numbers   # exp(885 - r/H) kept whole

        subs = _param_subs(model, parameter_values)
        H = substitute_numbers(H, subs)
        H_disp = substitute_numbers(H_disp, subs)
    return SymbolicConditions(
        hamiltonian=H_disp,
        hamiltonian_expanded=H,
        costates=lams,
        dH_du={u: H.diff(u) for u in model.controls},
        costate_rhs={x: -H.diff(x) for x in model.states},
        time_dependent=TIME in H.free_symbols,
    )
