"""Constraints of a problem file: relations classified as bounds, path or boundary
constraints, links and `continuous(...)`, and the checks that they can be met and resolved."""
from __future__ import annotations

import math
import zlib

import sympy as sp

from ...hints import did_you_mean
from ...symbolic.model import TIME, sym
from ...symbolic.problem import INF, Constraint, Objective, Phase
from ..errors import Issue
from ..expr import parse_relation
from .common import MAX_CONSTRAINTS, _is_number


class ConstraintCompiler:
    """The compiler's constraint part (mixed into :class:`~.compiler.Compiler`)."""

    def continuity(self, phases: list[Phase], names: list[str], states: list[str] | None, text: str,
                   loc: tuple) -> list[Constraint]:
        """``continuous(a, b, ..., [x, y])``: for each consecutive pair, a.tf == b.t0 and each
        named state (vectors by component; default: every state both phases have) equal
        across the junction, as if written one link each."""
        by_name = {p.name: p for p in phases}
        unknown = [n for n in names if n not in by_name]
        if unknown:
            self.issue(loc, f"unknown phase '{unknown[0]}'" + did_you_mean(unknown[0], by_name), text)
            return []
        out: list[Constraint] = []
        for a, b in zip(names, names[1:]):
            pa, pb = by_name[a], by_name[b]
            shared = [s.name for s in pa.states if s.name in {x.name for x in pb.states}]
            chosen = shared if states is None else []
            for n in states or []:
                vector = pa.model.vectors.get(n)
                comps = [c.name for c in vector] if vector is not None else [n]
                missing = [c for c in comps if c not in shared]
                if missing:
                    self.issue(loc, f"'{n}' is not a state of both '{a}' and '{b}'"
                               + did_you_mean(n, shared + list(pa.model.vectors)), text)
                    return []
                chosen += comps
            if pa.tf is not None and pb.t0 is not None:
                if abs(pa.tf - pb.t0) > 1e-12 * max(1.0, abs(pa.tf)):
                    self.issue(loc, f"'{a}' ends at tf = {pa.tf} but '{b}' starts at t0 = {pb.t0}", text)
                    return []
            else:
                out += self.relations(None, phases, f"{a}.tf == {b}.t0", loc, link=True)
            for x in chosen:
                out += self.relations(None, phases, f"{a}.{x}(tf) == {b}.{x}(t0)", loc, link=True)
        for c in out:
            c.text = f"{c.text}   ({text})"
        return out

    def check_resolved(self, phases: list[Phase], boundary: list[Constraint], obj: Objective | None) -> None:
        """Every symbol of a boundary constraint, link or the objective is one the
        transcription has a variable for; anything else is an error at its line now (as
        `ocdsl check` reports it), not at the build."""
        known = set(self.boundary_values) | set(self.free)
        for p in phases:
            known |= {p.t0_symbol, p.tf_symbol} | set(p.integrals)
        known |= {sym(n) for n in getattr(self, "symbolic", ())}
        for c in boundary:
            left = sorted(s.name for s in c.expr.free_symbols - known)
            if left:
                self.issues.append(Issue(str(self.path), c.line, f"{', '.join(left)} cannot be used here: "
                                         "a boundary constraint or link uses boundary values, phase times, "
                                         "integrals, free parameters and constants", c.text))
        if obj is not None:
            left = sorted(s.name for s in obj.expr.free_symbols - known - {sym("objective")})
            if left:
                loc = ("problem", "objective") if self.spec.problem is not None else ("objective",)
                self.issue(loc, f"the objective uses {', '.join(left)}, which has no value here "
                           "(boundary values, phase times, integrals, free parameters and constants only)")

    def check_contradictions(self, boundary: list[Constraint], phases: list[Phase] = ()) -> None:
        """Boundary constraints on the same quantity whose ranges do not meet (x(t0) == 1 and
        x(t0) == 2), or a boundary value outside its state's own bounds (x(t0) == 1 with
        x >= 2): an error naming both, not an infeasible solve."""
        first: dict[sp.Expr, Constraint] = {}
        by_name = {p.name: p for p in phases}
        for c in boundary:
            other = first.setdefault(c.expr, c)
            if other is not c and (c.lower > other.upper or c.upper < other.lower):
                self.issues.append(Issue(str(self.path), c.line, f"contradicts `{other.text}`"
                                         + (f" (line {other.line})" if other.line else "")
                                         + ": no value meets both", c.text))
                continue
            bv = self.boundary_values.get(c.expr)
            ph = by_name.get(bv.phase) if bv is not None else None
            if ph is None or bv.var not in ph.state_bounds:
                continue
            lo, hi = ph.state_bounds[bv.var]
            side = "lo" if c.upper < lo else "hi" if c.lower > hi else None
            if side is None:
                continue
            key = ((ph.name, bv.var), side)
            text = self.bound_texts.get(key, f"the bounds of {bv.var}")
            line = self.bound_lines.get(key)
            self.issues.append(Issue(str(self.path), c.line, f"contradicts the bound `{text}`"
                                     + (f" (line {line})" if line else "")
                                     + f": {bv.var} must lie in [{lo:g}, {hi:g}] at every time, "
                                     f"{bv.which} included", c.text))

    def check_repeated(self, boundary: list[Constraint], phases: list[Phase] = ()) -> None:
        """Two boundary constraints or links that say the same thing (`a.tf == b.t0` written
        beside `continuous(a, b)`, which adds it; an equality again up to a constant factor)
        are two identical rows of the NLP: its Jacobian loses rank, Ipopt's multipliers of
        the pair grow to +-1e17 and cancel, and its convergence test, scaled by them, passed
        a point 5e-4 below a two-stage ascent's optimum as optimal (unseen9 F1). An error
        naming both; a single quantity given twice (`x(t0) == 0`, a variable's bound) is no row."""
        integrals = {s for p in phases for s in p.integrals}     # an integral is a row, not a bound
        groups: dict[frozenset, list[Constraint]] = {}
        for c in boundary:
            if not isinstance(c.expr, sp.Symbol) or c.expr in integrals:
                groups.setdefault(frozenset(c.expr.free_symbols), []).append(c)
        for group in groups.values():
            if len(group) > 1:
                self._check_repeated_among(group)

    def _check_repeated_among(self, group: list[Constraint]) -> None:
        seen: list[tuple[Constraint, tuple | None]] = []
        for c in group:
            # an equality's residual at three fixed pseudo-random points: proportional residuals
            # are one condition (numbers, not sp.cancel, which ran for minutes on Delta III's links)
            samples = _residual_samples(c) if c.is_equality else None
            for other, other_samples in seen:
                if samples is None or other_samples is None:
                    same = (c.expr == other.expr and c.lower == other.lower and c.upper == other.upper)
                else:
                    same = _proportional(samples, other_samples)
                if same:
                    said, _, added_by = other.text.partition("   (")
                    origin = f", which `{added_by[:-1]}` adds" if added_by.endswith(")") else ""
                    self.issues.append(Issue(str(self.path), c.line, f"repeats `{said.strip()}`{origin}"
                                             + (f" (line {other.line})" if other.line else "")
                                             + ": a condition given twice is two identical rows of the NLP, "
                                             "which makes its multipliers and its convergence test "
                                             "meaningless; keep one", c.text))
                    break
            else:
                seen.append((c, samples))

    def _phase_constraint_texts(self):
        spec = self.spec
        if spec.problem is not None:
            yield ("problem", "constraints"), spec.problem.constraints
        else:
            for name, ph in spec.phases.items():
                yield ("phases", name, "constraints"), ph.constraints

    def constraints(self, ph: Phase, phases, texts, loc) -> list[Constraint]:
        if len(texts) > MAX_CONSTRAINTS:
            self.issue(loc, f"{len(texts)} constraints: more than the limit of {MAX_CONSTRAINTS}")
            return []
        out: list[Constraint] = []
        for i, text in enumerate(texts):
            out += self.relations(ph, phases, text, loc + (i,))
        return out

    def relations(self, ph: Phase | None, phases, text: str, loc: tuple, link: bool = False) -> list[Constraint]:
        rels = self.guarded(loc, parse_relation, text, self.scope(ph, phases, link))
        if rels is None:
            return []
        line = self.located.line(loc)
        sub = ph.substitute if ph is not None else self.substitute_top
        parts: dict[sp.Expr, list[float]] = {}
        for r in rels:
            lhs, rhs = sub(r.lhs), sub(r.rhs)
            op = r.op
            if _is_number(rhs):
                expr, value = lhs, rhs
            elif _is_number(lhs):
                expr, value, op = rhs, lhs, {"<=": ">=", ">=": "<=", "==": "=="}[op]
            else:
                expr, value = sp.expand(lhs - rhs) if False else lhs - rhs, sp.Integer(0)
            if _is_number(expr):
                if len(rels) > 1:
                    # `u <= 1 <= 2`: the chain has variables, one of its links has none
                    self.issue(loc, f"the link `{r.lhs} {r.op} {r.rhs}` of this chain compares two "
                               "numbers: a chain puts the expression in the middle, e.g. -1 <= u <= 1", text)
                else:
                    self.issue(loc, "this relation has no variables in it", text)
                return []
            v = float(value)
            lo, hi = parts.setdefault(expr, [-INF, INF])
            if op == "==":
                if not math.isfinite(v):
                    self.issue(loc, "an equality with an infinite value", text)
                    return []
                parts[expr] = [max(lo, v), min(hi, v)]
            elif op == "<=":
                parts[expr][1] = min(hi, v)
            else:
                parts[expr][0] = max(lo, v)
        out = []
        for expr, (lo, hi) in parts.items():
            if lo > hi:
                self.issue(loc, f"empty range: lower bound {lo} above upper bound {hi}", text)
                continue
            c = self.classify(ph, expr, lo, hi, text, line, loc)
            if c is not None:
                out.append(c)
        return out

    def classify(self, ph, expr, lo, hi, text, line, loc) -> Constraint | None:
        """Box bounds go to the phase; path constraints to the phase; the rest are boundary constraints."""
        syms_ = expr.free_symbols
        if ph is not None:
            bare = syms_ & (set(ph.states + ph.controls) | {TIME})
            if bare:
                if syms_ & set(ph.integrals):
                    # an integral is one number for the whole phase; a path constraint holds at each t
                    self.issue(loc, "a constraint cannot mix an integral (one value for the whole phase) "
                               "with path values (bare states/controls/t): bound the integral alone, e.g. "
                               "integral(x) <= 1, or make it a state (q' = x) and constrain q", text)
                    return None
                if syms_ & set(self.boundary_values) or syms_ & {ph.t0_symbol, ph.tf_symbol}:
                    self.issue(loc, "a constraint cannot mix path values (bare states/controls/t) with "
                               "boundary values or t0/tf", text)
                    return None
                if expr in ph.state_bounds or expr in ph.control_bounds or expr in set(ph.states + ph.controls):
                    table = ph.state_bounds if expr in ph.states else ph.control_bounds
                    table[expr] = self.narrowed(ph, expr, table.get(expr, (-INF, INF)), lo, hi, text, loc)
                    return None
                if self.contradicted_path(ph, expr, lo, hi, text, loc):
                    return None
                ph.path.append(Constraint(expr, lo, hi, text, line))
                return None
            if expr == ph.tf_symbol or expr == ph.t0_symbol:
                which = "tf" if expr == ph.tf_symbol else "t0"
                fixed = ph.tf if which == "tf" else (None if ph.t0 is None else ph.t0)
                if fixed is not None and not (lo <= fixed <= hi):
                    self.issue(loc, f"{which} is fixed at {fixed} by `time:`, outside this range", text)
                    return None
                if which == "tf" and ph.t0 is not None and hi <= ph.t0:
                    self.issue(loc, f"tf must be greater than t0 = {ph.t0:g}; this leaves it no room", text)
                    return None
                setattr(ph, f"{which}_bounds",
                        self.narrowed(ph, expr, getattr(ph, f"{which}_bounds"), lo, hi, text, loc))
                return None
        return Constraint(expr, lo, hi, text, line)

    def contradicted_path(self, ph, expr, lo, hi, text, loc) -> bool:
        """Whether an earlier path constraint on the same expression (or its negative) leaves
        this one no value: `x + y <= 0` beside `x + y >= 1` reached Ipopt, whose failure was
        answered with "try a random guess" (unseen47 F6), where the same contradiction on a
        bare control is an error at its line."""
        for c in ph.path:
            if c.expr == expr:
                a, b = c.lower, c.upper
            elif c.expr == -expr:
                a, b = -c.upper, -c.lower
            else:
                continue
            if max(a, lo) > min(b, hi):
                self.issue(loc, f"contradicts `{c.text}`: {expr} would have to lie in "
                                f"[{max(a, lo):g}, {min(b, hi):g}] at every instant", text)
                return True
        return False

    def narrowed(self, ph, expr, old, lo, hi, text, loc) -> tuple[float, float]:
        """A later bound on the same quantity intersects the earlier ones (never replaces
        them); an empty intersection names the constraint that set the other side."""
        seen = self.bound_texts
        key = (ph.name, expr)
        new = (max(old[0], lo), min(old[1], hi))
        if new[0] > new[1]:
            other = seen.get((key, "lo" if new[0] > hi else "hi"), "an earlier bound")
            self.issue(loc, f"contradicts `{other}`: {expr} would have to lie in [{new[0]:g}, {new[1]:g}]", text)
            return old
        line = self.located.line(loc)
        if lo > old[0]:
            seen[(key, "lo")] = text
            self.bound_lines[(key, "lo")] = line
        if hi < old[1]:
            seen[(key, "hi")] = text
            self.bound_lines[(key, "hi")] = line
        return new


def _residual_samples(c: Constraint) -> tuple | None:
    """``expr - value`` of an equality at three fixed points (each symbol a value from its
    name, so both sides of a comparison see the same point); None where it is not a finite
    number at all three."""
    symbols = sorted(c.expr.free_symbols, key=str)
    out = []
    for k in range(3):
        point = {s: sp.Float(0.37 + 0.61 * (zlib.crc32(f'{s.name}/{k}'.encode()) % 9973) / 9973.0) for s in symbols}
        try:
            v = complex(sp.N(c.expr.xreplace(point) - c.lower))
        except (TypeError, ValueError):
            return None
        if v.imag != 0.0 or not math.isfinite(v.real):
            return None
        out.append(v.real)
    return tuple(out)


def _proportional(a: tuple, b: tuple) -> bool:
    """Residuals that are one nonzero constant times the other at every sample point."""
    if any(x == 0.0 for x in b) or any(x == 0.0 for x in a):
        return a == b
    ratios = [x / y for x, y in zip(a, b)]
    return all(abs(r - ratios[0]) <= 1e-10 * abs(ratios[0]) for r in ratios)
