"""Safe expression parser: a whitelist over Python's ``ast`` that builds SymPy objects.

Nothing from a problem file is ever ``eval``-ed or ``sympify``-ed. Accepted: numbers,
declared names, + - * / ** and unary minus, whitelisted functions, boundary values
``x(t0)`` / ``x(tf)`` (``phase.x(tf)`` across phases), ``integral(expr)``, and in
relations the comparisons ``<=``, ``>=``, ``==`` (chains allowed).
"""
from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass, field
from typing import Callable

import sympy as sp

from ..hints import did_you_mean
from .errors import ExprError

FUNCTIONS: dict[str, tuple[Callable, int]] = {
    "sin": (sp.sin, 1), "cos": (sp.cos, 1), "tan": (sp.tan, 1),
    "asin": (sp.asin, 1), "acos": (sp.acos, 1), "atan": (sp.atan, 1), "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1), "cosh": (sp.cosh, 1), "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1), "log": (sp.log, 1), "sqrt": (sp.sqrt, 1), "abs": (sp.Abs, 1),
}
CONSTANTS = {"pi": sp.pi, "inf": sp.oo}
RESERVED = set(FUNCTIONS) | set(CONSTANTS) | {"integral", "t", "t0", "tf"}
MAX_EXPONENT = 64          # larger literal exponents are almost surely typos or attacks
MAX_TEXT = 20_000


@dataclass
class Scope:
    """Names an expression may use, and how boundary values and integrals are made.

    ``names`` maps a name to its SymPy object (states, controls, parameters, named
    expressions, ``t``, ``t0``, ``tf``). ``boundary`` makes the symbol for ``x(t0)``;
    when None, boundary values are not allowed here. ``integral`` likewise.
    """

    names: dict[str, sp.Basic]
    boundary: Callable[[str | None, str, str], sp.Symbol] | None = None
    integral: Callable[[sp.Expr], sp.Symbol] | None = None
    phases: dict[str, dict[str, sp.Basic]] = field(default_factory=dict)  # for phase.x(tf), phase.tf


def parse_expression(text: str | int | float, scope: Scope) -> sp.Expr:
    """Parse one expression (no comparison)."""
    tree = _parse(text)
    if isinstance(tree, ast.Compare):
        raise ExprError("a relation is not allowed here, an expression is expected", str(text))
    return _Builder(scope, str(text)).build(tree)


@dataclass(frozen=True)
class Relation:
    """``lhs op rhs`` with op in {'<=', '>=', '=='}; a chain becomes several Relations."""

    lhs: sp.Expr
    op: str
    rhs: sp.Expr


def parse_relation(text: str, scope: Scope) -> list[Relation]:
    """Parse a relation such as ``-1 <= u <= 1`` or ``x(tf) == 0``."""
    tree = _parse(text)
    if not isinstance(tree, ast.Compare):
        raise ExprError("a constraint must be a relation using <=, >= or ==", str(text))
    ops = {ast.LtE: "<=", ast.GtE: ">=", ast.Eq: "=="}
    builder = _Builder(scope, str(text))
    terms = [builder.build(tree.left)] + [builder.build(c) for c in tree.comparators]
    out = []
    for i, op in enumerate(tree.ops):
        if type(op) not in ops:
            raise ExprError("only <=, >= and == are allowed in relations (strict < and > have no "
                            "meaning for a continuous optimiser)", str(text))
        out.append(Relation(terms[i], ops[type(op)], terms[i + 1]))
    return out


def _parse(text: str | int | float) -> ast.expr:
    if isinstance(text, bool):
        raise ExprError("expected an expression, got a boolean", str(text))
    if isinstance(text, (int, float)):
        text = repr(text)
    if not isinstance(text, str):
        raise ExprError(f"expected an expression (text), got {type(text).__name__}", str(text))
    if len(text) > MAX_TEXT:
        raise ExprError(f"expression longer than {MAX_TEXT} characters", text[:60] + "...")
    try:
        return ast.parse(text.strip(), mode="eval").body
    except SyntaxError as e:
        hint = ""
        if re.search(r"(?<![<>=!])=(?!=)", text):
            hint = "; an equality is written with ==, e.g. x(t0) == 1"
        raise ExprError(f"syntax error ({e.msg}){hint}", text) from None


class _Builder:
    def __init__(self, scope: Scope, text: str):
        self.scope, self.text = scope, text

    def fail(self, message: str) -> ExprError:
        return ExprError(message, self.text)

    def build(self, node: ast.AST) -> sp.Expr:
        method = getattr(self, f"_{type(node).__name__}", None)
        if method is None:
            raise self.fail(f"'{ast.unparse(node)}' is not allowed ({type(node).__name__})")
        return method(node)

    def _Constant(self, node: ast.Constant) -> sp.Expr:
        v = node.value
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(f"only numbers are allowed as constants, not {v!r}")
        if isinstance(v, float) and not math.isfinite(v):
            raise self.fail(f"non-finite number {ast.unparse(node)}")
        if isinstance(v, int) and abs(v) > 10**300:
            raise self.fail("integer literal too large")
        return sp.Integer(v) if isinstance(v, int) else sp.Float(v)

    def _Name(self, node: ast.Name) -> sp.Expr:
        if node.id in self.scope.names:
            return self.scope.names[node.id]
        if node.id in CONSTANTS:
            return CONSTANTS[node.id]
        if node.id in FUNCTIONS or node.id == "integral":
            raise self.fail(f"'{node.id}' is a function and needs arguments")
        raise self.fail(f"unknown name '{node.id}'{did_you_mean(node.id, self.scope.names)}")

    def _UnaryOp(self, node: ast.UnaryOp) -> sp.Expr:
        if isinstance(node.op, ast.USub):
            return -self.build(node.operand)
        if isinstance(node.op, ast.UAdd):
            return self.build(node.operand)
        raise self.fail(f"operator '{ast.unparse(node)}' is not allowed")

    def _BinOp(self, node: ast.BinOp) -> sp.Expr:
        a, b = self.build(node.left), self.build(node.right)
        op = type(node.op)
        if op is ast.Add:
            return a + b
        if op is ast.Sub:
            return a - b
        if op is ast.Mult:
            return a * b
        if op is ast.Div:
            if b == 0:
                raise self.fail("division by zero")
            return a / b
        if op is ast.Pow:
            if b.is_number and (not b.is_finite or abs(float(b)) > MAX_EXPONENT):
                raise self.fail(f"exponent {b} too large (limit {MAX_EXPONENT})")
            return a ** b
        raise self.fail(f"operator in '{ast.unparse(node)}' is not allowed (use + - * / **)")

    def _Call(self, node: ast.Call) -> sp.Expr:
        if node.keywords:
            raise self.fail("keyword arguments are not allowed")
        func = node.func
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            return self._boundary(func.value.id, func.attr, node)
        if not isinstance(func, ast.Name):
            raise self.fail(f"'{ast.unparse(func)}(...)' is not allowed (only whitelisted functions may be called)")
        name = func.id
        if name == "integral":
            if self.scope.integral is None:
                raise self.fail("integral(...) is not allowed here")
            if len(node.args) != 1:
                raise self.fail("integral takes one argument")
            return self.scope.integral(self.build(node.args[0]))
        if name in FUNCTIONS:
            f, arity = FUNCTIONS[name]
            if len(node.args) != arity:
                raise self.fail(f"{name} takes {arity} argument{'s' * (arity > 1)}, got {len(node.args)}")
            return f(*[self.build(a) for a in node.args])
        if name in self.scope.names:
            return self._boundary(None, name, node)
        raise self.fail(f"unknown function '{name}'{did_you_mean(name, FUNCTIONS)}")

    def _Attribute(self, node: ast.Attribute) -> sp.Expr:
        # phase.tf, phase.t0 or a phase's parameter, in links
        if isinstance(node.value, ast.Name) and node.value.id in self.scope.phases:
            names = self.scope.phases[node.value.id]
            if node.attr in ("t0", "tf") and node.attr in names:
                return names[node.attr]
            raise self.fail(f"'{ast.unparse(node)}': use {node.value.id}.{node.attr}(t0) or (tf) for a state")
        raise self.fail(f"'{ast.unparse(node)}' is not allowed")

    def _boundary(self, phase: str | None, var: str, node: ast.Call) -> sp.Expr:
        if self.scope.boundary is None:
            raise self.fail(f"boundary value '{ast.unparse(node)}' is not allowed here")
        if len(node.args) != 1 or not isinstance(node.args[0], ast.Name) or node.args[0].id not in ("t0", "tf"):
            raise self.fail(f"'{ast.unparse(node)}': a boundary value is written {var}(t0) or {var}(tf)")
        if phase is not None and phase not in self.scope.phases:
            raise self.fail(f"unknown phase '{phase}'{did_you_mean(phase, self.scope.phases)}")
        try:
            return self.scope.boundary(phase, var, node.args[0].id)
        except ExprError as e:
            raise self.fail(e.message) from None
