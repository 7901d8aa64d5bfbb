"""Hints appended to the message of a failed solve (Ipopt's `error`, `max_iter`, `diverged`)
when the problem file shows a likely cause that is cheap to detect: variables of very
different magnitudes without `scaling: {mode: auto}`, abs() where Ipopt needs derivatives, a
minimum-time problem whose controls nothing bounds. Each is worded as a likely cause, never
as a diagnosis, and none is added to a solve that succeeded."""
from __future__ import annotations

import math

import sympy as sp

FAILED = ("error", "max_iter", "diverged")

#: the spread of typical magnitudes (largest / smallest over states, controls and free times,
#: at the start, by ocdsl/solve/scaling.py's rules) from which a failed unscaled solve is told
#: to try `scaling: {mode: auto}`. Zermelo in metres and seconds (restoration failed) spreads
#: 1.0e4; files in configs/ that solve unscaled reach 2.3e5 (mesh_shuttle.yaml), so the hint
#: is only ever given to a failure
BADLY_SCALED = 1e3


def failure_hints(file, tr, status: str) -> str:
    if status == "acceptable":
        # exit 1 on a right answer that the rounding of large variables kept from Ipopt's tol
        # (unseen61 F1: an altitude of 6.5e6 m in a `mesh:` run, tol 1e-10, J right to 8e-15,
        # "acceptable" on every mesh with no word why)
        try:
            spread = "" if file.spec.scaling.mode == "auto" else _spread(tr)
        except Exception:  # a hint must never lose the run
            return ""
        return f" Ipopt met only its acceptable level, not its `tol`: {spread}" if spread else ""
    if status not in FAILED:
        return ""
    out = ""
    for hint in (_scaling, _nonsmooth, _unbounded_controls, _unanchored_states):
        try:
            out += hint(file, tr)
        except Exception:  # a hint must never lose the run
            pass
    return out


def _scaling(file, tr) -> str:
    if file.spec.scaling.mode == "auto":
        return _sizeless(file, tr)
    spread = _spread(tr)
    return f" {spread[0].upper()}{spread[1:]}" if spread else ""


def _spread(tr) -> str:
    """The sentence on the variables' spread of typical magnitudes and its remedy, lower case,
    where they span ``BADLY_SCALED`` or more at the start; empty otherwise."""
    if tr.start_spread is None:
        return ""
    ratio, hi, lo = tr.start_spread
    if not ratio >= BADLY_SCALED:
        return ""
    return (f"the variables' typical magnitudes span {ratio:.1e} ({hi} against {lo}, from their bounds "
            "or guesses): try `scaling: {mode: auto}` (docs/problem-language.md, \"Scaling\"), or write the "
            "problem in units where they are of order 1.")


def _sizeless(file, tr) -> str:
    """Auto scaling divides each variable by its size from bounds or guesses; one with neither
    is taken as 1, which beside a radius of 3e7 m is no scaling at all (unseen20: SI orbit
    raising, v_r unbounded with no guess, 3000 iterations and no hint)."""
    names = list(tr.start_sizeless)
    if not names or tr.start_spread is None:
        return ""
    ratio, hi, _ = tr.start_spread
    if not ratio >= BADLY_SCALED:
        return ""
    shown = ", ".join(names[:4]) + (" ..." if len(names) > 4 else "")
    return (f" `scaling: {{mode: auto}}` found no size for {shown} (no finite bound, no guess but 0) and "
            f"took 1, against {hi}'s {ratio:.1e}: give a bound or a guess of its size, or "
            f"`scaling: {{mode: auto, variables: {{{names[0]}: ...}}}}`.")


def _nonsmooth(file, tr) -> str:
    """abs() in the dynamics, a path constraint or the Mayer term: Ipopt's Newton steps need
    derivatives, which abs() lacks at 0, where an L1 optimum (fuel, miss distance) sits."""
    problem = file.problem
    where = []
    for ph in problem.phases:
        rhs = ph.rhs()
        where += [f"the dynamics of {x.name}" for j, x in enumerate(ph.states) if rhs[j].has(sp.Abs)]
        where += [f"`{c.text}`" for c in ph.path if c.expr.has(sp.Abs)]
    where += [f"`{c.text}`" for c in problem.boundary if c.expr.has(sp.Abs)]
    if problem.objective is not None and problem.objective.expr.has(sp.Abs):
        where.append("the objective")
    if not where:
        return ""
    return (f" abs() in {', '.join(dict.fromkeys(where))} has no derivative at 0, where an L1 optimum sits "
            "(Ipopt needs derivatives): split a control into positive and negative parts (controls "
            "[up, um], 0 <= up, 0 <= um, the dynamics in up - um, a fuel rate up + um), or write "
            "abs(e) in the objective as a free parameter p with e <= p and -e <= p "
            "(docs/problem-language.md, \"Non-smooth costs\").")


def _unbounded_controls(file, tr) -> str:
    """A phase whose free final time the objective minimises, with controls that no bound or
    path constraint limits: the infimum is then often tf -> t0 with |u| growing, not attained."""
    import pyomo.core as pyo

    from ..transcribe.solution import periodic_controls

    problem = file.problem
    obj = problem.objective
    if obj is None or obj.sense != "minimize":
        return ""
    for ph, pb in zip(problem.phases, tr.phases):
        if ph.tf is None and ph.tf_symbol in obj.expr.free_symbols:
            in_path = set().union(*[c.expr.free_symbols for c in ph.path]) if ph.path else set()
            angles = {ph.controls[j] for j in periodic_controls(ph)}     # a heading in sin/cos is bounded
            free = [c.name for c in ph.controls
                    if not any(math.isfinite(b) for b in ph.bounds_of(c)) and c not in in_path | angles]
            if not free:
                continue
            t0, tf = float(pyo.value(pb.block.t0)), float(pyo.value(pb.block.tf))
            return (f" The objective shortens phase '{ph.name}', whose control{'s' * (len(free) > 1)} "
                    f"{', '.join(free)} nothing bounds: the duration can shrink towards 0 with the controls "
                    f"growing (the last iterate: tf - t0 = {tf - t0:.3g}); is a bound on a control missing "
                    f"(e.g. -1 <= {free[0]} <= 1)?")
    return ""


def _unanchored_states(file, tr) -> str:
    """A state that nothing anchors: no bound, in no right-hand side, integrand or path
    constraint, and every boundary condition unchanged when both its ends shift together
    (`x(tf) == x(t0)` only). Every shift of it is then another solution, the NLP's KKT matrix
    is singular along it, and Ipopt may wander to max_iter (unseen21 FA8: a periodic loop,
    13 of 17 meshes; with `x(t0) == 0` it solved at once)."""
    problem = file.problem
    shift = sp.Symbol("ocdsl_shift")
    out = []
    for ph in problem.phases:
        used = set().union(*(sp.sympify(e).free_symbols for e in ph.rhs()))
        used |= set().union(*(ph.substitute(e).free_symbols for e in ph.integrals.values()), set())
        used |= set().union(*(ph.substitute(c.expr).free_symbols for c in ph.path), set())
        for x in ph.states:
            if x in used or any(math.isfinite(b) for b in ph.bounds_of(x)):
                continue
            ends = {s for s, bv in problem.boundary_values.items() if bv.phase == ph.name and bv.var == x}
            exprs = [c.expr for c in problem.boundary] + ([problem.objective.expr] if problem.objective else [])
            moved = {s: s + shift for s in ends}
            if ends and all(sp.simplify(e.subs(moved) - e) == 0 for e in exprs if e.free_symbols & ends):
                out.append(x.name if len(problem.phases) == 1 else f"{ph.name}.{x.name}")
    if not out:
        return ""
    return (f" Nothing fixes the level of {', '.join(out)}: no bound, no condition on one end alone, and it "
            "enters no right-hand side, integrand or path constraint, so every shift of it is another "
            f"solution and the NLP is singular along it; fix one end (e.g. {out[0].split('.')[-1]}(t0) == 0).")
