"""Models of a problem file: a registered model with the file's parameters and options, or
an inline one (states, controls, expressions, vectors, dynamics), and the parameters."""
from __future__ import annotations

import math
from typing import Any

import sympy as sp

from ...hints import did_you_mean
from ...symbolic.model import TIME, Model, sym
from ...symbolic.problem import INF, FreeParameter
from ...symbolic.registry import build_model
from ..expr import RESERVED, Scope, is_vector, parse_expression
from ..schema import ModelSpec, ParameterSpec
from .common import MAX_VARIABLES, NAME_RE, _midpoint


class ModelCompiler:
    """The compiler's model part (mixed into :class:`~.compiler.Compiler`)."""

    def parameters(self, params: dict[str, Any], loc: tuple) -> dict[sp.Symbol, float | None]:
        out: dict[sp.Symbol, float | None] = {}
        for name, p in params.items():
            if not NAME_RE.match(name) or name in RESERVED:
                self.issue(loc + (name,), f"'{name}' is not a valid parameter name (reserved or not an identifier)")
                continue
            s = sym(name)
            if isinstance(p, ParameterSpec) and p.free:
                lo, hi = p.bounds or (None, None)
                guess = p.value if p.value is not None else _midpoint(lo, hi)
                self.free[s] = FreeParameter(s, -INF if lo is None else lo, INF if hi is None else hi, guess)
                self.free_locs[s] = loc + (name,)
                out[s] = None
            else:
                value = p.value if isinstance(p, ParameterSpec) else p
                if name in self.overrides:
                    self.file_values[name] = value
                    value = float(self.overrides[name])
                    self.used_overrides.add(name)
                if not math.isfinite(value):
                    self.issue(loc + (name,), f"parameter '{name}' is not a finite number")
                out[s] = value
                self.constants_in_force[name] = value
        return out

    def model(self, mspec: ModelSpec, loc: tuple) -> Model | None:
        if mspec.use:
            try:
                model = build_model(mspec.use, mspec.options)
            except (KeyError, ValueError) as e:
                self.issue(loc + ("use",), str(e).strip("'\""))
                return None
            except Exception as e:   # a model's builder is its author's code: any failure is the options'
                self.issue(loc + ("options",), f"model '{mspec.use}' cannot be built with these options "
                           f"({type(e).__name__}: {e})")
                return None
            given = self.parameters(mspec.parameters, loc + ("parameters",))
            known = {s.name: s for s in model.parameters}
            params = dict(model.parameters)
            for s, v in given.items():
                if s.name not in known:
                    self.issue(loc + ("parameters", s.name), f"model '{mspec.use}' has no parameter '{s.name}'; "
                               f"it has: {', '.join(sorted(known)) or 'none'}")
                    continue
                params[known[s.name]] = v
            for s, v in model.parameters.items():
                if s.name in self.overrides and s not in given:
                    self.file_values[s.name] = params[s]
                    params[s] = float(self.overrides[s.name])
                    self.used_overrides.add(s.name)
                if params[s] is not None and s not in self.free:
                    self.constants_in_force.setdefault(s.name, params[s])
            units = {**model.units, **mspec.units}
            names = {s.name: s for s in model.states + model.controls + tuple(model.parameters)}
            vectors = {**model.vectors, **self.vector_groups(mspec.vectors, names, loc)}
            return Model(model.name, model.states, model.controls, model.dynamics, params,
                         model.expressions, units, model.description,
                         tuple(mspec.positions) or model.positions, vectors, model.time_state, model.frame)
        return self.inline_model(mspec, loc)

    def inline_model(self, m: ModelSpec, loc: tuple) -> Model | None:
        if len(m.states) + len(m.controls) > MAX_VARIABLES:   # compile time grows with the square
            self.issue(loc + ("states",), f"{len(m.states)} states and {len(m.controls)} controls: more "
                       f"than the limit of {MAX_VARIABLES} together")
            return None
        names: dict[str, sp.Basic] = {"t": TIME}
        ok = True
        declared: dict[str, tuple] = {}
        for group, items in (("states", m.states), ("controls", m.controls), ("parameters", list(m.parameters))):
            for i, name in enumerate(items):
                where = loc + (group, i if group != "parameters" else name)
                if not isinstance(name, str) or not NAME_RE.match(name) or name in RESERVED:
                    self.issue(where, f"'{name}' is not a valid {group[:-1]} name (reserved or not an identifier)")
                    if isinstance(name, str):
                        self.refused_names.add(name)
                    ok = False
                elif name in declared:
                    self.issue(where, f"'{name}' is declared twice (also in {declared[name][0]})")
                    ok = False
                else:
                    declared[name] = (group,)
                    names[name] = sym(name)
        params = self.parameters(m.parameters, loc + ("parameters",))
        for name in self.spec.parameters:
            if declared.get(name, ("",))[0] in ("states", "controls"):
                # its value replaced the state in the dynamics, silently (unseen24: x' = u*x with a
                # file parameter x: 1 solved v' = u)
                self.issue(("parameters", name), f"'{name}' is a {declared[name][0][:-1]} of the model and a "
                                                 "parameter of the file: rename one")
                ok = False
                continue
            names.setdefault(name, sym(name))
        vectors = self.vector_groups(m.vectors, names, loc)
        expressions: dict[sp.Symbol, sp.Expr] = {}
        scope = Scope(names, functions=self.tables)
        clash = sorted(set(names) & set(self.tables))
        for name in clash:
            self.issue(("tables", name), f"'{name}' names both a table and a declared name of the model")
        # an expression that does not compile stands for a placeholder: its uses compile, and
        # whatever uses one is dropped without an error of its own (the root error is reported)
        failed: set[sp.Symbol] = set()
        ordered, cyclic = self.expression_order(m.expressions, loc)
        for name in cyclic:       # reported: their uses are dropped like those of a failed one
            names[name] = placeholder = sp.Dummy(name)
            failed.add(placeholder)
        for name, text in ordered:
            if not NAME_RE.match(name) or name in names or name in RESERVED:
                self.issue(loc + ("expressions", name), f"'{name}' cannot name an expression (reserved, declared or not an identifier)")
                ok = False
                continue
            e = self.guarded(loc + ("expressions", name), parse_expression, text, scope, True)
            if e is None or e.free_symbols & failed:
                names[name] = placeholder = sp.Dummy(name)
                failed.add(placeholder)
                continue
            if is_vector(e):            # a vector expression is kept whole, its components inline
                vectors[name] = names[name] = sp.ImmutableMatrix(e)
                continue
            s = sym(name)
            expressions[s] = e
            names[name] = s      # later expressions and the dynamics may use it
        dynamics: dict[sp.Symbol, sp.Expr] = {}
        covered: set[str] = set()
        unparsed = bool(failed)
        for name, text in m.dynamics.items():
            if name in m.states and name not in names:     # an invalid state name, reported above
                ok = False
                continue
            targets = self.dynamics_targets(name, m, vectors, loc)
            if targets is None:
                unparsed = True     # the declared names are sound: the rest is still checked
                continue
            covered.update(targets)
            e = self.guarded(loc + ("dynamics", name), parse_expression, text, scope, len(targets) > 1)
            if e is None or e.free_symbols & failed:
                unparsed = True     # reported (or its root is); the declarations still hold
                continue
            values = list(e) if is_vector(e) else [e]
            if len(values) != len(targets):
                self.issue(loc + ("dynamics", name), f"'{name}' has {len(targets)} components but its "
                           f"right-hand side has {len(values)}")
                unparsed = True
                continue
            for target, value in zip(targets, values):
                if names[target] in dynamics:
                    self.issue(loc + ("dynamics", name), f"dynamics of '{target}' given twice")
                    unparsed = True
                dynamics[names[target]] = value
        for i, s in enumerate(m.states):
            if s not in covered and s in names:
                self.issue(loc + ("states", i), f"state '{s}' has no dynamics (add `{s}: ...` under dynamics)")
                unparsed = True
        for key in m.units:       # a unit label of no declared name was dropped without a word
            if key not in names and key not in self.spec.parameters:
                self.issue(loc + ("units", key), f"a unit for '{key}', which the model does not declare"
                           + did_you_mean(key, [k for k in names if k != "t"] + ["t"]))
        if not ok:
            return None
        if unparsed:
            # a right-hand side or named expression that did not compile: the model's names
            # are sound, so the constraints and the objective are still compiled and their own
            # mistakes reported in the same pass; the file is refused all the same (the issue
            # is recorded), and the stand-in right-hand sides are never solved
            for s in m.states:
                dynamics.setdefault(names[s], sp.S.Zero)
        return Model(self.spec.name, tuple(names[s] for s in m.states), tuple(names[c] for c in m.controls),
                     dynamics, params, expressions, dict(m.units), "", tuple(m.positions), vectors)

    def expression_order(self, expressions: dict, loc: tuple) -> tuple[list[tuple[str, object]], list[str]]:
        """Named expressions in an order where each comes after those it uses: they may be
        written in any order (unseen12 F6: `acc: u*k + drag` above `drag: ...` was 'unknown
        name drag'). Expressions in a cycle are reported, each at its line, and left out."""
        import ast

        uses = {}
        for name, text in expressions.items():
            try:
                tree = ast.parse(str(text).strip(), mode="eval")
                uses[name] = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} & set(expressions) - {name}
            except (SyntaxError, ValueError, RecursionError, MemoryError):
                uses[name] = set()      # its own error comes from parsing it
        # depth first in the written order: a file in a valid order keeps it exactly
        order: list[str] = []
        state: dict[str, int] = {}          # 1 being visited, 2 placed
        cyclic: list[str] = []

        def visit(n: str, path: list[str]) -> None:
            if state.get(n) == 2 or n in cyclic:
                return
            if state.get(n) == 1:
                cyclic.extend(m for m in path[path.index(n):] if m not in cyclic)
                return
            state[n] = 1
            for d in (d for d in expressions if d in uses[n]):
                visit(d, path + [n])
            state[n] = 2
            if n not in cyclic:
                order.append(n)

        for n in expressions:
            visit(n, [])
        order = [n for n in order if n not in cyclic]       # their users meet placeholders
        for n in cyclic:
            self.issue(loc + ("expressions", n), f"'{n}' is defined through itself (a cycle of named "
                       f"expressions: {', '.join(cyclic)})")
        return [(n, expressions[n]) for n in order], cyclic

    def vector_groups(self, groups: dict[str, list[str]], names: dict, loc: tuple) -> dict[str, sp.ImmutableMatrix]:
        """``vectors: {r: [x, y, z]}``: each a column of declared names, added to ``names``."""
        out: dict[str, sp.ImmutableMatrix] = {}
        for vname, comps in groups.items():
            where = loc + ("vectors", vname)
            if not NAME_RE.match(vname) or vname in names or vname in RESERVED:
                self.issue(where, f"'{vname}' cannot name a vector (reserved, declared or not an identifier)")
                continue
            unknown = [c for c in comps if c not in names or c == "t"]
            if unknown or len(comps) < 2:
                self.issue(where, f"vector '{vname}' needs at least two declared states, controls or parameters"
                           + (f"; unknown: {', '.join(map(str, unknown))}" + did_you_mean(str(unknown[0]), names)
                              if unknown else ""))
                continue
            out[vname] = names[vname] = sp.ImmutableMatrix([names[c] for c in comps])
        return out

    def dynamics_targets(self, name: str, m: ModelSpec, vectors: dict, loc: tuple) -> list[str] | None:
        """The states a line of dynamics gives: one state, or a vector of states."""
        if name in m.states:
            return [name]
        if name in vectors and name in m.vectors and all(c in m.states for c in m.vectors[name]):
            return list(m.vectors[name])
        self.issue(loc + ("dynamics", name), f"dynamics given for '{name}', which is not a state "
                   "(nor a vector of states)" + did_you_mean(name, list(m.states) + list(m.vectors)))
        return None
