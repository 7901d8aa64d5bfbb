"""The direct NLP as cyipopt's problem object: variables and bounds from the Pyomo model,
the scatter indices of the sparse Jacobian and Hessian, evaluation, and the solution loaded back."""
from __future__ import annotations

import numpy as np

from .codegen import INF, Unsupported
from .structure import _compile, _linear_row


class DirectNLP:
    """The NLP of a Transcription as cyipopt's problem object (objective, gradient,
    constraints, jacobian, jacobianstructure, hessian, hessianstructure)."""

    def __init__(self, tr, compiled, extra_rows=(), penalty=()):
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
        # the objective's added sum coef (y_a - y_b)^2 (Transcription.penalty)
        where = {id(e): i for i, e in enumerate(entries)} if penalty else {}
        if any(id(a) not in where or id(b) not in where for _, a, b in penalty):
            raise Unsupported("a penalised variable is not in the NLP's rows")
        self._pen_c = np.array([c for c, _, _ in penalty], float)
        self._pen_a = np.array([where[id(a)] for _, a, _ in penalty], int)
        self._pen_b = np.array([where[id(b)] for _, _, b in penalty], int)
        self.boundary_base = c["boundary_base"]
        self._assemble()
        self._cache_x = None
        self._gather: dict = {}

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
        penalty = ()
        if tr.model.objective.expr is not tr.built_objective:
            if tr.penalty is None or tr.model.objective.expr is not tr.penalty[0]:
                return None, "the objective was changed after the build"
            penalty = tr.penalty[1]
        if any(pb.free_breakpoints for pb in tr.phases):
            return None, "breakpoints are unknowns of this NLP"
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
            return cls(tr, compiled, extra_rows, penalty), ""
        except Unsupported as e:
            tr._direct_nlp = str(e)
            return None, str(e)

    def with_breakpoints(self, phase: int, mesh) -> "DirectNLP":
        """This NLP with phase ``phase`` on ``mesh``: the same segments, degrees, variables and
        rows, other breakpoints. What moves is data, not structure: the nodes' times and, per
        segment, the width h that scales the dynamics' terms (h/2 (tf - t0) F) and the
        quadrature weights (w h/2). The envelope derivative in a breakpoint
        (``solve.mesh.switches``) differences this against the NLP itself, where it rebuilt
        the Pyomo model and its NLP for each breakpoint (most of a bang-bang mesh iteration)."""
        import copy

        from ..mesh import Layout

        lay = self.tr.phases[phase].layout
        new = Layout.of(mesh)
        if mesh.degrees != lay.mesh.degrees or mesh.scheme_name != lay.mesh.scheme_name:
            raise ValueError("with_breakpoints: the segments and degrees must be the same")
        seg = np.empty(lay.n_colloc, int)
        for k, nodes in enumerate(lay.colloc):
            seg[nodes] = k
        ratio = np.diff(np.asarray(mesh.breakpoints, float)) / np.diff(np.asarray(lay.mesh.breakpoints, float))
        ph = dict(self.phases[phase])
        ph["S"] = np.asarray(new.s_colloc, float)
        ph["t_coef"] = ph["t_coef"] * ratio[seg[ph["t_node"]]]
        ph["weights"] = ph["weights"] * ratio[seg]
        other = copy.copy(self)
        other.phases = [ph if i == phase else p for i, p in enumerate(self.phases)]
        other.y = self.y.copy()
        other._cache_x, other._gather = None, {}
        other._assemble()
        return other

    # -- assembly of the scatter indices ------------------------------------------------------
    def _assemble(self) -> None:
        n, xmap = self.n, self.xmap
        jrow, jcol, jsrc, jcoef = [], [], [], []      # Jacobian contributions
        grow_col, grow_src, grow_coef = [], [], []    # objective gradient contributions
        hr, hc, hsrc = [], [], []                     # Hessian contributions (value = source)
        hmu = []                                      # each one's multiplier slot in the weights
        lin_rows, lin_cols, lin_coef = [], [], []
        vrow, vsrc, vcoef = [], [], []                # constraint value contributions
        off_j = 0        # offsets into the Jacobian source vector
        off_v = 0        # into the value source vector
        off_h = 0        # into the Hessian source vector
        off_w = 0        # into the Hessian weight vector (a multiplier per output and node)
        self._w_of = []  # per phase: the weight offsets of G, g, H
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
                hmu.append(off_w + o * C + np.arange(C))
            off_h += len(G.hess) * C
            w_of = {"G": off_w, "mu_index": t_out * C + t_node}
            off_w += G.n_out * C
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
                    hmu.append(off_w + o * C + nodes)
                off_h += len(g.hess) * C
                w_of["g"] = off_w
                off_w += npath * C
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
                    hmu.append(off_w + o * C + np.arange(C))
                off_h += len(H.hess) * C
                w_of["H"] = off_w
                off_w += H.n_out * C
            self._w_of.append(w_of)
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
            hmu.append(np.array([off_w + out]))
        off_h += len(s.hess)
        self._w_scalar = off_w
        off_w += s.n_out
        # the penalty's constant second derivatives 2c, 2c, -2c at (a, a), (b, b), (a, b), in
        # a region of the Hessian buffer nothing overwrites, weighted by the objective factor
        P = len(self._pen_c)
        pen_h = off_h
        if P:
            for k, (ya, yb) in enumerate(((self._pen_a, self._pen_a), (self._pen_b, self._pen_b),
                                          (self._pen_a, self._pen_b))):
                hr.append(ya); hc.append(yb); hsrc.append(off_h + k * P + np.arange(P))
                hmu.append(np.full(P, self._w_scalar))
            off_h += 3 * P
        # buffers the evaluations write into (no concatenation per call); _eval_first's own
        # and the Hessian's, so that a Hessian never overwrites the values and first derivatives
        self._vbuf, self._jbuf, self._hbuf, self._wbuf = (np.zeros(k) for k in (off_v, off_j, off_h, off_w))
        self._hbuf[pen_h: pen_h + 3 * P] = np.concatenate([2 * self._pen_c, 2 * self._pen_c, -2 * self._pen_c])

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
        hs, hm = cat(hsrc, int), cat(hmu, int)
        keep = (a >= 0) & (b >= 0)
        a, b, hs, hm = a[keep], b[keep], hs[keep], hm[keep]
        r, cc = np.maximum(a, b), np.minimum(a, b)
        key = r.astype(np.int64) * max(n, 1) + cc
        uniq, slot = np.unique(key, return_inverse=True)
        self._hrows, self._hcols = (uniq // max(n, 1)).astype(np.int32), (uniq % max(n, 1)).astype(np.int32)
        self._hslot, self._hsrc, self._hmu = slot, hs, hm

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
        """The (local variables + S, nodes) array of a phase's node functions, gathered in one
        call into this NLP's buffer of the phase (nothing keeps it between calls)."""
        got = self._gather.get(ph["index"])
        if got is None:
            WT = np.ascontiguousarray(ph["W"].T)
            Y = np.empty((WT.shape[0] + 1, ph["nodes"]))
            Y[-1] = ph["S"]
            got = self._gather[ph["index"]] = (WT, Y)
        WT, Y = got
        np.take(self.y, WT, out=Y[:-1], mode="clip")     # "clip": no buffered copy (indices are valid)
        return Y

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
        """Values and first derivatives of every family at the current x, written in place into
        the value and Jacobian source buffers (the order of the offsets of :meth:`_assemble`)."""
        if self._vals is not None:
            return
        vbuf, jbuf = self._vbuf, self._jbuf
        ov = oj = 0
        self._integrals = {}

        def view(buf, off, rows, C):
            return buf[off: off + rows * C].reshape(rows, C)

        with np.errstate(all="ignore"):
            for ph in self.phases:
                C, cols = ph["nodes"], self._cols(ph)
                for F in (ph["G"], ph["g"]):
                    if F is None:
                        continue
                    F.values(cols, C, view(vbuf, ov, F.n_out, C))
                    F.first(cols, C, view(jbuf, oj, len(F.jac), C))
                    ov += F.n_out * C
                    oj += len(F.jac) * C
                if ph["H"] is not None:
                    H = ph["H"]
                    self._integrals[ph["index"]] = H.values(cols, C) @ ph["weights"]
                    H.first(cols, C, view(jbuf, oj, len(H.jac), C))
                    oj += len(H.jac) * C
            z = self._scalar_z()
            s = self.scalars
            s.evaluate(z, "values", vbuf[ov: ov + s.n_out])
            s.evaluate(z, "first", jbuf[oj: oj + len(s.jac)])
        self._vals, self._firsts = vbuf, jbuf

    def objective(self, x):
        self._set(x)
        self._eval_first()
        value = float(self._vals[self._s_val])
        if len(self._pen_c):
            value += float(self._pen_c @ (self.y[self._pen_a] - self.y[self._pen_b]) ** 2)
        return _finite(value, "objective")

    def gradient(self, x):
        self._set(x)
        self._eval_first()
        grad = np.bincount(self._gcol, weights=self._gcoef * self._firsts[self._gsrc], minlength=self.n)
        if len(self._pen_c):
            slope = 2 * self._pen_c * (self.y[self._pen_a] - self.y[self._pen_b])
            for ys, sign in ((self._pen_a, 1.0), (self._pen_b, -1.0)):
                cols = self.xmap[ys]
                free = cols >= 0
                grad += np.bincount(cols[free], weights=sign * slope[free], minlength=self.n)
        return _finite(grad, "objective gradient")

    def constraints(self, x):
        return _finite(self.constraint_values(x), "constraints")

    def constraint_values(self, x):
        """The rows at ``x``, NaN where they have no value (for naming them: Ipopt gets
        :meth:`constraints`, which raises there)."""
        self._set(x)
        self._eval_first()
        w = np.concatenate([self._acoef * self.y[self._acol], self._vcoef * self._vals[self._vsrc]])
        return np.bincount(self._crow, weights=w, minlength=self.m)

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
        """sum over the Hessian sources of (second derivative) x (its output's multiplier at its
        node), scattered: the second derivatives and the multipliers are written into two
        buffers and multiplied entry by entry in the scatter (the products and their order of
        summation are the same as weighting each family's rows first)."""
        self._set(x)
        self._eval_first()
        lam = np.asarray(lagrange, float)
        hbuf, wbuf = self._hbuf, self._wbuf
        oh = 0
        with np.errstate(all="ignore"):
            for ph, w_of in zip(self.phases, self._w_of):
                C, cols = ph["nodes"], self._cols(ph)
                G = ph["G"]
                G.second(cols, C, hbuf[oh: oh + len(G.hess) * C].reshape(-1, C))
                oh += len(G.hess) * C
                # mu_{j,n}: the rows' multipliers gathered onto each node's G_j
                o = w_of["G"]
                wbuf[o: o + G.n_out * C] = np.bincount(w_of["mu_index"], weights=ph["t_coef"] * lam[ph["t_row"]],
                                                       minlength=G.n_out * C)
                if ph["g"] is not None:
                    g = ph["g"]
                    g.second(cols, C, hbuf[oh: oh + len(g.hess) * C].reshape(-1, C))
                    oh += len(g.hess) * C
                    o = w_of["g"]
                    wbuf[o: o + g.n_out * C].reshape(g.n_out, C)[:] = \
                        lam[ph["path_base"]: ph["path_base"] + g.n_out * C].reshape(C, g.n_out).T
                if ph["H"] is not None:
                    H = ph["H"]
                    H.second(cols, C, hbuf[oh: oh + len(H.hess) * C].reshape(-1, C))
                    oh += len(H.hess) * C
                    mq = np.zeros(H.n_out)
                    for out, ph_i, q, coef in self.scalars.integral_coef:
                        if ph_i == ph["index"]:
                            mq[q] += coef * (obj_factor if out == 0 else lam[self._boundary_row(out)])
                    o = w_of["H"]
                    wbuf[o: o + H.n_out * C].reshape(H.n_out, C)[:] = mq[:, None] * ph["weights"][None, :]
            s = self.scalars
            if len(s.hess):
                s.evaluate(self._scalar_z(), "second", hbuf[oh: oh + len(s.hess)])
            o = self._w_scalar
            wbuf[o] = obj_factor
            for out in range(1, s.n_out):
                wbuf[o + out] = lam[self._boundary_row(out)]
            source = hbuf[self._hsrc] * wbuf[self._hmu]
        return _finite(np.bincount(self._hslot, weights=source, minlength=len(self._hrows)), "Hessian")

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
                "inequality_constraints": self.m - eq, "evaluation": f"direct ({self._evaluation()})"}

    def _evaluation(self) -> str:
        """How the node families are evaluated: "NumPy", "C", or each family's way when they differ."""
        ways = [f.evaluation for ph in self.phases for f in (ph["G"], ph["g"], ph["H"]) if f is not None]
        return ", ".join(dict.fromkeys(ways)) or "NumPy"


def _finite(values, what):
    """``values``, or Ipopt's evaluation error where a node function left its domain (a
    square root or logarithm of a negative number, an overflow): Ipopt then cuts its step
    back, as it does for the ASL's evaluation errors on the PyNumero route."""
    if np.all(np.isfinite(values)):
        return values
    import cyipopt

    raise cyipopt.CyIpoptEvaluationError(f"non-finite {what}")
