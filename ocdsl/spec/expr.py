"""Safe expression parser: a whitelist over Python's ``ast`` that builds SymPy objects.

Nothing from a problem file is ever ``eval``-ed or ``sympify``-ed. Accepted: numbers,
declared names, + - * / ** and unary minus, whitelisted functions, boundary values
``x(t0)`` / ``x(tf)`` (``phase.x(tf)`` across phases), ``integral(expr)``, and in
relations the comparisons ``<=``, ``>=``, ``==`` (chains allowed).
"""
from __future__ import annotations

import ast
import keyword
import math
import re
from dataclasses import dataclass, field
from typing import Callable

import sympy as sp

from ..hints import did_you_mean
from ..symbolic.numbers import exp_of
from .errors import ExprError, FollowOnError, UnknownNames

FUNCTIONS: dict[str, tuple[Callable, int]] = {
    "sin": (sp.sin, 1), "cos": (sp.cos, 1), "tan": (sp.tan, 1),
    "asin": (sp.asin, 1), "acos": (sp.acos, 1), "atan": (sp.atan, 1), "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1), "cosh": (sp.cosh, 1), "tanh": (sp.tanh, 1),
    "exp": (lambda a: exp_of(a), 1), "log": (sp.log, 1), "sqrt": (sp.sqrt, 1), "abs": (sp.Abs, 1),
}
# functions of vectors (declared vector groups, vector expressions or [a, b, c] literals)
VECTOR_FUNCTIONS = {"norm": 1, "dot": 2, "cross": 2}
CONSTANTS = {"pi": sp.pi, "inf": sp.oo}
# Python's keywords too: the parser reads expressions as Python (a state `lambda` made
# `lambda(t0)` a syntax error about lambda expressions: unseen24)
RESERVED = (set(FUNCTIONS) | set(VECTOR_FUNCTIONS) | set(CONSTANTS) | {"integral", "t", "t0", "tf", "continuous"}
            | set(keyword.kwlist))
MAX_EXPONENT = 64          # larger literal exponents are almost surely typos or attacks
MAX_TEXT = 20_000
# Input limits (docs/problem-language.md): nesting counts calls, powers, unary minus and
# parentheses (a long sum a + b + c + ... is one level); SymPy's own recursion ends past
# about 150 nested calls, so 64 leaves room for named expressions used inside others
MAX_NESTING = 64
MAX_MAGNITUDE = 300        # a constant beyond 1e300 is refused before SymPy computes it

# t0 and tf where they are not names (a model's dynamics and path constraints): what to write
# instead (unseen21 U4: `x: u/tf` said "did you mean 't'?")
_TIME_ENDS = {n: (f" (the phase's {'initial' if n == 't0' else 'final'} time is not a name in a model's dynamics, "
                  "path constraints or integrands; to use it there, write the phase over t in [0, 1] with "
                  "its duration a free parameter T and the dynamics times T, e.g. `x: T*u`)")
              for n in ("t0", "tf")}


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
    functions: dict[str, Callable[..., sp.Expr]] = field(default_factory=dict)  # tables: name -> f(*args)


def parse_expression(text: str | int | float, scope: Scope, vector: bool = False) -> sp.Expr:
    """Parse one expression (no comparison); with ``vector``, a vector (a column
    ``sp.Matrix``) is a valid result too (named expressions, dynamics of a vector group)."""
    tree = _parse(text)
    if isinstance(tree, ast.Compare):
        raise ExprError("a relation is not allowed here, an expression is expected", str(text))
    e = _real(_Builder(scope, str(text), tree).build(tree), text)
    if isinstance(e, sp.MatrixBase) and not vector:
        raise ExprError(f"this is a vector of {len(e)} components where a number is expected "
                        "(use norm(...), dot(...) or a component such as r[0])", str(text))
    return e


def _real(e, text):
    """Refuse complex constants (sqrt(-1), log(-2), acos(2)): no back end has a meaning for them."""
    parts = list(e) if is_vector(e) else [e]
    for part in parts:
        if isinstance(part, sp.Basic) and (part.has(sp.I) or any(
                f.is_number and f.is_extended_real is False for f in part.atoms(sp.Function, sp.Pow))):
            raise ExprError("this has a complex value (e.g. sqrt or log of a negative number, "
                            "asin/acos outside [-1, 1])", str(text))
    return e


def is_vector(e) -> bool:
    return isinstance(e, sp.MatrixBase)


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
    builder = _Builder(scope, str(text), tree)
    terms = [_real(builder.build(t), text) for t in [tree.left, *tree.comparators]]
    sizes = {len(t) for t in terms if is_vector(t)}
    if len(sizes) > 1:
        raise ExprError(f"vectors of different sizes {sorted(sizes)} in one relation", str(text))
    if any(isinstance(op, ast.NotEq) for op in tree.ops):
        # unseen24: `x(t0) != 1` got the message about < and >
        raise ExprError("`!=` is not a constraint an optimiser can keep (the points it excludes have no "
                        "neighbourhood): write the side you mean, e.g. `x(t0) >= 1.1` or `x(t0) <= 0.9`",
                        str(text))
    if any(type(op) not in ops for op in tree.ops):
        raise ExprError("only <=, >= and == are allowed in relations (strict < and > have no "
                        "meaning for a continuous optimiser)", str(text))
    directions = {type(op) for op in tree.ops} - {ast.Eq}
    if len(directions) > 1:
        # `-1 <= u >= 1` is legal Python (u >= 1) but never what a bound means: a typo
        raise ExprError("a chain's inequalities must point one way (all <= or all >=): this one "
                        "mixes them, so it does not bound the middle from both sides; write e.g. "
                        "-1 <= u <= 1, or two constraints", str(text))
    out = []
    for i, op in enumerate(tree.ops):
        a, b = terms[i], terms[i + 1]
        if is_vector(a) or is_vector(b):
            # a vector relation holds component by component (a number applies to each)
            n = len(a) if is_vector(a) else len(b)
            for k in range(n):
                out.append(Relation(a[k] if is_vector(a) else a, ops[type(op)], b[k] if is_vector(b) else b))
        else:
            out.append(Relation(a, ops[type(op)], b))
    return out


def parse_continuity(text: str) -> tuple[list[str], list[str] | None] | None:
    """``continuous(a, b, ...)`` or ``continuous(a, b, ..., [x, y])``: the phases (in order)
    and the states named (None: every state the phases share); None when ``text`` is not
    such a call."""
    try:
        tree = ast.parse(str(text).strip(), mode="eval").body
    except SyntaxError:
        return None
    if not (isinstance(tree, ast.Call) and isinstance(tree.func, ast.Name) and tree.func.id == "continuous"):
        return None
    args, names = list(tree.args), None
    if tree.keywords:
        raise ExprError("continuous(...) takes phase names and optionally a list of states, "
                        "e.g. continuous(stage1, stage2, [r, v])", str(text))
    if args and isinstance(args[-1], ast.List):
        names = []
        for e in args.pop().elts:
            if not isinstance(e, ast.Name):
                raise ExprError(f"'{ast.unparse(e)}' in the list of continuous states is not a name", str(text))
            names.append(e.id)
    phases = []
    for a in args:
        if not isinstance(a, ast.Name):
            raise ExprError(f"'{ast.unparse(a)}' is not a phase name", str(text))
        phases.append(a.id)
    if len(phases) < 2:
        raise ExprError("continuous(...) joins at least two phases, e.g. continuous(stage1, stage2)", str(text))
    return phases, names


def _parse(text: str | int | float) -> ast.expr:
    if isinstance(text, bool):
        raise ExprError("expected an expression, got a boolean", str(text))
    if isinstance(text, (int, float)):
        text = repr(text)
    if not isinstance(text, str):
        raise ExprError(f"expected an expression (text), got {type(text).__name__}", str(text))
    if len(text) > MAX_TEXT:
        raise ExprError(f"expression longer than {MAX_TEXT} characters", text[:60] + "...")
    if re.search(r"\d{301}", text):    # Python refuses 4,300 digits, float() 309 anyway
        raise ExprError("a number of more than 300 digits", text[:60] + "...")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as e:
        # x' reads to Python as an unclosed string: say what the quote is taken for instead
        m = re.search(r"[A-Za-z_]\w*[ \t]*'", text)
        if m:
            name = m.group(0).rstrip(" \t'")
            raise ExprError(f"`'` is not allowed in an expression (`{name}'`): derivatives are written in "
                            f"`dynamics:` (`{name}: ...` gives {name}'); to bound {name}', bound that right-hand side",
                            text) from None
        hint = ""
        if re.search(r"(?<![\w.])\d+(\.\d*)?([eE][+-]?\d+)?\s*deg\b", text):
            # `x(tf) == 10deg` (unseen29): the suffix is the controller blocks' (spec/controller.py)
            hint = ("; `deg` is read only in a controller's numbers (`x0: {phi: 10deg}`): in an expression "
                    "write the radians, e.g. 10*pi/180")
        elif m := re.search(r"=\s*([<>])", text):
            # `x(tf) => 0` (unseen48 F5) was told "an equality is written with =="
            hint = f"; `={m.group(1)}` is written `{m.group(1)}=`"
        elif re.search(r"(?<![<>=!])=(?!=)", text):
            hint = "; an equality is written with ==, e.g. x(t0) == 1"
        elif re.search(r"(?<![\w.])\d+(\.\d*)?([eE][+-]?\d+)?\s+[A-Za-z_]", text):
            # `-1 m/s**2 <= u` (unseen12 F11): a number followed by a name
            hint = ("; a number followed by a name: units are not written in expressions (numbers are "
                    "in the model's units; `units:` labels them), and a product needs *")
        raise ExprError(f"syntax error ({e.msg}){hint}", text) from None
    except (RecursionError, MemoryError, ValueError) as e:   # Python's own parser limits
        raise ExprError(f"expression too long or nested too deeply for the parser ({type(e).__name__}); a sum "
                        "or product of more than about 1,500 terms is: split it into named expressions",
                        text[:60]) from None
    _check_nesting(tree, text)
    return tree


def _check_nesting(tree: ast.AST, text: str) -> None:
    """Refuse deeper nesting than MAX_NESTING before anything is built (without recursion)."""
    stack = [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_NESTING:
            raise ExprError(f"expression nested deeper than {MAX_NESTING} levels", text[:60] + "...")
        for child in ast.iter_child_nodes(node):
            if not isinstance(child, ast.expr):      # Load contexts, operators
                continue
            chained = isinstance(node, ast.BinOp) and child is node.left and isinstance(child, ast.BinOp)
            stack.append((child, depth if chained else depth + 1))


def _log10_abs(x: sp.Expr) -> float:
    """log10 |x| of a numeric constant, without computing a huge integer's float."""
    if x.is_Integer:
        n = abs(int(x))
        return 0.0 if n == 0 else max(0.0, (n.bit_length() - 1) * 0.30103)
    try:
        v = abs(complex(x.evalf(15)))
    except (TypeError, ValueError, OverflowError):
        return math.inf
    return math.log10(v) if v > 0 else 0.0


class _Builder:
    def __init__(self, scope: Scope, text: str, tree: ast.AST):
        self.scope, self.text, self.tree = scope, text, tree      # tree: the whole parsed text

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
        if node.id in FUNCTIONS or node.id in VECTOR_FUNCTIONS or node.id == "integral" \
                or node.id in self.scope.functions:
            raise self.fail(f"'{node.id}' is a function and needs arguments")
        # every unknown name of the expression in one message (unseen12 F6: `uu + q + zz`
        # took three runs, one name each)
        unknown = [(n, f"'{n}'{_TIME_ENDS[n] if n in _TIME_ENDS else did_you_mean(n, self.scope.names)}")
                   for n in self._unknown_names() or [node.id]]
        raise UnknownNames(unknown, self.text)

    def _unknown_names(self) -> list[str]:
        """The expression's plain names (not a called function, not a phase before a dot) that
        are neither declared nor a constant or function, in the order written."""
        tree = self.tree
        skip = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
        skip |= {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
        # the t0 / tf of a boundary value x(tf) is its form, not a name (unseen29: `cc` unknown
        # in `-b.x(tf) + cc*b.v(tf)**2` was reported with 'tf' beside it)
        skip |= {id(n.args[0]) for n in ast.walk(tree) if isinstance(n, ast.Call) and len(n.args) == 1
                 and isinstance(n.args[0], ast.Name) and n.args[0].id in ("t0", "tf")}
        out: list[str] = []
        known = set(self.scope.names) | set(CONSTANTS) | set(FUNCTIONS) | set(VECTOR_FUNCTIONS) \
            | set(self.scope.functions) | {"integral"}
        for n in sorted((n for n in ast.walk(tree) if isinstance(n, ast.Name) and id(n) not in skip),
                        key=lambda n: (n.lineno, n.col_offset)):
            if n.id not in known and n.id not in out:
                out.append(n.id)
        return out

    def _List(self, node: ast.List) -> sp.Matrix:
        items = [self.build(e) for e in node.elts]
        if len(items) < 2 or any(is_vector(e) for e in items):
            raise self.fail("a vector literal is a list of at least two numbers or scalar expressions, e.g. [0, 0, w]")
        return sp.Matrix(items)

    def _Subscript(self, node: ast.Subscript) -> sp.Expr:
        v = self.build(node.value)
        index = node.slice
        if not is_vector(v):
            raise self.fail(f"'{ast.unparse(node.value)}' is not a vector and cannot be indexed")
        if not (isinstance(index, ast.Constant) and isinstance(index.value, int) and not isinstance(index.value, bool)):
            raise self.fail(f"a component index is a whole number, e.g. {ast.unparse(node.value)}[0]")
        if not -len(v) <= index.value < len(v):
            raise self.fail(f"index {index.value} outside the {len(v)} components of '{ast.unparse(node.value)}' "
                            "(components count from 0)")
        return v[index.value]

    def _UnaryOp(self, node: ast.UnaryOp) -> sp.Expr:
        if isinstance(node.op, ast.USub):
            return -self.build(node.operand)
        if isinstance(node.op, ast.UAdd):
            return self.build(node.operand)
        raise self.fail(f"operator '{ast.unparse(node)}' is not allowed")

    def _BinOp(self, node: ast.BinOp) -> sp.Expr:
        # a chain a + b - c + ... (left-nested in the tree) is walked in a loop, not by recursion
        chain = []
        while isinstance(node, ast.BinOp) and not isinstance(node.op, ast.Pow):
            chain.append(node)
            node = node.left
        if not chain:
            return self._binary(node, self.build(node.left), self.build(node.right))
        acc = self.build(node)
        terms: list = []     # scalar terms of a sum gathered, added once (linear, not quadratic)
        for n in reversed(chain):
            b = self.build(n.right)
            if isinstance(n.op, (ast.Add, ast.Sub)) and not (is_vector(acc) or is_vector(b)):
                terms.append(b if isinstance(n.op, ast.Add) else -b)
                continue
            if terms:
                acc, terms = sp.Add(acc, *terms), []
            acc = self._binary(n, acc, b)
        return sp.Add(acc, *terms) if terms else acc

    def _binary(self, node: ast.BinOp, a, b) -> sp.Expr:
        op = type(node.op)
        if is_vector(a) or is_vector(b):
            return self._vector_op(op, a, b, node)
        if op is ast.Add:
            return a + b
        if op is ast.Sub:
            return a - b
        if op is ast.Mult:
            if a.is_Number and b.is_Number and _log10_abs(a) + _log10_abs(b) > MAX_MAGNITUDE:
                raise self.fail(f"a constant beyond 1e{MAX_MAGNITUDE}")
            return a * b
        if op is ast.Div:
            if b == 0:
                raise self.fail("division by zero")
            return a / b
        if op is ast.Pow:
            if b.is_number and (not b.is_finite or abs(float(b)) > MAX_EXPONENT):
                raise self.fail(f"exponent {b} too large (limit {MAX_EXPONENT})")
            if a.is_number and b.is_number and _log10_abs(a) * abs(float(b)) > MAX_MAGNITUDE:
                raise self.fail(f"a constant beyond 1e{MAX_MAGNITUDE} ('{ast.unparse(node)[:60]}')")
            return a ** b
        raise self.fail(f"operator in '{ast.unparse(node)}' is not allowed (use + - * / **)")

    def _vector_op(self, op, a, b, node):
        if op in (ast.Add, ast.Sub):
            if not (is_vector(a) and is_vector(b)):
                raise self.fail(f"'{ast.unparse(node)}' adds a vector and a number")
            if a.shape != b.shape:
                raise self.fail(f"'{ast.unparse(node)}' adds vectors of {len(a)} and {len(b)} components")
            return a + b if op is ast.Add else a - b
        if op is ast.Mult:
            if is_vector(a) and is_vector(b):
                raise self.fail(f"'{ast.unparse(node)}' multiplies two vectors: use dot(a, b) or cross(a, b)")
            return a * b if is_vector(a) else b * a
        if op is ast.Div and is_vector(a) and not is_vector(b):
            if b == 0:
                raise self.fail("division by zero")
            return a / b
        raise self.fail(f"'{ast.unparse(node)}' is not defined for vectors (vectors add, subtract, "
                        "and are multiplied or divided by numbers)")

    def _vector_call(self, name: str, node: ast.Call):
        args = [self.build(a) for a in node.args]
        if len(args) != VECTOR_FUNCTIONS[name]:
            n = VECTOR_FUNCTIONS[name]
            raise self.fail(f"{name} takes {n} argument{'s' * (n > 1)}, got {len(args)}")
        if not all(is_vector(a) for a in args):
            raise self.fail(f"{name}(...) takes vectors (declared under the model's vectors:, or [a, b, c])")
        if name == "norm":
            return sp.sqrt(sum(c**2 for c in args[0]))
        a, b = args
        if a.shape != b.shape:
            raise self.fail(f"{name} of vectors of {len(a)} and {len(b)} components")
        if name == "dot":
            return sum(x * y for x, y in zip(a, b))
        if len(a) != 3:
            raise self.fail("cross takes vectors of 3 components")
        return a.cross(b)

    def _Call(self, node: ast.Call) -> sp.Expr:
        if node.keywords:
            raise self.fail("keyword arguments are not allowed")
        func = node.func
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            if func.attr == "integral" and func.value.id in self.scope.phases:
                # the natural guess for a multi-phase cost; it read as a boundary value
                ph = func.value.id
                arg = ast.unparse(node.args[0]) if node.args else "..."
                raise self.fail(f"'{ast.unparse(node)}': an integral over phase '{ph}' is written in that phase's "
                                f"`objective:` (phases: {{{ph}: {{objective: integral({arg})}}}}); phase objectives "
                                "are added to this one as costs (subtracted under maximize), e.g. `objective: "
                                "minimize 0` beside each phase's integral; in a constraint (a budget the phases "
                                f"share) carry the integral as a state: a state E with dynamics `E: {arg}`, "
                                f"continuous across the phases, and a bound on the last phase's E(tf)")
            if not self.scope.phases:
                # `np.float64(0.0866)` in a parameter read as a phase's boundary value (unseen41 F6)
                raise self.fail(f"'{ast.unparse(node)}' is not allowed: write the number, or call one of the "
                                f"whitelisted functions (sqrt(2), atan2(1, 2), ...)")
            return self._boundary(func.value.id, func.attr, node)
        if not isinstance(func, ast.Name):
            raise self.fail(f"'{ast.unparse(func)}(...)' is not allowed (only whitelisted functions may be called)")
        name = func.id
        if name == "integral":
            if self.scope.integral is None:
                raise self.fail("integral(...) is not allowed here")
            if len(node.args) != 1:
                raise self.fail("integral takes one argument")
            inner = next((n for n in ast.walk(node.args[0]) if isinstance(n, ast.Call)
                          and isinstance(n.func, ast.Name) and n.func.id == "integral"), None)
            if inner is not None:     # unseen24: passed `check`, then a NameError in the run
                raise self.fail(f"'{ast.unparse(node)}': an integral inside an integral is not allowed; make "
                                f"the inner one a state (z: {ast.unparse(inner.args[0]) if inner.args else '...'} "
                                "in the dynamics, z(t0) == 0) and integrate z")
            integrand = self.build(node.args[0])
            if is_vector(integrand):
                raise self.fail("integral(...) takes a number, not a vector")
            return self.scope.integral(integrand)
        if name in VECTOR_FUNCTIONS:
            return self._vector_call(name, node)
        if name in FUNCTIONS:
            f, arity = FUNCTIONS[name]
            if len(node.args) != arity:
                raise self.fail(f"{name} takes {arity} argument{'s' * (arity > 1)}, got {len(node.args)}")
            args = [self.build(a) for a in node.args]
            if any(is_vector(a) for a in args):
                raise self.fail(f"{name} takes numbers, not vectors (use norm(...) or a component)")
            return f(*args)
        if name in self.scope.functions:
            args = [self.build(a) for a in node.args]
            if any(is_vector(a) for a in args):
                raise self.fail(f"table {name} takes numbers, not vectors (use a component such as r[0])")
            try:
                return self.scope.functions[name](*args)
            except FollowOnError:      # a broken table: its own error is reported at its line
                raise
            except ValueError as e:
                raise self.fail(str(e)) from None
        if name in self.scope.names:
            return self._boundary(None, name, node)
        if self.scope.boundary is not None and len(node.args) == 1 and isinstance(node.args[0], ast.Name) \
                and node.args[0].id in ("t0", "tf"):
            # `z(tf)` of no state z read as a function call (unseen41 F4: "unknown function 'z'")
            known = [k for k, v in self.scope.names.items() if isinstance(v, sp.Symbol) and k not in ("t", "t0", "tf")]
            raise self.fail(f"'{ast.unparse(node)}': unknown name '{name}' (a boundary value is a state's or a "
                            f"control's, {name}(t0) or {name}(tf)){did_you_mean(name, known)}")
        raise self.fail(f"unknown function '{name}'{did_you_mean(name, list(FUNCTIONS) + list(self.scope.functions))}")

    def _Attribute(self, node: ast.Attribute) -> sp.Expr:
        # phase.tf, phase.t0 or a phase's parameter, in links
        if isinstance(node.value, ast.Name) and node.value.id in self.scope.phases:
            names = self.scope.phases[node.value.id]
            if node.attr in ("t0", "tf") and node.attr in names:
                return names[node.attr]
            # `brake.tff` is far likelier a misspelt tf than a state written without its time
            raise self.fail(f"'{ast.unparse(node)}': a phase has t0 and tf{did_you_mean(node.attr, ['t0', 'tf'])}; "
                            f"a state's value is written {node.value.id}.{node.attr}(t0) or "
                            f"{node.value.id}.{node.attr}(tf)")
        if isinstance(node.value, ast.Name) and self.scope.phases and node.attr in ("t0", "tf"):
            raise self._unknown_phase(node.value.id)
        raise self.fail(f"'{ast.unparse(node)}' is not allowed")

    def _unknown_phase(self, phase: str) -> ExprError:
        return self.fail(f"unknown phase '{phase}'{did_you_mean(phase, self.scope.phases)}")

    def _boundary(self, phase: str | None, var: str, node: ast.Call) -> sp.Expr:
        if self.scope.boundary is None:
            raise self.fail(f"boundary value '{ast.unparse(node)}' is not allowed here")
        if len(node.args) != 1 or not isinstance(node.args[0], ast.Name) or node.args[0].id not in ("t0", "tf"):
            raise self.fail(f"'{ast.unparse(node)}': a boundary value is written {var}(t0) or {var}(tf)")
        if phase is not None and phase not in self.scope.phases:
            raise self._unknown_phase(phase)
        try:
            return self.scope.boundary(phase, var, node.args[0].id)
        except ExprError as e:
            raise self.fail(e.message) from None


def constant_value(value) -> float:
    """A parameter's value given outside a file (`--param`, the Python API's ``parameters=``): a
    finite number, or a constant expression of the problem language (`1/9`, `2*pi`,
    `sqrt(2)`); a ValueError otherwise. `inf`, `nan` and `1e400` are refused (unseen40 F3)."""
    import math

    try:
        number = float(value)
    except (TypeError, ValueError):
        if not isinstance(value, str):
            raise ValueError(repr(value)) from None
        try:
            e = parse_expression(value.strip(), Scope(names={}))
        except (ExprError, SyntaxError, TypeError, ValueError):
            raise ValueError(value) from None
        if e.free_symbols:
            raise ValueError(value)
        number = float(e)
    if not math.isfinite(number):
        raise ValueError(value if isinstance(value, str) else repr(value))
    return number
