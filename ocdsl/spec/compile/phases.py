"""Phases of a problem file: times, guesses (and chains), per-phase constants, and the
scope in which a phase's expressions, boundary values and integrals are read."""
from __future__ import annotations

import math
import re

import sympy as sp

from ...chain.check import check_guess, is_problem_file
from ...hints import did_you_mean
from ...symbolic.model import TIME, Model, sym
from ...symbolic.problem import INF, BoundaryValue, Objective, Phase, Problem
from ..errors import ExprError
from ..expr import Scope, is_vector, parse_expression
from ..schema import TimeSpec
from .common import _guess_value_ok


#: an L1 cost sits where abs() has no derivative (Ipopt stops with "error" on the first iterate
#: there, configs/mesh_bang_off_bang.yaml); refused with the smooth way to write it
NONSMOOTH_INTEGRAL = ("abs() in an integral is not differentiable at 0, where an L1 cost's optimum "
                      "sits (Ipopt stops with an error): split the control into its positive and "
                      "negative parts, e.g. controls [up, um] with 0 <= up, 0 <= um, the dynamics "
                      "in up - um and integral(up + um) (docs/problem-language.md, \"Non-smooth costs\")")


class PhaseCompiler:
    """The compiler's phase part (mixed into :class:`~.compiler.Compiler`)."""

    def time_value(self, value, constants: dict, loc: tuple) -> float | None:
        """A phase's t0 or tf: None for `free`, else the number, or the value of an expression
        of the phase's constants (`tf: T`, T a parameter; --param T=... and a study's sweep
        change it like any constant)."""
        if value == "free":
            return None
        if not isinstance(value, str):
            return float(value)
        names = {s.name: s for s in constants}
        try:
            e = parse_expression(value, Scope(names)).xreplace({s: sp.Float(v) for s, v in constants.items()})
        except ExprError as err:
            free = sorted(s.name for s in getattr(self, "free", {}) if re.search(rf"\b{re.escape(s.name)}\b", value))
            if free:
                # a known name, only not a constant (unseen34 F9: "unknown name 'T'" for a free T)
                self.issue(loc, f"`{value}`: {', '.join(free)} is a free parameter, which cannot set a time; "
                                f"write `{loc[-1]}: free` and a constraint (e.g. `{loc[-1]} == {value}` among the "
                                "phase's constraints)")
                return None
            self.issue(loc, f"`{value}`: {err.message}; a time is a number, `free`, or an expression of "
                            "the file's constant parameters" + did_you_mean(value, list(names)))
            return None      # as if free: no knock-on error (a constant objective `minimize tf`)
        if not (e.is_number and e.is_real and e.is_finite):
            free = sorted(n.name for n in e.free_symbols) if not e.is_number else []
            self.issue(loc, f"`{value}` is not a constant" + (f" ({', '.join(free)} has no value: a free "
                            "parameter cannot set a time; write `tf: free` and a constraint)" if free else ""))
            return None
        return float(e)

    def phase(self, name, model, time: TimeSpec, constraints, guess, loc, top_params, values) -> Phase | None:
        if model is None:
            return None
        multi = self.spec.phases is not None
        prefix = f"{name}." if multi else ""
        constants = {s: v for s, v in model.parameters.items() if v is not None and s not in self.free}
        constants.update({s: v for s, v in top_params.items() if v is not None})
        constants.update(self.phase_values(name, model, top_params, values, loc))
        # ``symbolic``: constants left as symbols (not folded), for a model built once with
        # them as mutable Pyomo Params and re-solved at each study point (ocdsl/solve/reuse.py)
        for s in [s for s in constants if s.name in getattr(self, "symbolic", ())]:
            del constants[s]
        for s, v in model.parameters.items():
            if v is None and s not in self.free:
                self.issue(loc, f"model parameter '{s}' has no value; give it under model: parameters:")
        t0s, tfs = sym(prefix + "t0"), sym(prefix + "tf")
        tf = self.time_value(time.tf, constants, loc + ("time", "tf"))
        t0 = self.time_value(time.t0, constants, loc + ("time", "t0"))
        if tf is not None and t0 is not None and tf <= t0:
            self.issue(loc + ("time", "tf"), f"tf = {tf} must be greater than t0 = {t0}")
        guess_items = dict(guess.model_extra or {})
        known = {s.name for s in model.states + model.controls} | {p.name for p in self.free}
        for k in guess_items:
            if k not in known:
                self.issue(loc + ("guess", k), f"guess for unknown variable '{k}'" + did_you_mean(k, known))
            elif not _guess_value_ok(guess_items[k]):
                self.issue(loc + ("guess", k), f"guess for '{k}': a finite number, a list of finite numbers "
                           "or {t: [...], values: [...]} of the same length")
            elif isinstance(guess_items[k], dict) and any(b <= a for a, b in zip(guess_items[k]["t"],
                                                                                guess_items[k]["t"][1:])):
                # t: [0, 2, 1] was taken as it came (unseen40 F5)
                self.issue(loc + ("guess", k), f"guess for '{k}': its times t must increase, "
                           f"got {guess_items[k]['t']}")
        check_guess(self.path, guess, loc, self.issue)
        # a problem file, or a transform, is a chain (ocdsl/chain): its stages give `from` at run time
        chained = guess.from_ is not None and (is_problem_file(guess.from_) or guess.transform is not None)
        guess_dict = {"values": guess_items, "t0": guess.t0, "tf": guess.tf, "from": None if chained else guess.from_,
                      "random": guess.random, "seed": guess.seed,
                      "chain": {"from": guess.from_, "transform": guess.transform, "reuse": guess.reuse,
                                "file": str(self.path)} if chained else None}
        # time runs forward: with one end fixed the other is bounded by it (a free final time
        # with nothing below it let `minimize tf` run to tf = -1e20); later bounds narrow these
        bounds = {}
        texts = self.bound_texts
        if tf is None and t0 is not None:
            bounds["tf_bounds"] = (t0, INF)
            texts[((name, tfs), "lo")] = f"tf >= t0 = {t0:g} (time runs forward)"
        if t0 is None and tf is not None:
            bounds["t0_bounds"] = (-INF, tf)
            texts[((name, t0s), "hi")] = f"t0 <= tf = {tf:g} (time runs forward)"
        return Phase(name, model, constants, t0, tf, t0s, tfs, guess=guess_dict, **bounds)

    def phase_values(self, phase: str, model: Model, top_params, values: dict, loc) -> dict[sp.Symbol, float]:
        """A phase's own values of constants of its model or of the file (``parameters:`` under
        the phase); ``--param PHASE.NAME=VALUE`` overrides one."""
        known = {s.name: s for s in model.parameters} | {s.name: s for s in top_params}
        out = {}
        for pname, value in values.items():
            where = loc + ("parameters", pname)
            s = known.get(pname)
            if s is None:
                self.issue(where, f"'{pname}' is not a parameter of phase '{phase}''s model nor of the file"
                           + did_you_mean(pname, known))
                continue
            if s in self.free:
                self.issue(where, f"'{pname}' is a free parameter: it takes one value for the whole problem")
                continue
            key = f"{phase}.{pname}"
            if key in self.overrides:
                self.file_values[key] = float(value)
                value = float(self.overrides[key])
                self.used_overrides.add(key)
            if not math.isfinite(value):
                self.issue(where, f"parameter '{pname}' is not a finite number")
                continue
            out[s] = float(value)
            self.constants_in_force[key] = float(value)
        return out

    def scope(self, ph: Phase | None, phases: list[Phase], link: bool = False) -> Scope:
        names: dict[str, sp.Basic] = {}
        if ph is not None:
            names["t"] = TIME
            for s in ph.states + ph.controls + tuple(ph.model.parameters) + tuple(ph.model.expressions):
                names[s.name] = s
            names.update(ph.model.vectors)
            names["t0"], names["tf"] = ph.t0_symbol, ph.tf_symbol
        for s in self.free:
            names[s.name] = s
        for pname in self.spec.parameters:
            names.setdefault(pname, sym(pname))
        phase_names = {p.name: {"t0": p.t0_symbol, "tf": p.tf_symbol, "phase": p} for p in phases} \
            if self.spec.phases is not None else {}

        def boundary(phase_name, var, which):
            target = ph
            if phase_name is not None:
                target = phase_names[phase_name]["phase"]
            elif target is None:
                raise ExprError(f"name the phase of {var}({which}), e.g. {phases[0].name}.{var}({which})")
            model = target.model
            if var in {s.name for s in target.states}:
                return state_at(target, var, which)
            if var in model.vectors or var in {s.name for s in model.expressions}:
                return expression_at(target, var, which)
            raise ExprError(f"'{var}' is not a state (nor a named expression) of phase '{target.name}'" +
                            did_you_mean(var, [s.name for s in target.states + tuple(model.expressions)]
                                         + list(model.vectors)))

        def state_at(target, var, which):
            label = f"{target.name}.{var}({which})" if self.spec.phases is not None else f"{var}({which})"
            s = sym(label)
            self.boundary_values[s] = BoundaryValue(target.name, target.model.symbol(var), which)
            return s

        def expression_at(target, var, which):
            """``E(tf)``: the named expression (or vector) of the states at that end."""
            model = target.model
            value = model.vectors[var] if var in model.vectors else model.symbol(var)
            parts = [target.substitute(c) for c in (value if is_vector(value) else [value])]
            used = set().union(*[p.free_symbols for p in parts])
            controls = sorted(c.name for c in used & set(target.controls))
            if controls:
                raise ExprError(f"'{var}' uses the control{'s' * (len(controls) > 1)} {', '.join(controls)}, "
                                f"which has no value at {which}: a boundary value uses states only")
            subs = {s: state_at(target, s.name, which) for s in used & set(target.states)}
            subs[TIME] = target.tf_symbol if which == "tf" else target.t0_symbol
            parts = [p.xreplace(subs) for p in parts]
            return sp.ImmutableMatrix(parts) if is_vector(value) else parts[0]

        def integral(integrand):
            target = ph
            if target is None:
                raise ExprError("integral(...) belongs to a phase; write it in the phase's objective or constraints")
            if integrand.has(*[s for p in phases for s in (p.t0_symbol, p.tf_symbol)]) or \
                    any(s in self.boundary_values for s in integrand.free_symbols):
                raise ExprError("an integrand may use states, controls, t and parameters, not boundary values")
            expanded = target.substitute(integrand)
            if expanded.has(sp.Abs):
                raise ExprError(NONSMOOTH_INTEGRAL)
            for known, e in target.integrals.items():
                if e == expanded:       # one integral, however often it is written (a constraint
                    return known        # repeated is then the same row: check_repeated, unseen10 F4)
            self.integral_count += 1
            s = sym(f"integral{self.integral_count}_{target.name}")
            target.integrals[s] = expanded
            return s

        return Scope(names, boundary, integral, {k: {"t0": v["t0"], "tf": v["tf"]} for k, v in phase_names.items()},
                     self.tables)

    def expression(self, text, ph, phases) -> sp.Expr:
        e = parse_expression(text, self.scope(ph, phases))
        return ph.substitute(e) if ph is not None else self.substitute_top(e)

    def substitute_top(self, e: sp.Expr) -> sp.Expr:
        from ...symbolic.numbers import substitute_numbers

        return substitute_numbers(e, {k: sp.Float(v) for k, v in getattr(self, "top_constants", {}).items()})

    def objective(self, text: str, ph, phases) -> Objective:
        m = re.match(r"^\s*(minimize|maximize)\s+(.+)$", str(text), re.S)
        if not m:
            first = str(text).split(maxsplit=1)[0] if str(text).strip() else ""
            raise ExprError("the objective is written `minimize EXPR` or `maximize EXPR`"
                            + did_you_mean(first, ["minimize", "maximize"]), str(text))
        expr = self.expression(m.group(2), ph, phases)
        if ph is not None:
            bare = expr.free_symbols & set(ph.states + ph.controls + (TIME,))
            if bare:
                names = ", ".join(sorted(s.name for s in bare))
                raise ExprError(f"the objective uses {names} without a time: write e.g. {sorted(bare, key=str)[0]}(tf), "
                                f"or integral(...) for a running cost", str(text))
        return Objective(m.group(1), expr, str(text))

    def parse_expect(self, key: str, problem: Problem) -> sp.Expr:
        if key == "objective":
            return sym("objective")
        multi = self.spec.phases is not None
        ph = None if multi else problem.phases[0]
        e = self.expression(key, ph, problem.phases)
        # a state or control alone is a function of time, no one number to compare (it was
        # accepted, then nan at the run)
        used = getattr(e, "free_symbols", set())
        states = {x for p_ in problem.phases for x in p_.states}
        along = sorted(used & (states | {c for p_ in problem.phases for c in p_.controls} | {TIME}), key=str)
        if along:
            name = "t" if along[0] == TIME else str(along[0])
            ends = f"a value at an end, e.g. {name}(tf) or {name}(t0), " if along[0] in states else ""
            raise ExprError(f"`{name}` varies along the phase, so `{key}` is no single number: expect {ends}"
                            f"an integral such as integral({name}), a final time, a parameter or the "
                            "objective", key)
        return e
