"""Automatic (partial) differential-flatness elimination of a :class:`Model`.

Given a model ``x' = f(x, u, p, t)`` and a set of *outputs* (a few of its states), the
states and controls are expressed, where possible, as functions of the outputs and of
their time derivatives; what cannot be eliminated stays as *residual* equations:

* algebraic residuals ``g(y, y', y'', ..., t) = 0`` (e.g. the lunar lander's thrust
  magnitude (T/m)^2 = a_t^2 + a_r^2, written dimensionless as ``sin^2 + cos^2 - 1``);
* differential residuals ``x' - f(...) = 0`` in the states that could not be eliminated
  (the system is then not flat with these outputs; those states stay NLP unknowns).

Notation
--------
For an output ``y`` the symbol ``y`` itself is its value and ``y_d1, y_d2, ...`` its 1st,
2nd, ... derivatives with respect to the physical time ``t``. A state whose right-hand
side depends on time and parameters only (the lander's mass) is integrated in closed
form from its value at the phase start, the *integration constant* ``x_t0``; time is
measured from the phase start (``t = 0`` there).

Elimination rules, applied until nothing changes
------------------------------------------------
1. *quadrature*: ``x' = f(t, p)`` gives ``x = x_t0 + int_0^t f``;
2. *single unknown*: a dynamics equation whose state is already known, with one unknown
   state or control left in it, is solved for that unknown with SymPy;
3. *trigonometric pair*: equations in which an unknown angle ``c`` appears only through
   ``sin c`` and ``cos c`` (thrust or heading angles) are solved for ``S = sin c``,
   ``C = cos c`` (and at most one other unknown, e.g. a speed); ``c = atan2(S, C)``, and
   ``S^2 + C^2 = 1`` is either used to find the other unknown or kept as a residual;
4. *pairs*: two equations in the same two unknowns are solved jointly.

When SymPy returns several solutions, the branch is chosen by the given bounds: random
consistent points (states and controls drawn inside their bounds, output derivatives
computed from the dynamics) are mapped back through each candidate and the candidate
that recovers the drawn value is kept.

Time normalisation (free final time): with ``t = tf * tau``, every ``d^k y/dt^k`` is
``(d^k y/dtau^k) / tf^k`` (:meth:`FlatMap.normalized`).

This module never imports Pyomo.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace
from typing import Iterable, Mapping, Sequence

import numpy as np
import sympy as sp

from .equations import solve_limited, solve_linear, trig_angle
from .model import TIME, Model, sym

__all__ = ["FlatnessError", "Residual", "NLPReduction", "FlatMap", "flatten", "derivative_symbol"]


class FlatnessError(ValueError):
    """The model cannot be reduced with the requested (or any searched) outputs."""


def derivative_symbol(y: sp.Symbol, k: int) -> sp.Symbol:
    """Symbol of the k-th time derivative of ``y`` (``y`` itself for k = 0)."""
    return y if k == 0 else sym(f"{y.name}_d{k}")


@dataclass(frozen=True)
class Residual:
    """One equation left after elimination: ``expr == 0``.

    ``kind`` is ``"algebraic"`` (outputs and their derivatives only) or ``"differential"``
    (involves a state that could not be eliminated, through its derivative symbols).
    ``source`` names the dynamics equations it comes from, e.g. ``("u'", "v'")``.
    """

    expr: sp.Expr
    kind: str
    source: tuple[str, ...]


@dataclass(frozen=True)
class NLPReduction:
    """NLP size with and without elimination for ``n_con`` control points (per
    function) and ``n_col`` collocation points, ``n_boundary`` boundary constraints
    and one free final time (the seed's counting: quadrature states such as the mass
    are known in closed form in both cases and not counted).
    """

    n_con: int
    n_col: int
    n_boundary: int
    variables_flat: int
    constraints_flat: int
    variables_full: int
    constraints_full: int

    @property
    def variable_ratio(self) -> float:
        return self.variables_flat / self.variables_full

    def as_dict(self) -> dict[str, int]:
        return {k: getattr(self, k) for k in ("n_con", "n_col", "n_boundary", "variables_flat",
                                              "constraints_flat", "variables_full",
                                              "constraints_full")}


@dataclass(frozen=True)
class FlatMap:
    """Result of :func:`flatten` (treat as immutable).

    Attributes
    ----------
    model : the model that was reduced (its name is ``model.name``).
    outputs : the flat (or partially flat) outputs, state symbols of the model.
    functions : outputs followed by the states that could not be eliminated; these are
        the unknown functions of time the transcription approximates.
    orders : function symbol -> highest derivative order that occurs.
    states, controls : symbol -> expression in the functions' derivative symbols
        (:func:`derivative_symbol`), ``TIME``, parameters and integration constants.
        Uneliminated states map to themselves.
    residuals : equations that remain, each ``expr == 0``.
    constants : integration constants (``x_t0`` of quadrature states) -> state.
    parameter_values : numbers substituted for parameters.
    time_scale : ``None`` for physical time; the ``tf`` symbol after :meth:`normalized`
        (then derivative symbols are tau-derivatives and ``TIME`` means tau).
    eliminated_equations : the dynamics equations used as definitions, in order.
    """

    model: Model
    outputs: tuple[sp.Symbol, ...]
    functions: tuple[sp.Symbol, ...]
    orders: Mapping[sp.Symbol, int]
    states: Mapping[sp.Symbol, sp.Expr]
    controls: Mapping[sp.Symbol, sp.Expr]
    residuals: tuple[Residual, ...]
    constants: Mapping[sp.Symbol, sp.Symbol]
    parameter_values: Mapping[sp.Symbol, float] = field(default_factory=dict)
    time_scale: sp.Symbol | None = None
    eliminated_equations: tuple[str, ...] = ()

    # -- queries -------------------------------------------------------------------
    @property
    def remaining_states(self) -> tuple[sp.Symbol, ...]:
        return tuple(f for f in self.functions if f not in self.outputs)

    @property
    def is_flat(self) -> bool:
        """True when no residual is left (every state and control is a function of
        the outputs and finitely many of their derivatives)."""
        return not self.residuals and not self.remaining_states

    def derivative_symbols(self) -> list[sp.Symbol]:
        """All derivative symbols used, function by function, order by order."""
        return [derivative_symbol(y, k) for y in self.functions for k in range(self.orders[y] + 1)]

    def expression(self, name: str) -> sp.Expr:
        """Flat expression of a state or control given by name."""
        for group in (self.states, self.controls):
            for s, e in group.items():
                if s.name == name:
                    return e
        raise KeyError(f"{name!r} is neither a state nor a control of {self.model.name!r}")

    def reduction(self, n_con: int, n_col: int | None = None, n_boundary: int = 0,
                  free_tf: bool = True) -> NLPReduction:
        """NLP sizes with and without elimination (see :class:`NLPReduction`)."""
        n_col = n_con if n_col is None else n_col
        quad = set(self.constants.values())
        full_states = [s for s in self.model.states if s not in quad]
        extra = 1 if free_tf else 0
        return NLPReduction(
            n_con=n_con, n_col=n_col, n_boundary=n_boundary,
            variables_flat=len(self.functions) * n_con + extra,
            constraints_flat=len(self.residuals) * n_col + n_boundary,
            variables_full=(len(full_states) + len(self.model.controls)) * n_con + extra,
            constraints_full=len(full_states) * n_col + n_boundary,
        )

    def normalized(self, tf: sp.Symbol | None = None) -> "FlatMap":
        """The same map in normalised time ``tau = t / tf`` on [0, 1].

        Each derivative symbol ``y_dk`` is replaced by ``y_dk / tf**k`` (the symbol now
        meaning the tau-derivative) and ``t`` by ``tf * tau`` (``TIME`` then stands for
        tau). Residuals are kept as they are after the substitution (no rescaling).
        """
        if self.time_scale is not None:
            raise ValueError("map is already normalised")
        tf = tf if tf is not None else sym("tf")
        sub = {TIME: tf * TIME}
        for y in self.functions:
            for k in range(1, self.orders[y] + 1):
                sub[derivative_symbol(y, k)] = derivative_symbol(y, k) / tf ** k

        def tr(e: sp.Expr) -> sp.Expr:
            return e.xreplace(sub)

        return replace(
            self,
            states={s: tr(e) for s, e in self.states.items()},
            controls={c: tr(e) for c, e in self.controls.items()},
            residuals=tuple(Residual(tr(r.expr), r.kind, r.source) for r in self.residuals),
            time_scale=tf,
        )

    def summary(self) -> str:
        lines = [f"flat map of {self.model.name!r}: outputs {[y.name for y in self.outputs]}"
                 + ("" if self.is_flat else f", {len(self.residuals)} residual(s)")]
        for group in (self.states, self.controls):
            for s, e in group.items():
                lines.append(f"  {s} = {e}")
        for r in self.residuals:
            lines.append(f"  0 = {r.expr}   [{r.kind}, from {', '.join(r.source)}]")
        return "\n".join(lines)


# ---------------------------------------------------------------------------------------
# internals
# ---------------------------------------------------------------------------------------
def _total_derivative(expr: sp.Expr, functions: Iterable[sp.Symbol], orders: dict,
                      rates: Mapping[sp.Symbol, sp.Expr] | None = None) -> sp.Expr:
    """d/dt of an expression in derivative symbols of ``functions``, TIME and
    quadrature states (whose rates are given)."""
    out = sp.diff(expr, TIME)
    for x, fx in (rates or {}).items():
        if expr.has(x):
            out += sp.diff(expr, x) * fx
    for y in functions:
        for k in range(orders.get(y, 0) + 1):
            s = derivative_symbol(y, k)
            if expr.has(s):
                out += sp.diff(expr, s) * derivative_symbol(y, k + 1)
                orders[y] = max(orders.get(y, 0), k + 1)
    return out


def _eq_name(x: sp.Symbol) -> str:
    return f"{x.name}'"


class _Sampler:
    """Random consistent points: states/controls (and control derivatives) inside
    their bounds, output derivatives from the dynamics (for branch selection)."""

    def __init__(self, model: Model, f: Mapping[sp.Symbol, sp.Expr], bounds, numbers, seed=0):
        self.model, self.f, self.numbers = model, f, numbers
        self.bounds = bounds
        self.rng = np.random.default_rng(seed)
        self._lie: dict[tuple[sp.Symbol, int], sp.Expr] = {}

    def _range(self, s: sp.Symbol) -> tuple[float, float]:
        lo, hi = self.bounds.get(s.name, (None, None))
        free = (lo is None or not np.isfinite(lo)) and (hi is None or not np.isfinite(hi))
        # a quantity without bounds is sampled positive: a branch such as v = +-sqrt(x'^2 +
        # y'^2) is then the principal one (forward), where samples of both signs made it a
        # coin flip and a unicycle drove backwards into "Problem may be infeasible" (unseen22 f13)
        lo = (0.0 if free else -1.0) if lo is None or not np.isfinite(lo) else float(lo)
        hi = (lo + 2.0) if hi is None or not np.isfinite(hi) else float(hi)
        if hi <= lo:
            hi = lo + 1.0
        pad = 0.1 * (hi - lo)
        return lo + pad, hi - pad

    def lie(self, y: sp.Symbol, k: int) -> sp.Expr:
        """k-th time derivative of state y along the dynamics, in x, u, u_dj, t."""
        key = (y, k)
        if key not in self._lie:
            if k == 0:
                self._lie[key] = y
            else:
                prev = self.lie(y, k - 1)
                out = sp.diff(prev, TIME)
                for x in self.model.states:
                    if prev.has(x):
                        out += sp.diff(prev, x) * self.f[x]
                for u in self.model.controls:
                    for j in range(k):
                        s = derivative_symbol(u, j)
                        if prev.has(s):
                            out += sp.diff(prev, s) * derivative_symbol(u, j + 1)
                self._lie[key] = out
        return self._lie[key]

    def point(self, functions, orders, constants) -> tuple[dict, dict]:
        """(values of derivative symbols/constants/t, true values of states/controls)."""
        truth: dict[sp.Symbol, float] = {}
        for s in (*self.model.states, *self.model.controls):
            lo, hi = self._range(s)
            truth[s] = float(self.rng.uniform(lo, hi))
        for u in self.model.controls:
            for j in range(1, 6):
                truth[derivative_symbol(u, j)] = float(self.rng.uniform(-0.1, 0.1))
        truth[TIME] = float(self.rng.uniform(0.0, 1.0))
        values: dict[sp.Symbol, float] = {TIME: truth[TIME], **self.numbers}
        for y in functions:
            for k in range(orders.get(y, 0) + 1):
                values[derivative_symbol(y, k)] = complex(
                    sp.N(self.lie(y, k).xreplace(truth))).real
        for x in constants.values():     # quadrature states stay symbols until the end
            values[x] = truth[x]
        return values, truth


def _choose(unknown, candidates, sampler, functions, orders, constants, eq_text):
    """Pick the candidate solution that reproduces random consistent points."""
    candidates = [sp.simplify(c) for c in candidates]
    if len(candidates) == 1:
        return candidates[0]
    score = [0] * len(candidates)
    for _ in range(6):
        values, truth = sampler.point(functions, orders, constants)
        tv = truth[unknown]
        for i, c in enumerate(candidates):
            try:
                val = complex(sp.N(c.xreplace(values)))
            except (TypeError, ValueError, ZeroDivisionError):
                continue
            if abs(val.imag) < 1e-9 and abs(val.real - tv) <= 1e-7 * (1 + abs(tv)):
                score[i] += 1
    best = max(score)
    if best == 0:
        raise FlatnessError(
            f"equation {eq_text}: none of the {len(candidates)} solutions for {unknown} "
            f"({', '.join(map(str, candidates))}) is consistent with the bounds given")
    winners = [c for c, s in zip(candidates, score) if s == best]
    return min(winners, key=sp.count_ops)


# ---------------------------------------------------------------------------------------
# public entry point
# ---------------------------------------------------------------------------------------
def flatten(model: Model, outputs: Sequence[str] | None = None,
            bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
            parameter_values: Mapping[str | sp.Symbol, float] | None = None,
            max_outputs: int | None = None) -> FlatMap:
    """Eliminate states and controls of ``model`` through flat outputs.

    Parameters
    ----------
    model : the model.
    outputs : state names to use as outputs; ``None`` searches subsets of the states of
        size 1 .. ``max_outputs`` (default: number of controls + 1) and keeps the one with
        the fewest residual equations plus uneliminated states (then the fewest outputs).
    bounds : name -> (lo, hi) of states/controls, used to choose solution branches
        (e.g. a speed that must be positive, an angle in [-pi/2, pi/2]).
    parameter_values : numbers for parameters (default: the model's defaults); those
        left symbolic stay symbols in the expressions.

    Raises
    ------
    FlatnessError : nothing can be eliminated, or a control cannot be expressed; the
        message names the dynamics equation that blocks the elimination.
    """
    bounds = dict(bounds or {})
    pv: dict[sp.Symbol, float] = dict(model.default_parameters())
    for k, v in (parameter_values or {}).items():
        pv[model.symbol(k) if isinstance(k, str) else k] = v
    if outputs is not None:
        names = {s.name: s for s in model.states}
        unknown = [o for o in outputs if o not in names]
        if unknown:
            raise FlatnessError(f"outputs {unknown} are not states of {model.name!r}; "
                                f"states: {list(names)}")
        return _flatten_with(model, tuple(names[o] for o in outputs), bounds, pv)

    max_outputs = max_outputs or min(model.n_states, model.n_controls + 1)
    best, best_key, errors = None, None, []
    for size in range(1, max_outputs + 1):
        for combo in itertools.combinations(model.states, size):
            try:
                fm = _flatten_with(model, combo, bounds, pv)
            except FlatnessError as e:
                errors.append(f"{[s.name for s in combo]}: {e}")
                continue
            key = (len(fm.residuals) + len(fm.remaining_states), size,
                   sum(fm.orders.values()), sum(y.name not in model.positions for y in combo))
            if best_key is None or key < best_key:
                best, best_key = fm, key
        if best is not None and best_key[0] == 0:
            break
    if best is None:
        raise FlatnessError(f"model {model.name!r} cannot be reduced by any set of up to "
                            f"{max_outputs} states:\n  " + "\n  ".join(errors))
    return best


def _flatten_with(model: Model, outputs: tuple[sp.Symbol, ...], bounds, pv) -> FlatMap:
    numbers = {k: sp.Float(v) for k, v in pv.items()}
    f = {x: model.expand(model.dynamics[x]) for x in model.states}
    unknown_syms = set(model.states) | set(model.controls)
    known: dict[sp.Symbol, sp.Expr] = {y: y for y in outputs}
    orders: dict[sp.Symbol, int] = {y: 0 for y in outputs}
    constants: dict[sp.Symbol, sp.Symbol] = {}
    quad: dict[sp.Symbol, sp.Expr] = {}      # quadrature state -> closed form
    rates: dict[sp.Symbol, sp.Expr] = {}     # quadrature state -> its rate
    pending = [x for x in model.states]          # equations not yet used
    used: list[str] = []
    residuals: list[Residual] = []
    sampler = _Sampler(model, {x: e.xreplace(numbers) for x, e in f.items()}, bounds, numbers)

    def current(x: sp.Symbol) -> sp.Expr:
        """Equation x' - f(x, u) = 0 with known quantities substituted."""
        lhs = _total_derivative(known[x], outputs, orders, rates)
        return lhs - f[x].xreplace(known)

    def unknowns_of(e: sp.Expr) -> set:
        return {s for s in e.free_symbols if s in unknown_syms and s not in known}

    def choose(u, cands, text):
        return _choose(u, cands, sampler, outputs, orders, constants, text)

    progress = True
    while progress:
        progress = False
        # 1. quadrature states
        for x in list(pending):
            if x not in known and not (f[x].free_symbols & unknown_syms):
                c = sym(f"{x.name}_t0")
                constants[c] = x
                quad[x] = c + sp.integrate(f[x], (TIME, 0, TIME))
                rates[x] = f[x]
                known[x] = x
                pending.remove(x)
                used.append(_eq_name(x))
                progress = True
        eqs = {x: current(x) for x in pending if x in known}
        # 2. single unknown
        for x, e in eqs.items():
            unk = unknowns_of(e)
            if len(unk) != 1:
                continue
            (u,) = unk
            if trig_angle([e], unk) is not None:
                continue  # handled with its partner equation (rule 3)
            sols = [d[u] for d in solve_limited(e, [u]) if u in d]
            if not sols:
                continue
            known[u] = choose(u, sols, f"{_eq_name(x)} = {f[x]}")
            pending.remove(x)
            used.append(_eq_name(x))
            progress = True
            break
        if progress:
            continue
        # 3. trigonometric pair
        eqs = {x: current(x) for x in pending if x in known}
        for c in sorted({s for e in eqs.values() for s in unknowns_of(e)}, key=lambda s: s.name):
            group = {x: e for x, e in eqs.items() if e.has(c)}
            if len(group) < 2:
                continue
            if trig_angle(list(group.values()), {c}) is None:
                continue
            others = set().union(*(unknowns_of(e) for e in group.values())) - {c}
            if len(others) > 1:
                continue
            S, C = sp.Dummy("S"), sp.Dummy("C")
            sub = {sp.sin(c): S, sp.cos(c): C}
            lin = [e.xreplace(sub) for e in group.values()]
            unk = [S, C, *sorted(others, key=lambda s: s.name)]
            src = tuple(_eq_name(x) for x in group)
            if len(lin) >= len(unk):        # over-determined: sin^2 + cos^2 = 1 is left over
                sol = solve_linear(lin[:len(unk)], unk)
                if sol is None:
                    continue
                rest = [sp.simplify(e.xreplace(sol)) for e in lin[len(unk):]]
                resid = sol[S] ** 2 + sol[C] ** 2 - 1
                residuals.append(Residual(resid, "algebraic", src))
                residuals.extend(Residual(r, "algebraic", src) for r in rest if r != 0)
            else:
                # polar pair: sin c and cos c both multiplied by the other unknown o
                # (x' = v cos psi, y' = v sin psi): solve for P = o S, Q = o C, then
                # o = +-sqrt(P^2 + Q^2) by the bounds
                (o,) = others
                P, Q = sp.Dummy("P"), sp.Dummy("Q")
                pq = [sp.expand(e.xreplace({S: P / o, C: Q / o})) for e in lin]
                if any(e.has(o) for e in pq):
                    continue
                sol_pq = solve_linear(pq, [P, Q])
                if sol_pq is None:
                    continue
                norm = sp.sqrt(sol_pq[P] ** 2 + sol_pq[Q] ** 2)
                o_val = choose(o, [norm, -norm], " and ".join(src))
                known[o] = o_val
                sol = {S: sol_pq[P] / o_val, C: sol_pq[Q] / o_val}
                if o_val == norm:   # positive factor: atan2 of the numerators only
                    sol = {S: sol_pq[P], C: sol_pq[Q]}
            known[c] = sp.atan2(sol[S], sol[C])
            for x in group:
                pending.remove(x)
                used.append(_eq_name(x))
            progress = True
            break
        if progress:
            continue
        # 4. two equations in the same two unknowns
        eqs = {x: current(x) for x in pending if x in known}
        for (x1, e1), (x2, e2) in itertools.combinations(eqs.items(), 2):
            unk = unknowns_of(e1) | unknowns_of(e2)
            if len(unk) != 2:
                continue
            sols = solve_limited([e1, e2], sorted(unk, key=lambda s: s.name))
            if not sols:
                continue
            text = f"{_eq_name(x1)} and {_eq_name(x2)}"
            cands = {u: [s[u] for s in sols if u in s and not s[u].has(*unk)] for u in unk}
            if not all(cands.values()):
                continue
            for u in sorted(unk, key=lambda s: s.name):
                known[u] = choose(u, cands[u], text)
            pending.remove(x1)
            pending.remove(x2)
            used += [_eq_name(x1), _eq_name(x2)]
            progress = True
            break

    # what is left
    blocked_controls = [u for u in model.controls if u not in known]
    remaining = [x for x in model.states if x not in known]
    eliminated = [s for s in (*model.states, *model.controls) if s in known and s not in outputs]
    if not eliminated:
        blockers = "; ".join(f"{_eq_name(x)} = {f[x]}" for x in pending) or "none"
        raise FlatnessError(
            f"model {model.name!r} cannot be reduced with outputs {[y.name for y in outputs]}: "
            f"no state or control can be expressed through them; blocking equation(s): {blockers}")
    if blocked_controls:
        where = [f"{_eq_name(x)} = {f[x]}" for x in pending
                 if f[x].free_symbols & set(blocked_controls)]
        raise FlatnessError(
            f"model {model.name!r} with outputs {[y.name for y in outputs]}: control(s) "
            f"{[u.name for u in blocked_controls]} cannot be expressed through the outputs; "
            f"blocking equation(s): {'; '.join(where) or 'none'}")
    functions = tuple(outputs) + tuple(remaining)
    for x in remaining:
        orders[x] = 0
        known[x] = x
    for x in list(pending):
        e = _total_derivative(known[x], functions, orders, rates) - f[x].xreplace(known)
        if sp.expand(e) == 0:
            continue
        kind = "differential" if any(e.has(derivative_symbol(r, k)) for r in remaining
                                     for k in range(orders.get(r, 0) + 1)) else "algebraic"
        residuals.append(Residual(e, kind, (_eq_name(x),)))
    # orders actually needed
    all_exprs = [*known.values(), *(r.expr for r in residuals)]
    final_orders = {}
    for y in functions:
        final_orders[y] = max([k for k in range(orders.get(y, 0) + 2)
                               if any(e.has(derivative_symbol(y, k)) for e in all_exprs)] or [0])
    def num(e: sp.Expr) -> sp.Expr:
        return e.xreplace(quad).xreplace(numbers)

    return FlatMap(
        model=model, outputs=tuple(outputs), functions=functions, orders=final_orders,
        states={x: num(known[x]) for x in model.states},
        controls={u: num(known[u]) for u in model.controls},
        residuals=tuple(Residual(num(r.expr), r.kind, r.source) for r in residuals),
        constants=constants, parameter_values=pv,
        eliminated_equations=tuple(used),
    )
