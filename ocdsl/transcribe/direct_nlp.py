"""The NLP of a pseudospectral Transcription evaluated with NumPy, for Ipopt through cyipopt.

Why: the PyNumero route (Pyomo's NL writer, then the ASL) walks the Pyomo expression tree of
every node to write the NL file, and the ASL then interprets one expression graph per
constraint at every evaluation. At 40k variables that is 2.4 s of hand-over and 1.7 s of
function evaluations, against CasADi's 0.1 s (reports/bench/levers.md section 17). Every
collocation node evaluates the same few functions, so here each is differentiated once by
SymPy (first and second derivatives) and evaluated for all nodes at once by NumPy; the
sparse Jacobian and Hessian are assembled with precomputed scatter indices.

This is a fast path of ``ocdsl.solve.ipopt.solve``, not a second transcription: the Pyomo
model that ``pseudospectral.build`` made stays the definition. The structure read here (which
variables, rows and coefficients) is taken from that model's variables and the mesh, the row
order is the model's constraint data, and solutions, duals and bound multipliers are loaded
back into it, so everything downstream (costates, warm starts, the certificate) is unchanged.
``DirectNLP.of`` returns ``None`` with a reason when a model is outside what it covers (extra
nonlinear constraints added after the build, an objective changed after it (mesh
refinement's regularisation), functions without a smooth NumPy form here,
an objective or boundary constraint nonlinear in an integral); the caller then takes the
PyNumero route. ``tests/test_direct_nlp.py`` checks values, Jacobians and
Hessians against PyNumero's at random points on every example in ``configs/``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ..symbolic.model import TIME

INF = 1e20
# functions whose NumPy form and SymPy derivatives agree with the ASL's everywhere they are
# smooth; anything else (Abs, Min/Max, Piecewise, sign...) stays on the PyNumero route
_SMOOTH = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
           "asinh", "acosh", "atanh", "exp", "log", "sqrt"}


class Unsupported(Exception):
    pass


def _check_smooth(exprs, what: str) -> None:
    for e in exprs:
        for f in sp.sympify(e).atoms(sp.Function):
            if type(f).__name__ not in _SMOOTH:
                raise Unsupported(f"{what} uses {type(f).__name__}")
        if sp.sympify(e).has(sp.Piecewise):
            raise Unsupported(f"{what} is piecewise")


def _derivatives(exprs, syms):
    """Nonzero first derivatives [(output, a)], their expressions, and nonzero lower-triangle
    second derivatives [(output, a, b)] with b <= a, their expressions. Only the symbols an
    expression contains are tried (the others give 0): the count of ``diff`` calls grows with
    the nonzero derivatives, not with outputs x symbols (48 states: 10.0 s against 12.6 s)."""
    pos = {s: i for i, s in enumerate(syms)}
    jac, jexprs, hess, hexprs = [], [], [], []
    for o, e in enumerate(exprs):
        e = sp.sympify(e)
        for a in sorted(pos[s] for s in e.free_symbols if s in pos):
            d = sp.diff(e, syms[a])
            if d == 0:
                continue
            jac.append((o, a))
            jexprs.append(d)
            for b in sorted(pos[s] for s in d.free_symbols if s in pos and pos[s] <= a):
                d2 = sp.diff(d, syms[b])
                if d2 != 0:
                    hess.append((o, a, b))
                    hexprs.append(d2)
    return jac, jexprs, hess, hexprs


def _source(args, exprs) -> str | None:
    """NumPy source of ``f(*args, _out)`` writing ``exprs`` into the rows of ``_out`` after
    common-subexpression elimination (``sympy.lambdify(..., cse=True)``'s code, as text that
    can be cached). Rows are assigned in place: a constant or a node array fills its row by
    broadcasting, without a per-entry ``broadcast_to`` and ``stack`` (which took half of a
    Hessian evaluation's time on seed 0)."""
    if not exprs:
        return None
    from sympy.printing.numpy import NumPyPrinter

    reps, red = sp.cse(list(exprs), symbols=sp.numbered_symbols("_c"))
    pr = NumPyPrinter({"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False})
    lines = [f"def f({', '.join(str(a) for a in args)}, _out):"]
    lines += [f"    {s} = {pr.doprint(e)}" for s, e in reps]
    lines += [f"    _out[{i}] = {pr.doprint(e)}" for i, e in enumerate(red)]
    lines.append("    return _out")
    return "\n".join(lines) + "\n"


def _function(source: str | None):
    if source is None:
        return None
    ns = {"numpy": np}
    exec(compile(source, "<ocdsl.transcribe.direct_nlp>", "exec"), ns)
    return ns["f"]


_GENERATOR: list[str] = []


def _generator_id() -> str:
    """What the generated code depends on besides the expressions: ocdsl's and SymPy's
    versions and this module's own source (an edited generator never meets old entries)."""
    if not _GENERATOR:
        from pathlib import Path

        from .. import __version__
        from ..cache import fingerprint

        _GENERATOR.append(fingerprint(__version__, sp.__version__, Path(__file__).read_text()))
    return _GENERATOR[0]


def _generated(exprs, dvars, extra=()) -> dict:
    """``exprs`` with their nonzero first and lower-triangle second derivatives in ``dvars``
    (further arguments ``extra``): {"n_out", "jac", "hess", "values", "first", "second"},
    the last three NumPy sources of functions of ``dvars + extra``. Taken from the disk
    cache (ocdsl/cache.py, kind ``nlp``) when it holds them: the key is the expressions
    themselves, with the arguments renamed by position, so a study's points and a second
    run of a file skip SymPy's differentiation."""
    from .. import cache

    args = list(dvars) + list(extra)
    stand = [sp.Symbol(f"_a{i}", **a.assumptions0) for i, a in enumerate(args)]
    norm = [sp.sympify(e).xreplace(dict(zip(args, stand))) for e in exprs]
    free = set().union(*(e.free_symbols for e in norm)) - set(stand) if norm else set()
    if free:
        raise Unsupported(f"the expressions use {', '.join(sorted(str(s) for s in free))}")
    key = cache.fingerprint(_generator_id(), str(len(dvars)), sp.srepr(stand), sp.srepr(norm))
    entry = cache.read_entry("nlp", key)
    if not (isinstance(entry, dict) and entry.get("n_out") == len(norm)):
        jac, jexprs, hess, hexprs = _derivatives(norm, stand[:len(dvars)])
        entry = {"n_out": len(norm), "jac": jac, "hess": hess, "values": _source(stand, norm),
                 "first": _source(stand, jexprs), "second": _source(stand, hexprs)}
        cache.write_entry("nlp", key, entry)
    return entry


@dataclass
class _Family:
    """Expressions of one node's local variables w (and the node's normalised time S),
    with their nonzero first and (lower-triangle) second derivatives, evaluated for many
    nodes at once."""

    n_out: int
    jac: np.ndarray       # (E1, 2): output, local variable
    hess: np.ndarray      # (E2, 3): output, local a, local b (b <= a)
    _values: Any
    _first: Any
    _second: Any

    @classmethod
    def compile(cls, exprs: list, wsyms: list, S: sp.Symbol) -> "_Family":
        g = _generated(exprs, wsyms, [S])
        return cls(g["n_out"], np.array(g["jac"], int).reshape(-1, 2), np.array(g["hess"], int).reshape(-1, 3),
                   _function(g["values"]), _function(g["first"]), _function(g["second"]))

    @staticmethod
    def _stack(fn, n_rows, cols, nodes) -> np.ndarray:
        if fn is None or n_rows == 0:
            return np.zeros((0, nodes))
        return fn(*cols, np.empty((n_rows, nodes)))

    def values(self, cols, nodes):
        return self._stack(self._values, self.n_out, cols, nodes)

    def first(self, cols, nodes):
        return self._stack(self._first, len(self.jac), cols, nodes)

    def second(self, cols, nodes):
        return self._stack(self._second, len(self.hess), cols, nodes)


@dataclass
class _Scalars:
    """The objective (output 0) and the general boundary constraints (outputs 1..) as
    functions of the scalar symbols: y entries (boundary values, t0/tf, parameters) and
    integrals, which may only enter linearly (their coefficients are constants)."""

    n_out: int            # 1 + number of general boundary constraints
    symbols: list         # ("y", y index) or ("I", (phase, integral)) of each argument, y first
    jac: list             # (output, symbol position, ) nonzero first derivatives in y symbols
    hess: list            # (output, a, b) b <= a, y symbols only
    integral_coef: list   # (output, phase index, integral index, constant coefficient)
    _values: Any
    _first: Any
    _second: Any

    @property
    def y_of(self) -> list:
        """index in y of each non-integral symbol (the first arguments)"""
        return [ref for kind, ref in self.symbols if kind == "y"]

    def evaluate(self, z, which):
        fn = {"values": self._values, "first": self._first, "second": self._second}[which]
        if fn is None:
            return np.zeros(0)
        n = {"values": self.n_out, "first": len(self.jac), "second": len(self.hess)}[which]
        return fn(*z, np.empty(n))


class DirectNLP:
    """The NLP of a Transcription as cyipopt's problem object (objective, gradient,
    constraints, jacobian, jacobianstructure, hessian, hessianstructure)."""

    def __init__(self, tr, compiled, extra_rows=()):
        import pyomo.core as pyo
        from pyomo.core.base.var import VarData

        self.tr = tr
        c = compiled
        # --- y: every Pyomo VarData / Param the rows use; x: the unfixed VarData ---------
        entries = c["entries"]
        self.entries = entries
        values, fixed, lower, upper = [], [], [], []
        for e in entries:                      # one pass: 0.1 s at 100k variables
            if isinstance(e, VarData):
                values.append(e.value)
                fixed.append(e.fixed)
                lower.append(e.lb)
                upper.append(e.ub)
            else:                              # a Param: a constant of this solve
                values.append(pyo.value(e))
                fixed.append(True)
                lower.append(None)
                upper.append(None)

        def array(xs, none):
            a = np.array(xs, dtype=float)      # None -> nan
            a[np.isnan(a)] = none
            return a

        self.free = np.flatnonzero(~np.array(fixed, bool))
        self.n = len(self.free)
        self.xmap = np.full(len(entries), -1)
        self.xmap[self.free] = np.arange(self.n)
        self.y = array(values, 0.0)
        self.x0 = self.y[self.free].copy()
        self.xl = array(lower, -INF)[self.free]
        self.xu = array(upper, INF)[self.free]
        free_vars = [entries[i] for i in self.free]
        self.variables = free_vars
        self.phases = c["phases"]
        self.scalars = c["scalars"]
        # Pyomo constraint data in row order: the transcription's, then the added linear ones
        self.rows = list(c["rows"]) + [r[0] for r in extra_rows]
        self.m = len(self.rows)
        self.gl = np.concatenate([np.asarray(c["gl"], float), [r[2] for r in extra_rows]])
        self.gu = np.concatenate([np.asarray(c["gu"], float), [r[3] for r in extra_rows]])
        base = len(c["rows"])
        self._extra_lin = [(base + i, y, coef) for i, r in enumerate(extra_rows) for y, coef in r[1]]
        self.boundary_base = c["boundary_base"]
        self._assemble()
        self._cache_x = None

    # -- compilation (once per Transcription, kept on it) -----------------------------------
    @classmethod
    def of(cls, tr) -> tuple["DirectNLP | None", str]:
        """(the NLP, "") or (None, why this model takes the PyNumero route)."""
        import pyomo.core as pyo

        tr = tr.defining or tr
        # checked before compiling: mesh refinement's regularisation, for one, adds a term to
        # the built objective of every mesh
        objs = list(tr.model.component_data_objects(pyo.Objective, active=True))
        if len(objs) != 1 or objs[0] is not tr.model.objective:
            return None, "the model's objective was replaced"
        if tr.model.objective.expr is not tr.built_objective:
            return None, "the objective was changed after the build"
        try:
            compiled = getattr(tr, "_direct_nlp", None)
            if compiled is None:
                compiled = _compile(tr)
                tr._direct_nlp = compiled
            if isinstance(compiled, str):
                return None, compiled
            # every row the transcription built must still be active; rows added to the built
            # model since (mesh refinement's control junctions) are taken if they are linear
            ids = compiled.setdefault("row_ids", {id(c) for c in compiled["rows"]})
            active = list(tr.model.component_data_objects(pyo.Constraint, active=True))
            extra = [c for c in active if id(c) not in ids]
            if len(active) - len(extra) != len(ids):
                return None, "a row the transcription built is no longer active"
            extra_rows = [_linear_row(c, compiled) for c in extra]
            if any(r is None for r in extra_rows):
                return None, "a nonlinear constraint was added to the built model"
            return cls(tr, compiled, extra_rows), ""
        except Unsupported as e:
            tr._direct_nlp = str(e)
            return None, str(e)

    # -- assembly of the scatter indices ------------------------------------------------------
    def _assemble(self) -> None:
        n, xmap = self.n, self.xmap
        jrow, jcol, jsrc, jcoef = [], [], [], []      # Jacobian contributions
        grow_col, grow_src, grow_coef = [], [], []    # objective gradient contributions
        hr, hc, hsrc = [], [], []                     # Hessian contributions (value = source)
        lin_rows, lin_cols, lin_coef = [], [], []
        vrow, vsrc, vcoef = [], [], []                # constraint value contributions
        off_j = 0        # offsets into the Jacobian source vector
        off_v = 0        # into the value source vector
        off_h = 0        # into the Hessian source vector
        if self._extra_lin:
            r, y, k = zip(*self._extra_lin)
            lin_rows.append(np.array(r, int)); lin_cols.append(np.array(y, int)); lin_coef.append(np.array(k, float))
        for ph in self.phases:
            C = ph["nodes"]
            W = ph["W"]                               # (C, nl) y index of each local variable
            G, g, H = ph["G"], ph["g"], ph["H"]
            # linear parts of the collocation rows
            lin_rows.append(ph["lin_row"]); lin_cols.append(ph["lin_y"]); lin_coef.append(ph["lin_coef"])
            # terms coef * G_j(w_n) in rows
            t_row, t_node, t_out, t_coef = ph["t_row"], ph["t_node"], ph["t_out"], ph["t_coef"]
            vrow.append(t_row); vsrc.append(off_v + t_out * C + t_node); vcoef.append(t_coef)
            off_v += G.n_out * C
            for e, (o, a) in enumerate(G.jac):
                sel = t_out == o
                jrow.append(t_row[sel]); jcol.append(W[t_node[sel], a])
                jsrc.append(off_j + e * C + t_node[sel]); jcoef.append(t_coef[sel])
            off_j += len(G.jac) * C
            for e, (o, a, b) in enumerate(G.hess):
                hr.append(W[:, a]); hc.append(W[:, b]); hsrc.append(off_h + e * C + np.arange(C))
            off_h += len(G.hess) * C
            # path constraints g_c(w_n): row = path_base + n * npath + c
            if g is not None:
                npath = g.n_out
                base = ph["path_base"]
                nodes = np.arange(C)
                for q in range(npath):
                    vrow.append(base + nodes * npath + q); vsrc.append(off_v + q * C + nodes)
                    vcoef.append(np.ones(C))
                off_v += npath * C
                for e, (o, a) in enumerate(g.jac):
                    jrow.append(base + nodes * npath + o); jcol.append(W[:, a])
                    jsrc.append(off_j + e * C + nodes); jcoef.append(np.ones(C))
                off_j += len(g.jac) * C
                for e, (o, a, b) in enumerate(g.hess):
                    hr.append(W[:, a]); hc.append(W[:, b]); hsrc.append(off_h + e * C + nodes)
                off_h += len(g.hess) * C
            # integrals I_q = sum_n weight_n H_q(w_n): enter rows/objective with constant coefficients
            if H is not None:
                for out, ph_i, q, coef in self.scalars.integral_coef:
                    if ph_i != ph["index"]:
                        continue
                    for e, (o, a) in enumerate(H.jac):
                        if o != q:
                            continue
                        src = off_j + e * C + np.arange(C)
                        if out == 0:
                            grow_col.append(W[:, a]); grow_src.append(src); grow_coef.append(coef * ph["weights"])
                        else:
                            jrow.append(np.full(C, self._boundary_row(out)))
                            jcol.append(W[:, a]); jsrc.append(src); jcoef.append(coef * ph["weights"])
                off_j += len(H.jac) * C
                for e, (o, a, b) in enumerate(H.hess):
                    hr.append(W[:, a]); hc.append(W[:, b]); hsrc.append(off_h + e * C + np.arange(C))
                off_h += len(H.hess) * C
        # scalar level: objective (output 0) and boundary rows
        s = self.scalars
        y_of = s.y_of
        for e, (out, a) in enumerate(s.jac):
            ycol = y_of[a]
            if out == 0:
                grow_col.append(np.array([ycol])); grow_src.append(np.array([off_j + e])); grow_coef.append(np.ones(1))
            else:
                jrow.append(np.array([self._boundary_row(out)])); jcol.append(np.array([ycol]))
                jsrc.append(np.array([off_j + e])); jcoef.append(np.ones(1))
        off_j += len(s.jac)
        self._s_val = off_v
        for out in range(1, s.n_out):
            vrow.append(np.array([self._boundary_row(out)])); vsrc.append(np.array([off_v + out]))
            vcoef.append(np.ones(1))
        off_v += s.n_out
        for e, (out, a, b) in enumerate(s.hess):
            hr.append(np.array([y_of[a]])); hc.append(np.array([y_of[b]])); hsrc.append(np.array([off_h + e]))
        off_h += len(s.hess)

        cat = lambda parts, dtype=float: (np.concatenate(parts).astype(dtype) if parts  # noqa: E731
                                          else np.zeros(0, dtype))
        # constraint values: bincount(rows, coef * y[cols] (linear parts), vcoef * vsource[vsrc])
        # in one pass (NumPy alone: scipy.sparse would be 0.25 s of import for one product)
        self._arow, self._acol, self._acoef = cat(lin_rows, int), cat(lin_cols, int), cat(lin_coef)
        self._vrow, self._vsrc, self._vcoef = cat(vrow, int), cat(vsrc, int), cat(vcoef)
        self._crow = np.concatenate([self._arow, self._vrow])
        # Jacobian: linear contributions (source = 1) and nonlinear ones, in x columns
        lr, lc, lk = cat(lin_rows, int), cat(lin_cols, int), cat(lin_coef)
        rows = np.concatenate([lr, cat(jrow, int)])
        cols_y = np.concatenate([lc, cat(jcol, int)])
        src = np.concatenate([np.full(len(lr), -1), cat(jsrc, int)])
        coef = np.concatenate([lk, cat(jcoef)])
        cols = xmap[cols_y]
        keep = cols >= 0
        rows, cols, src, coef = rows[keep], cols[keep], src[keep], coef[keep]
        key = rows.astype(np.int64) * max(n, 1) + cols
        uniq, slot = np.unique(key, return_inverse=True)
        self._jrows, self._jcols = (uniq // max(n, 1)).astype(np.int32), (uniq % max(n, 1)).astype(np.int32)
        lin = src < 0
        self._jconst = np.bincount(slot[lin], weights=coef[lin], minlength=len(uniq))
        self._jslot, self._jsrc, self._jcoef = slot[~lin], src[~lin], coef[~lin]
        # objective gradient
        gc_ = xmap[cat(grow_col, int)]
        keep = gc_ >= 0
        self._gcol, self._gsrc, self._gcoef = gc_[keep], cat(grow_src, int)[keep], cat(grow_coef)[keep]
        # Hessian (lower triangle in x)
        a, b = xmap[cat(hr, int)], xmap[cat(hc, int)]
        hs = cat(hsrc, int)
        keep = (a >= 0) & (b >= 0)
        a, b, hs = a[keep], b[keep], hs[keep]
        r, cc = np.maximum(a, b), np.minimum(a, b)
        key = r.astype(np.int64) * max(n, 1) + cc
        uniq, slot = np.unique(key, return_inverse=True)
        self._hrows, self._hcols = (uniq // max(n, 1)).astype(np.int32), (uniq % max(n, 1)).astype(np.int32)
        self._hslot, self._hsrc = slot, hs

    def _boundary_row(self, out: int) -> int:
        return self.boundary_base + out - 1

    # -- evaluation ---------------------------------------------------------------------------
    def _set(self, x) -> None:
        if self._cache_x is not None and np.array_equal(x, self._cache_x):
            return
        self._cache_x = np.array(x, float)
        self.y[self.free] = x
        self._vals = self._firsts = None

    def _cols(self, ph):
        return [self.y[ph["W"][:, a]] for a in range(ph["W"].shape[1])] + [ph["S"]]

    def _scalar_z(self):
        s = self.scalars
        z = []
        for kind, ref in s.symbols:
            if kind == "y":
                z.append(self.y[ref])
            else:
                ph_i, q = ref
                z.append(self._integrals[ph_i][q])
        return z

    def _eval_first(self) -> None:
        if self._vals is not None:
            return
        vparts, jparts = [], []
        self._integrals = {}
        with np.errstate(all="ignore"):
            for ph in self.phases:
                C, cols = ph["nodes"], self._cols(ph)
                vparts.append(ph["G"].values(cols, C).ravel())
                jparts.append(ph["G"].first(cols, C).ravel())
                if ph["g"] is not None:
                    vparts.append(ph["g"].values(cols, C).ravel())
                    jparts.append(ph["g"].first(cols, C).ravel())
                if ph["H"] is not None:
                    Hv = ph["H"].values(cols, C)
                    self._integrals[ph["index"]] = Hv @ ph["weights"]
                    jparts.append(ph["H"].first(cols, C).ravel())
            z = self._scalar_z()
            vparts.append(self.scalars.evaluate(z, "values"))
            jparts.append(self.scalars.evaluate(z, "first"))
        self._vals = np.concatenate(vparts)
        self._firsts = np.concatenate(jparts)

    def objective(self, x):
        self._set(x)
        self._eval_first()
        return _finite(float(self._vals[self._s_val]), "objective")

    def gradient(self, x):
        self._set(x)
        self._eval_first()
        return _finite(np.bincount(self._gcol, weights=self._gcoef * self._firsts[self._gsrc], minlength=self.n),
                       "objective gradient")

    def constraints(self, x):
        self._set(x)
        self._eval_first()
        w = np.concatenate([self._acoef * self.y[self._acol], self._vcoef * self._vals[self._vsrc]])
        return _finite(np.bincount(self._crow, weights=w, minlength=self.m), "constraints")

    def jacobianstructure(self):
        return self._jrows, self._jcols

    def jacobian(self, x):
        self._set(x)
        self._eval_first()
        return _finite(self._jconst + np.bincount(self._jslot, weights=self._jcoef * self._firsts[self._jsrc],
                                                  minlength=len(self._jrows)), "Jacobian")

    def hessianstructure(self):
        return self._hrows, self._hcols

    def hessian(self, x, lagrange, obj_factor):
        self._set(x)
        self._eval_first()
        lam = np.asarray(lagrange, float)
        parts = []
        with np.errstate(all="ignore"):
            for ph in self.phases:
                C, cols = ph["nodes"], self._cols(ph)
                G = ph["G"]
                # mu_{j,n}: the rows' multipliers gathered onto each node's G_j
                mu = np.bincount(ph["t_out"] * C + ph["t_node"], weights=ph["t_coef"] * lam[ph["t_row"]],
                                 minlength=G.n_out * C).reshape(G.n_out, C)
                parts.append((G.second(cols, C) * mu[G.hess[:, 0]]).ravel())
                if ph["g"] is not None:
                    g = ph["g"]
                    lp = lam[ph["path_base"]: ph["path_base"] + g.n_out * C].reshape(C, g.n_out).T
                    parts.append((g.second(cols, C) * lp[g.hess[:, 0]]).ravel())
                if ph["H"] is not None:
                    H = ph["H"]
                    mq = np.zeros(H.n_out)
                    for out, ph_i, q, coef in self.scalars.integral_coef:
                        if ph_i == ph["index"]:
                            mq[q] += coef * (obj_factor if out == 0 else lam[self._boundary_row(out)])
                    parts.append((H.second(cols, C) * (mq[H.hess[:, 0]][:, None] * ph["weights"][None, :])).ravel())
            s = self.scalars
            w_out = np.array([obj_factor] + [lam[self._boundary_row(o)] for o in range(1, s.n_out)])
            hv = s.evaluate(self._scalar_z(), "second")
            parts.append(hv * w_out[np.array([h[0] for h in s.hess], int)] if len(s.hess) else np.zeros(0))
        source = np.concatenate(parts)
        return _finite(np.bincount(self._hslot, weights=source[self._hsrc], minlength=len(self._hrows)), "Hessian")

    def intermediate(self, *args):
        return True

    # -- results back into the Pyomo model ----------------------------------------------------
    def load(self, x, mult_g, zl, zu) -> None:
        from pyomo.core.base.suffix import active_import_suffix_generator

        for v, val in zip(self.variables, x):
            v.set_value(float(val), skip_validation=True)
        model = self.tr.model
        suffixes = dict(active_import_suffix_generator(model))
        if "dual" in suffixes:
            suffixes["dual"].clear()
            suffixes["dual"].update(zip(self.rows, (float(v) for v in mult_g)))
        for name, values in (("ipopt_zL_out", zl), ("ipopt_zU_out", zu)):
            if name in suffixes:
                suffixes[name].clear()
                suffixes[name].update(zip(self.variables, (float(v) for v in values)))

    def info(self) -> dict:
        eq = int(np.sum(self.gl == self.gu))
        return {"variables": self.n, "constraints": self.m, "nonzeros": len(self._jrows),
                "hessian_nonzeros": len(self._hrows), "equality_constraints": eq,
                "inequality_constraints": self.m - eq, "evaluation": "direct (NumPy)"}


def _finite(values, what):
    """``values``, or Ipopt's evaluation error where a node function left its domain (a
    square root or logarithm of a negative number, an overflow): Ipopt then cuts its step
    back, as it does for the ASL's evaluation errors on the PyNumero route."""
    if np.all(np.isfinite(values)):
        return values
    import cyipopt

    raise cyipopt.CyIpoptEvaluationError(f"non-finite {what}")


# ------------------------------------------------------------------------------------------
# reading the structure of a built Transcription
# ------------------------------------------------------------------------------------------

def _compile(tr):
    """The structure and compiled functions of ``tr``; a string when it is not covered."""
    import pyomo.core as pyo
    from pyomo.core.base.var import VarData

    problem, model = tr.problem, tr.model
    entries: list = []
    index: dict[int, int] = {}

    def y_of(obj) -> int:
        k = id(obj)
        if k not in index:
            index[k] = len(entries)
            entries.append(obj)
        return index[k]

    free = sorted(problem.free_parameters, key=str)
    times = {sym for pb in tr.phases for sym in (pb.phase.t0_symbol, pb.phase.tf_symbol)}
    # constants kept as symbols (build(mutable=...)) are mutable Params, arguments like parameters
    consts = sorted([s for s, v in tr.scalars.items() if _is_param(v) and s not in times], key=str)
    T0, TF, S = sp.Dummy("t0"), sp.Dummy("tf"), sp.Dummy("s")
    rows: list = []
    gl: list = []
    gu: list = []
    phases = []
    for ip, pb in enumerate(tr.phases):
        ph, lay, b = pb.phase, pb.layout, pb.block
        nx, nu = len(ph.states), len(ph.controls)
        C = lay.n_colloc
        X = _indexed(b.X, (lay.n_state_nodes, nx), entries, index)
        U = _indexed(b.U, (C, nu), entries, index)
        t0i, tfi = y_of(b.t0), y_of(b.tf)
        pidx = [y_of(tr.scalars[s]) for s in free + consts]
        colloc_state = np.concatenate(lay.colloc_state)
        W = np.concatenate([X[colloc_state], U, np.full((C, 1), t0i), np.full((C, 1), tfi),
                            np.tile(np.array(pidx, int), (C, 1)).reshape(C, len(pidx))], axis=1)
        wsyms = list(ph.states) + list(ph.controls) + [T0, TF] + free + consts
        path_exprs = [c.expr for c in ph.path]
        G, g, H = _families(ph, wsyms, (T0, TF, S))
        # rows: the model's defect, end and path constraint data, in this order
        base = len(rows)
        rows.extend(pb.defects.values())
        rows.extend(pb.ends.values())
        gl.extend([0.0] * (len(rows) - base))
        gu.extend([0.0] * (len(rows) - base))
        lin, terms, weights = _collocation_rows(pb, X, base)
        path_base = len(rows)
        if path_exprs:
            rows.extend(b.path[i] for i in range(C * len(path_exprs)))
            gl.extend([-INF if not math.isfinite(c.lower) else c.lower for c in ph.path] * C)
            gu.extend([INF if not math.isfinite(c.upper) else c.upper for c in ph.path] * C)
        phases.append({"index": ip, "nodes": C, "W": W, "S": np.asarray(lay.s_colloc, float),
                       "G": G, "g": g, "H": H, "weights": weights, "path_base": path_base,
                       "lin_row": lin[0], "lin_y": lin[1], "lin_coef": lin[2],
                       "t_row": terms[0], "t_node": terms[1], "t_out": terms[2], "t_coef": terms[3]})
    # scalar level: objective and the general boundary constraints (the model's m.boundary)
    boundary_base = len(rows)
    general = tr.boundary_general
    cons = list(model.boundary.values())
    if len(cons) != len(general):
        raise Unsupported("the boundary constraints do not match the problem's")
    for con, c in zip(cons, general):
        rows.append(con)
        gl.append(-INF if not math.isfinite(c.lower) else c.lower)
        gu.append(INF if not math.isfinite(c.upper) else c.upper)
    # a maximised objective is minimised negated, as PyNumero does, so that the multipliers
    # Ipopt returns have PyNumero's signs on both routes
    sign = 1 if problem.objective.sense == "minimize" else -1
    exprs = [sign * problem.objective.expr] + [c.expr for c in general]
    _check_smooth(exprs, "the objective or a boundary constraint")
    integral_of = {s: (ip, q) for ip, pb in enumerate(tr.phases) for q, s in enumerate(pb.phase.integrals)}
    syms = sorted(set().union(*[sp.sympify(e).free_symbols for e in exprs]), key=str)
    ysyms = [s for s in syms if s not in integral_of]
    isyms = [s for s in syms if s in integral_of]
    for s in ysyms:
        target = tr.scalars.get(s)
        if target is None or not (isinstance(target, VarData) or _is_param(target)):
            raise Unsupported(f"the objective or a boundary constraint uses {s}")
    y_of_sym = [y_of(tr.scalars[s]) for s in ysyms]
    icoef = []
    for out, e in enumerate(exprs):
        for s in isyms:
            d = sp.diff(sp.sympify(e), s)
            if d.free_symbols:
                raise Unsupported("the objective or a boundary constraint is nonlinear in an integral")
            if d != 0:
                ip, q = integral_of[s]
                icoef.append((out, ip, q, float(d)))
    gen = _generated(exprs, ysyms, isyms)
    symbols = [("y", y) for y in y_of_sym] + [("I", integral_of[s]) for s in isyms]
    scal = _Scalars(len(exprs), symbols, [tuple(j) for j in gen["jac"]], [tuple(h) for h in gen["hess"]], icoef,
                    _function(gen["values"]), _function(gen["first"]), _function(gen["second"]))
    # every variable the model has must be an entry (unused ones too: PyNumero drops them,
    # Ipopt keeps them at their start)
    for v in model.component_data_objects(pyo.Var):
        y_of(v)
    return {"entries": entries, "phases": phases, "scalars": scal, "rows": rows, "gl": gl, "gu": gu,
            "boundary_base": boundary_base}


def _indexed(var, shape, entries, index) -> np.ndarray:
    """y indices of a 2-index Var's data, appended to ``entries`` in one pass."""
    out = np.full(shape, -1, int)
    keys = list(var.keys())
    if keys:
        k = np.array(keys, int).reshape(-1, 2)
        out[k[:, 0], k[:, 1]] = np.arange(len(entries), len(entries) + len(keys))
        for v in var.values():
            index[id(v)] = len(entries)
            entries.append(v)
    return out


def _collocation_rows(pb, X, base):
    """The defect and end rows of one phase, vectorised over rows of the same scheme: linear
    parts (row, y index, coefficient) and terms coef * G_j(w_node) (row, node, j, coefficient),
    as ``pseudospectral._build_phase`` writes them, plus each collocation node's quadrature
    weight (for the integrals). Rows are numbered from ``base`` in the order of
    ``pb.defects`` then ``pb.ends``."""
    from .nodes import lobatto_integration_matrix, scheme

    lay = pb.layout
    mesh = lay.mesh
    K = mesh.segments
    half_h = np.diff(mesh.breakpoints) / 2.0
    weights = np.zeros(lay.n_colloc)
    for k in range(K):
        weights[lay.colloc[k]] = np.asarray(mesh.scheme(k).weights, float) * half_h[k]
    lin, terms = [], []
    # defect rows (k, i, j), grouped by their segment's degree
    keys = np.array(list(pb.defects.keys()), int).reshape(-1, 3)
    rows = base + np.arange(len(keys))
    degrees = np.asarray(mesh.degrees)
    for d in np.unique(degrees):
        sc = scheme(mesh.scheme_name, int(d))
        segs = np.flatnonzero(degrees == d)
        pos = np.full(K, -1)
        pos[segs] = np.arange(len(segs))
        sup = np.array([lay.support[k] for k in segs], int)          # (segments, m)
        col = np.array([lay.colloc[k] for k in segs], int)           # (segments, n)
        sel = degrees[keys[:, 0]] == d
        r, k, i, j = rows[sel], keys[sel, 0], keys[sel, 1], keys[sel, 2]
        p = pos[k]
        if sc.name == "LGL":
            # X_i - X_0 - h/2 * sum_l A_il (tf - t0) F_l
            lin.append((np.concatenate([r, r]), np.concatenate([X[sup[p, i], j], X[sup[p, 0], j]]),
                        np.concatenate([np.ones(len(r)), -np.ones(len(r))])))
            A = lobatto_integration_matrix(sc.degree)
            coef = -half_h[k][:, None] * A[i, :]                       # (rows, n)
            nz = coef != 0.0
            terms.append((np.broadcast_to(r[:, None], coef.shape)[nz], col[p][nz],
                          np.broadcast_to(j[:, None], coef.shape)[nz], coef[nz]))
        else:
            # D_i . X - h/2 (tf - t0) F_i
            D = np.asarray(sc.D, float)[i, :]                          # (rows, m)
            nz = D != 0.0
            ys = X[sup[p], j[:, None]]                                 # (rows, m)
            lin.append((np.broadcast_to(r[:, None], D.shape)[nz], ys[nz], D[nz]))
            terms.append((r, col[p, i], j, -half_h[k]))
    # LG end rows (k, j): X_end - X_0 - h/2 sum_i w_i (tf - t0) F_i
    if pb.ends:
        ekeys = np.array(list(pb.ends.keys()), int).reshape(-1, 2)
        r = base + len(keys) + np.arange(len(ekeys))
        k, j = ekeys[:, 0], ekeys[:, 1]
        start = np.array([lay.support[kk][0] for kk in k], int)
        endn = np.array([lay.end[kk] for kk in k], int)
        lin.append((np.concatenate([r, r]), np.concatenate([X[endn, j], X[start, j]]),
                    np.concatenate([np.ones(len(r)), -np.ones(len(r))])))
        for kk_r, kk, jj in zip(r, k, j):
            sc = mesh.scheme(kk)
            cns = np.asarray(lay.colloc[kk], int)
            terms.append((np.full(len(cns), kk_r), cns, np.full(len(cns), jj),
                          -half_h[kk] * np.asarray(sc.weights, float)))
    cat = lambda parts, t: np.concatenate([np.asarray(q[t]) for q in parts]) if parts else np.zeros(0)  # noqa: E731
    return ((cat(lin, 0).astype(int), cat(lin, 1).astype(int), cat(lin, 2).astype(float)),
            (cat(terms, 0).astype(int), cat(terms, 1).astype(int), cat(terms, 2).astype(int),
             cat(terms, 3).astype(float)), weights)


def _families(ph, wsyms, times):
    """The phase's dynamics, path and integrand families; compiled once per Phase object
    (kept on it), so that rebuilt meshes (mesh refinement, multi-start) and the points of a
    reused study model do not differentiate again."""
    key = (tuple(wsyms[len(ph.states) + len(ph.controls) + 2:]),)
    cached = getattr(ph, "_direct_families", None)
    if cached is not None and cached[0] == key:
        return cached[1]         # positional functions: which dummy symbols made them is moot
    T0, TF, S = times
    t_sub = {TIME: T0 + (TF - T0) * S}
    duration = TF - T0
    rhs = list(ph.rhs())
    _check_smooth(rhs, "the dynamics")
    G = _Family.compile([duration * sp.sympify(e).xreplace(t_sub) for e in rhs], wsyms, S)
    path_exprs = [c.expr for c in ph.path]
    _check_smooth(path_exprs, "a path constraint")
    g = _Family.compile([sp.sympify(e).xreplace(t_sub) for e in path_exprs], wsyms, S) if path_exprs else None
    integrands = list(ph.integrals.values())
    _check_smooth(integrands, "an integral")
    H = _Family.compile([duration * sp.sympify(e).xreplace(t_sub) for e in integrands], wsyms, S) if integrands else None
    ph._direct_families = (key, (G, g, H))
    return G, g, H


def _linear_row(con, compiled):
    """(con, [(y index, coefficient)], lower, upper) of a linear constraint data, else None."""
    from pyomo.repn import generate_standard_repn

    repn = generate_standard_repn(con.body, compute_values=True, quadratic=False)
    if not repn.is_linear():
        return None
    index = compiled.setdefault("entry_index", {id(e): i for i, e in enumerate(compiled["entries"])})
    terms = []
    for v, coef in zip(repn.linear_vars, repn.linear_coefs):
        if id(v) not in index:
            return None
        terms.append((index[id(v)], float(coef)))
    const = float(repn.constant)
    lo = -INF if con.lb is None else float(con.lb) - const
    hi = INF if con.ub is None else float(con.ub) - const
    # the constant moves into the bounds: the row's value is the linear part alone
    return con, terms, lo, hi


def _is_param(obj) -> bool:
    from pyomo.core.base.param import ParamData, ScalarParam

    return isinstance(obj, (ParamData, ScalarParam))

