"""Why a solve cannot start or cannot succeed, in the problem file's terms.

The rows of a pseudospectral NLP are named by where they come from: the dynamics of a state
at a node of a phase, a path constraint at a node, a boundary constraint or link (with its
text and line). :func:`nonfinite_at_start` names what is NaN or infinite at the initial
guess before Ipopt starts; :func:`violated` ranks what a point (Ipopt's point of local
infeasibility) leaves unmet; :func:`diverging` says when an objective ran away.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


def describe_row(tr, con) -> str:
    """A constraint of the transcription's Pyomo model, in the problem file's words."""
    for pb in tr.phases:
        ph = pb.phase
        block = pb.block
        if con.parent_component() is getattr(block, "defect", None):
            k, i, j = con.index()
            return f"the dynamics of {ph.states[j].name} (phase {ph.name}, segment {k}, node {i})"
        if con.parent_component() is getattr(block, "end", None):
            k, j = con.index()
            return f"the dynamics of {ph.states[j].name} (phase {ph.name}, end of segment {k})"
        if con.parent_component() is getattr(block, "path", None) and ph.path:
            n = con.index()
            c = ph.path[n % len(ph.path)]
            return f"path constraint `{c.text}`{_line(c)} (phase {ph.name}, node {n // len(ph.path)})"
    if con.parent_component() is getattr(tr.model, "boundary", None):
        i = con.index() - 1                     # a ConstraintList counts from 1
        if 0 <= i < len(tr.boundary_general):
            c = tr.boundary_general[i]
            return f"`{c.text}`{_line(c)}"
    return con.name


def _line(c) -> str:
    return f" (line {c.line})" if getattr(c, "line", None) else ""


def nonfinite_at_start(tr, nlp) -> str | None:
    """What is NaN or infinite at the NLP's starting point (the objective, or the first
    rows by origin), or None when everything is finite."""
    x0 = np.asarray(nlp.x0, float)
    parts = []
    with np.errstate(all="ignore"):
        try:
            f = float(nlp.objective(x0))
        except (ArithmeticError, ValueError):
            f = math.nan
        try:   # the rows' own values where the NLP has them: a raised error would blame every row
            g = np.asarray(getattr(nlp, "constraint_values", nlp.constraints)(x0), float)
        except (ArithmeticError, ValueError):
            g = np.full(nlp.m, math.nan)
    if not math.isfinite(f):
        parts.append(f"the objective `{tr.problem.objective.text}` is {f}")
    bad = np.flatnonzero(~np.isfinite(g))
    seen: dict[str, int] = {}
    for r in bad:
        where = describe_row(tr, nlp.rows[r])
        key = where.split(" (")[0]
        if key not in seen:
            seen[key] = 0
            parts.append(f"{where} is {g[r]}")
        seen[key] += 1
        if len(seen) >= 5:
            break
    if not parts:
        return None
    more = f" ({len(bad)} constraint rows in all)" if len(bad) > len(seen) else ""
    try:
        culprit = domain_at_guess(tr, objective=not math.isfinite(f), rows=[nlp.rows[r] for r in bad[:50]])
    except Exception:  # the hint must never hide the message
        culprit = None
    hint = (f": {culprit}" if culprit else
            ": change the guess (guess:) or bound the variables so that every expression is defined "
            "there (e.g. no division by a state that starts at 0)")
    return ("the initial guess gives a value that is not a number: " + "; ".join(parts) + more +
            ". Ipopt was not started" + hint)


def _domain_of(sub, derivative: bool = False):
    """(argument, what it must be, test of a bad value) for a function of ``sub``'s kind that is
    not defined everywhere (``derivative``: whose derivative is not: sqrt at 0), else None."""
    import sympy as sp

    if derivative:
        if isinstance(sub, sp.Pow) and sub.exp.is_number and not sub.exp.is_integer and 0 < sub.exp < 1:
            return sub.base, "> 0", lambda a: a <= 0
        return None

    if isinstance(sub, sp.log):
        return sub.args[0], "> 0", lambda a: a <= 0
    if isinstance(sub, (sp.asin, sp.acos)):
        return sub.args[0], "in [-1, 1]", lambda a: abs(a) > 1
    if isinstance(sub, sp.Pow) and sub.exp.is_number:
        if not sub.exp.is_integer:          # sqrt, x**1.5: complex below 0 (and 0**-0.5)
            return (sub.base, ">= 0", lambda a: a < 0) if sub.exp > 0 else (sub.base, "> 0", lambda a: a <= 0)
        if sub.exp < 0:
            return sub.base, "!= 0", lambda a: a == 0
    return None


def root_of_zero_at_guess(tr) -> str | None:
    """A square root (any power in (0, 1)) of something the guess makes 0 in the objective,
    its integrands or the phases' dynamics and path constraints: the ASL of the PyNumero route
    ends the process on its infinite derivative (sqrt(integral(u**2)) with u = 0)."""
    rows = [c for pb in tr.phases for c in (getattr(pb.block, "defect", None), getattr(pb.block, "path", None))
            if c is not None]
    return domain_at_guess(tr, objective=True, rows=rows, derivative=True)


def domain_at_guess(tr, objective: bool, rows=(), derivative: bool = False) -> str | None:
    """The first log/sqrt/power/asin of the expressions that are NaN at the guess (the
    objective's integrands and Mayer term, the rows' dynamics and path constraints) whose
    argument leaves its domain there, in the file's words: which expression, which phase,
    where, and its value; None when no such function is found."""
    import numpy as np
    import pyomo.core as pyo
    import sympy as sp

    from ..symbolic.model import TIME
    from ..transcribe.solution import control_on_state_nodes, node_values, phase_times

    scalars = {}
    for s, v in tr.scalars.items():
        try:
            scalars[s] = float(pyo.value(v, exception=False))
        except (ValueError, ArithmeticError, TypeError):
            pass
    candidates = []       # (expression, phase block or None, what it is)
    for pb in tr.phases:
        ph = pb.phase
        rhs = ph.rhs()
        wanted = {con.parent_component() for con in rows}
        for j, x in enumerate(ph.states):
            if getattr(pb.block, "defect", None) in wanted or getattr(pb.block, "end", None) in wanted:
                candidates.append((rhs[j], pb, f"the dynamics of {x.name}"))
        if getattr(pb.block, "path", None) in wanted:
            candidates += [(c.expr, pb, f"path constraint `{c.text}`{_line(c)}") for c in ph.path]
        if objective:
            candidates += [(e, pb, "the objective's integral") for e in ph.integrals.values()]
    if objective:
        candidates.append((tr.problem.objective.expr, None, "the objective"))
    for expr, pb, what in candidates:
        env = dict(scalars)
        times = None
        if pb is not None:
            X, U = node_values(pb)
            t0, tf = phase_times(pb)
            times = t0 + (tf - t0) * pb.layout.s_state
            Us = control_on_state_nodes(pb, U)
            env.update({s: X[:, j] for j, s in enumerate(pb.phase.states)})
            env.update({c: Us[:, j] for j, c in enumerate(pb.phase.controls)})
            env[TIME] = times
        for sub in sp.preorder_traversal(expr):
            dom = _domain_of(sub, derivative)
            if dom is None:
                continue
            arg, need, is_bad = dom
            syms = sorted(arg.free_symbols, key=str)
            if any(s not in env for s in syms):
                continue
            with np.errstate(all="ignore"):
                vals = np.broadcast_to(np.asarray(sp.lambdify(syms, arg, "numpy")(*[env[s] for s in syms]),
                                                  float), times.shape if times is not None else ())
                badness = np.atleast_1d(is_bad(vals) & np.isfinite(vals))
            if not badness.any():
                continue
            i = int(np.argmax(badness))
            where = f" at t = {times[i]:.4g} (phase {pb.phase.name})" if times is not None else ""
            value = float(np.atleast_1d(vals)[i])
            # the file's words: integral(u**2), not the NLP's symbol for it
            words = {q: sp.Function("integral")(e) for p_ in tr.phases for q, e in p_.phase.integrals.items()}
            shown = sp.sstr(arg.xreplace(words))
            return (f"{what} has `{sp.sstr(sub.xreplace(words))}`, which needs {shown} {need}, and the guess gives "
                    f"{shown} = {value:.4g}{where}. Give a guess where {shown} {need} (`guess:` of the "
                    f"phase), or bounds on the variables that keep it so")
    return None


def violated(tr, nlp, x, top: int = 5) -> list[tuple[str, float]]:
    """The constraints ``x`` violates most, one entry per origin (a constraint's text, or
    the dynamics of a state in a phase), largest violation first."""
    with np.errstate(all="ignore"):
        g = np.asarray(nlp.constraints(np.asarray(x, float)), float)
    gl, gu = np.asarray(nlp.gl, float), np.asarray(nlp.gu, float)
    excess = np.maximum(np.maximum(gl - g, g - gu), 0.0)
    excess[~np.isfinite(excess)] = np.inf
    worst: dict[str, tuple[str, float]] = {}
    for r in np.argsort(-excess):
        if excess[r] <= 1e-6 or len(worst) >= top:
            break
        where = describe_row(tr, nlp.rows[r])
        key = where.split(" (phase")[0].split(" (segment")[0]
        if key not in worst:
            worst[key] = (where, float(excess[r]))
    return list(worst.values())


def infeasibility_message(tr, nlp, x) -> str:
    rows = violated(tr, nlp, x)
    if not rows:
        return ""
    listed = "; ".join(f"{where} off by {v:.3g}" for where, v in rows)
    return (f" Constraints that Ipopt could not meet (largest violation at its point of local "
            f"infeasibility): {listed}.")


def diverging(history: list[tuple[int, float, float, float]], sign: float = 1.0) -> str:
    """A hint when the objective ran away (its size grew a thousandfold and was still
    growing over the last fifth of the iterations, or passed 1e12): probably unbounded.
    ``sign``: -1 for a maximisation, whose history Ipopt kept negated (the message shows the
    objective as the file writes it)."""
    if len(history) < 10:
        return ""
    first, last = abs(history[0][1]), abs(history[-1][1])
    late = abs(history[int(0.8 * len(history))][1])
    # still growing, or stuck where Ipopt's numbers run out (about 1e19 is its infinity)
    if math.isfinite(last) and last > 1e3 * max(first, 1.0) and (last > 1.01 * late or last > 1e12):
        shown = [sign * history[k][1] + 0.0 for k in (0, -1)]       # + 0.0: never "-0"
        return (f" The objective went from {shown[0]:.6g} to {shown[1]:.6g}: the problem is "
                "probably unbounded (bound the final time, the states or the controls, or check the "
                "objective's sense).")
    return ""


def local_hint(starts: int = 1) -> str:
    """What to try when Ipopt found no feasible point from the ``starts`` it was given."""
    more = "`method: {starts: 4}`" if starts < 4 else f"more starts than the {starts} tried (`method: {{starts: {2 * starts}}}`)"
    return ("Ipopt could not find a feasible point from this guess; that does not show the problem "
            "infeasible. Try `guess: {random: true, seed: 1}`, a guess block for the controls "
            f"(values away from 0 where the dynamics multiply a control by a state), or {more}.")


def max_violation(tr) -> float:
    """The largest violation of the model's constraints at its current values, each relative
    to max(1, |bound|): whether a solve Ipopt called optimal really meets them."""
    import pyomo.core as pyo

    worst = 0.0
    for con in tr.model.component_data_objects(pyo.Constraint, active=True):
        body = pyo.value(con.body, exception=False)
        if body is None or not math.isfinite(body):
            return math.inf
        for bound, sign in ((con.lower, -1.0), (con.upper, 1.0)):
            if bound is None:
                continue
            b = float(pyo.value(bound))
            worst = max(worst, sign * (body - b) / max(1.0, abs(b)))
    return worst


@dataclass
class Elastic:
    """The diagnosis of a locally infeasible solve: its ``message``, and ``feasible``, the
    relaxed model whose solution meets every relaxed condition (a feasible point of the
    problem itself, built on the same meshes), or None."""
    message: str
    feasible: Any = None


def copy_values(source, target) -> None:
    """The values of the Pyomo model ``source`` into the variables of ``target`` with the
    same names (a model built from the same meshes and phases, which may have variables of
    its own that ``target`` lacks). A variable of ``target`` that ``source`` lacks is an
    error: the models differ."""
    import pyomo.core as pyo

    values = {v.name: v.value for v in source.component_data_objects(pyo.Var, descend_into=True)}
    for b in target.component_data_objects(pyo.Var, descend_into=True):
        if b.name not in values:
            raise ValueError(f"the models differ: {b.name} is not in the source model")
        if values[b.name] is not None and not b.fixed:
            b.set_value(values[b.name], skip_validation=True)


def elastic(problem, meshes, starts, options: dict | None = None, tried: str = "the guess",
            n_starts: int = 1) -> Elastic:
    """Which boundary equalities (boundary conditions, links) cannot be met: solve again with
    each of them relaxed by a pair of nonnegative slacks whose sum is the objective (dynamics,
    bounds, path constraints and boundary inequalities kept), from each guess of ``starts`` (a
    list of {phase: PhaseGuess}), and name those the best relaxed solution leaves unmet, with
    the closest value the rest of the problem allows. ``tried`` says which starts of the
    problem itself ended infeasible (``n_starts`` of them from ``method.starts``). A relaxed
    solve that meets every condition is a feasible point of the problem itself: returned as
    ``feasible``, for the caller to solve the problem from. Only a relaxed solve that Ipopt
    solved and that meets its own constraints (:func:`max_violation`) is quoted; every
    statement is a local one (a solver cannot prove infeasibility), and an inconclusive
    diagnosis says so."""
    import dataclasses

    import pyomo.core as pyo
    import sympy as sp

    from ..symbolic.problem import FreeParameter, Objective
    from ..transcribe.pseudospectral import build
    from . import ipopt

    head = f" From {tried} Ipopt converged to a point of local infeasibility."
    equalities = [c for c in problem.boundary if c.is_equality]
    if not equalities:
        return Elastic(head + " " + local_hint(n_starts))
    # elastic mode: each equality gets a pair of nonnegative slacks, c = lower + p - n, and
    # the objective is their sum, an exact L1 norm of the residuals that stays smooth (it
    # leaves few conditions unmet, where least squares would spread the violation over all
    # of them; a smoothed |r| made Ipopt take over 1,000 iterations near r = 0)
    free = dict(problem.free_parameters)
    elastic_rows, total = [], sp.Integer(0)
    for i, c in enumerate(equalities):
        p, n = sp.Symbol(f"elastic_plus_{i}"), sp.Symbol(f"elastic_minus_{i}")
        free[p], free[n] = FreeParameter(p, 0.0), FreeParameter(n, 0.0)
        elastic_rows.append(dataclasses.replace(c, expr=c.expr - p + n))
        total += p + n
    relaxed = dataclasses.replace(problem, boundary=[c for c in problem.boundary if not c.is_equality] + elastic_rows,
                                  free_parameters=free,
                                  objective=Objective("minimize", total, "total boundary violation"))
    from ..transcribe.guess import make_guess

    # and from the relaxed problem's own default guess (states in the middle of their bounds,
    # not on a line between the conditions that may be what cannot be met)
    starts = list(starts) + [{ph.name: make_guess(relaxed, ph) for ph in relaxed.phases}]

    def unmet_at(values):
        out = []
        for c in equalities:
            got = float(c.expr.xreplace({s: sp.Float(values[s]) for s in c.expr.free_symbols if s in values}))
            if abs(got - c.lower) > 1e-4 * max(1.0, abs(c.lower)):
                # the relaxed solve's value, not a proof of the nearest one: it is a local
                # minimum of the violation from these starts (unseen29: a reachable waypoint,
                # every start at tf's lower bound, "the nearest feasible value x(t0) = -0.739")
                out.append(f"`{c.text}`{_line(c)} (the relaxed solve's value {sp.sstr(c.expr)} = {got:.6g})")
        return out

    best, ends = None, []
    for guesses in starts:
        try:
            tr = build(relaxed, meshes, guesses)
            info = ipopt.solve(tr.model, options, transcription=tr)
        except Exception as e:  # the diagnosis must never lose the run
            ends.append(f"failed ({type(e).__name__}: {e})")
            continue
        ends.append(info.status)
        if info.status not in ("optimal", "acceptable") or max_violation(tr) > 1e-6:
            continue
        values = {s: float(pyo.value(v)) for s, v in tr.scalars.items()}
        unmet = unmet_at(values)
        if not unmet:
            # a point that meets every condition: a feasible point of the problem itself,
            # so the later starts cannot tell more
            return Elastic(head + " Yet with the boundary conditions and links relaxed, Ipopt found a point "
                           "that meets all of them: the problem is feasible. " + local_hint(n_starts), tr.model)
        if best is None or info.objective < best[0]:
            best = (info.objective, unmet)
    if best is None:
        if all(e == "infeasible" for e in ends):
            return Elastic(head + f" With every boundary condition and link relaxed, Ipopt still found no point "
                           f"that meets the bounds, path constraints and boundary inequalities together with the "
                           f"dynamics ({len(ends)} relaxed solve(s), each from one of those starts).")
        return Elastic(head + " The relaxed re-solve (boundary conditions and links as penalties) ended "
                       + ", ".join(f"'{e}'" for e in ends) + ", so which conditions cannot be met is not known. "
                       + local_hint(n_starts))
    return Elastic(head + " The boundary conditions cannot all be met from these starts: relaxed to their "
                   f"smallest total violation (best of {len(ends)} relaxed solve(s), each verified to meet the "
                   "dynamics, bounds and path constraints), the problem leaves " + "; ".join(best[1]) + " unmet.")
