"""The model's functions at the nodes of a solution (lambdified once per model and parameters), the
node arrays of a trajectory, and H and dH/du there."""
from __future__ import annotations

from typing import Mapping

import numpy as np
import sympy as sp

from ocdsl.symbolic.model import TIME, Model

from ...symbolic.engine import jacobian
from .conditions import _param_subs

class _Numeric:
    """Lambdified f, df/dx, df/du, L, dL/du, df/dt, dL/dt of a model at fixed parameters."""

    def __init__(self, model: Model, parameter_values: Mapping | None, lagrange, path=()):
        subs = _param_subs(model, parameter_values)
        self.model = model
        x, u = list(model.states), list(model.controls)
        from ...symbolic.numbers import substitute_numbers   # exp(885 - r/H) kept whole

        f = substitute_numbers(model.rhs(), subs)
        L = sp.Matrix([substitute_numbers(model.expand(sp.sympify(lagrange)), subs)])
        G = sp.Matrix([substitute_numbers(model.expand(sp.sympify(g)), subs) for g in path])
        left = (f.free_symbols | L.free_symbols | G.free_symbols) - set(x) - set(u) - {TIME}
        if left:
            raise ValueError(f"certificate: no value for {sorted(s.name for s in left)}")
        self.time_dependent = TIME in (f.free_symbols | L.free_symbols | G.free_symbols)
        self.n, self.m, self.p = len(x), len(u), len(path)

        def make():      # matrices as their flat (row-major) entries
            d = {"f": f, "fx": jacobian(f, x), "fu": jacobian(f, u), "L": L, "Lu": jacobian(L, u),
                 "ft": jacobian(f, [TIME]), "Lt": jacobian(L, [TIME])}
            if self.p:
                d.update(g=G, gu=jacobian(G, u), gt=jacobian(G, [TIME]))
            return {k: (list(e), "numpy") for k, e in d.items()}

        from ...symbolic.numeric import family   # printed once, then from the disk cache

        fns = family([TIME, *x, *u], ("certificate", f, L, G), make)

        def at(fn):
            return lambda t, xs, us: fn(t, *xs, *us)

        self._f, self._fx, self._fu = at(fns["f"]), at(fns["fx"]), at(fns["fu"])
        self._L, self._Lu, self._ft, self._Lt = at(fns["L"]), at(fns["Lu"]), at(fns["ft"]), at(fns["Lt"])
        if self.p:
            self._g, self._gu, self._gt = at(fns["g"]), at(fns["gu"]), at(fns["gt"])

    @staticmethod
    def _nodes(fun, t, X, U, shape):
        """Evaluate a lambdified matrix at N nodes -> array (N, *shape)."""
        N = len(t)
        out = fun(t, list(X.T), list(U.T))
        arr = np.empty((N, int(np.prod(shape))))
        for i, entry in enumerate(out):
            arr[:, i] = np.broadcast_to(np.asarray(entry, float), (N,))
        return arr.reshape((N, *shape))

    def f_nodes(self, t, X, U):
        return self._nodes(self._f, t, X, U, (self.n,))

    def fu_nodes(self, t, X, U):
        return self._nodes(self._fu, t, X, U, (self.n, self.m))

    def L_nodes(self, t, X, U):
        return self._nodes(self._L, t, X, U, (1,))[:, 0]

    def Lu_nodes(self, t, X, U):
        return self._nodes(self._Lu, t, X, U, (self.m,))

    def g_nodes(self, t, X, U):
        return self._nodes(self._g, t, X, U, (self.p,))

    def gu_nodes(self, t, X, U):
        return self._nodes(self._gu, t, X, U, (self.p, self.m))

    def Ht_nodes(self, t, X, U, Lam, Mu=None):
        ft = self._nodes(self._ft, t, X, U, (self.n,))
        Lt = self._nodes(self._Lt, t, X, U, (1,))[:, 0]
        Ht = Lt + np.einsum("ki,ki->k", Lam, ft)
        if Mu is not None and self.p:     # dH_aug/dt|explicit
            Ht = Ht + np.einsum("kq,kq->k", Mu, self._nodes(self._gt, t, X, U, (self.p,)))
        return Ht

    def f_point(self, t, x, u):
        return np.asarray(self._f(t, list(x), list(u)), float).reshape(self.n)

    def fx_point(self, t, x, u):
        return np.asarray(self._fx(t, list(x), list(u)), float).reshape(self.n, self.n)


def _columns(model: Model, trajectory):
    """(t, X, U, Lam) of every row of ``trajectory`` (a mapping or a PhaseTrajectory), rows
    with NaN included; Lam None without costates."""
    get = (lambda k: trajectory[k]) if isinstance(trajectory, Mapping) else (lambda k: getattr(trajectory, k))
    t = np.asarray(get("time"), float).ravel()
    states, controls = get("states"), get("controls")
    try:
        costates = get("costates")
    except (KeyError, AttributeError):
        costates = None
    X = np.column_stack([np.asarray(states[s.name], float) for s in model.states])
    U = np.column_stack([np.asarray(controls[c.name], float) for c in model.controls]) \
        if model.controls else np.zeros((len(t), 0))
    Lam = None
    if costates:
        missing = [s.name for s in model.states if s.name not in costates]
        if missing:
            raise ValueError(f"certificate: no costates for {missing}")
        Lam = np.column_stack([np.asarray(costates[s.name], float) for s in model.states])
    if not (len(t) == len(X) == len(U)) or (Lam is not None and len(Lam) != len(t)):
        raise ValueError("certificate: time, states, controls and costates differ in length")
    return t, X, U, Lam


def _arrays(model: Model, trajectory, return_mask: bool = False, multipliers=None):
    """Node arrays (rows with a NaN left out). With ``multipliers`` ((N, p) array) their
    rows count too and the filtered array is returned last."""
    t, X, U, Lam = _columns(model, trajectory)
    if multipliers is not None and len(multipliers) != len(t):
        raise ValueError("certificate: path multipliers and time differ in length")
    # keep the collocation nodes: rows where everything is defined (a back end may also
    # list non-collocated points, e.g. segment ends, with NaN controls or costates)
    keep = np.isfinite(t) & np.isfinite(X).all(axis=1) & np.isfinite(U).all(axis=1)
    if Lam is not None:
        keep &= np.isfinite(Lam).all(axis=1)
    if multipliers is not None:
        keep &= np.isfinite(multipliers).all(axis=1)
    t, X, U = t[keep], X[keep], U[keep]
    Lam = Lam[keep] if Lam is not None else None
    more = (multipliers[keep],) if multipliers is not None else ()
    if return_mask:
        return (t, X, U, Lam, keep) + more
    if len(t) < 2 or np.any(np.diff(t) <= 0):
        raise ValueError("certificate: node times must be strictly increasing (at least 2 nodes)")
    return (t, X, U, Lam) + more


def hamiltonian_arrays(model: Model, parameter_values: Mapping | None, trajectory,
                       lagrange: sp.Expr | float = 0) -> dict[str, np.ndarray]:
    """H and the switching functions dH/du at the nodes, for ``PhaseTrajectory.extra``.

    Keys: ``hamiltonian`` and ``dH_d<control>`` for every control; arrays as long as the
    trajectory's time, NaN on rows with a missing value.
    """
    num = _Numeric(model, parameter_values, lagrange)
    t, X, U, Lam, keep = _arrays(model, trajectory, return_mask=True)
    if Lam is None:
        raise ValueError("hamiltonian_arrays: the trajectory has no costates")
    H, dHdu, _, _ = _hamiltonian_nodes(num, t, X, U, Lam)

    def full(a):   # back onto every row of the trajectory, NaN where a value is missing
        out = np.full(len(keep), np.nan)
        out[keep] = a
        return out

    out = {"hamiltonian": full(H)}
    out.update({f"dH_d{c.name}": full(dHdu[:, j]) for j, c in enumerate(model.controls)})
    return out


def node_shares(t: np.ndarray) -> np.ndarray:
    """Each node's share of the phase's time: half the distance between its neighbours (half
    the end interval at the ends); they sum to the duration."""
    share = np.empty(len(t))
    share[1:-1] = 0.5 * (t[2:] - t[:-2])
    share[0], share[-1] = 0.5 * (t[1] - t[0]), 0.5 * (t[-1] - t[-2])
    return share


def _hamiltonian_nodes(num: _Numeric, t, X, U, Lam):
    f = num.f_nodes(t, X, U)
    fu = num.fu_nodes(t, X, U)
    L = num.L_nodes(t, X, U)
    Lu = num.Lu_nodes(t, X, U)
    H = L + np.einsum("ki,ki->k", Lam, f)
    H_terms = np.abs(L) + np.einsum("ki,ki->k", np.abs(Lam), np.abs(f))
    dHdu = Lu + np.einsum("ki,kij->kj", Lam, fu)
    dHdu_terms = np.abs(Lu) + np.einsum("ki,kij->kj", np.abs(Lam), np.abs(fu))
    return H, dHdu, H_terms, dHdu_terms
