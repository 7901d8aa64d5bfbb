"""State-dependent coefficient (SDC) factorisation: f(x, u) = A(x) x + B(x) u.

Given a :class:`~ocdsl.symbolic.model.Model` whose dynamics vanish at the origin
(f(0, 0) = 0) and are affine in the controls, :func:`factorise` builds A(x) and B(x)
symbolically so that ``A(x) x + B(x) u - f(x, u)`` simplifies to exactly zero.

Controlled and auxiliary states
-------------------------------
Some plants carry states that the controller neither weights nor regulates (the
reaction-wheel momentum h of the spacecraft model). Name them in ``auxiliary``: they stay
symbols inside A and B (A = A(x, h)), are not columns of A, and their own dynamics are
not factorised. The condition f(0, 0) = 0 is then checked for every value of the
auxiliary states.

How A(x) is built (the documented default)
-----------------------------------------
An SDC factorisation is not unique when n > 1 (for any W(x) with W(x) x = 0, A + W is
another one). ``factorise`` builds one deterministically, row by row:

1. B(x) = df/du (exact, since f is affine in u), and f0(x) = f(x, 0).
2. f0 is expanded into additive terms. For each term the *candidate columns* are the
   controlled states that appear in it as an explicit polynomial factor (``wy`` in
   ``wy*sin(phi)*tan(theta)``). The term is divided among its candidates according to
   ``split``:

   - ``"even"`` (default): in equal shares among all candidates. Symmetric, independent
     of the order in which states are listed.
   - ``"first"`` / ``"last"``: all of it to the first / last candidate in state order.

3. Terms with no polynomial state factor (``sin(x1)``, ``cos(x1) - 1``) are collected into
   a remainder r(x) with r(0) = 0 and factorised by telescoping along the state order:
   r(x) = sum_j [r(x1..xj, 0..) - r(x1..x_{j-1}, 0..)], the j-th difference vanishing at
   xj = 0 and therefore divisible by xj. Quotients with a removable singularity at
   xj = 0 (``sin(x)/x``) get their limit there (``sinc`` or a Piecewise), so the numeric
   callables are finite at the origin.

Every (A, B) is verified: A x + B u - f is simplified to zero, otherwise an error is
raised. Other choices: ``split="first"|"last"``, convex combinations
(:func:`blend`), or a user factorisation (``sdc: given`` in a problem file) through
:func:`given`, which is checked for exactness in the same way.

Pointwise checks
----------------
:func:`check_pointwise` evaluates A(x), B(x) at points and reports the controllability
rank and stabilisability (PBH test) with a clear message where they fail, e.g.
"controllability rank 6 of 9 at x = ...". :func:`lambdify_sdc` makes fast NumPy
callables of the full plant state vector.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np
import sympy as sp

from .model import TIME, Model

SPLITS = ("even", "first", "last")


class SDCError(ValueError):
    """No SDC form exists, or a given one is wrong, or a pointwise check failed."""


@dataclass
class SDC:
    """A factorisation f(x, u) = A(x) x + B(x) u of the controlled part of a model.

    ``states`` are the controlled states (the columns of A and the rows of A and B),
    ``auxiliary`` the plant states that may appear inside A and B, ``method`` says how it
    was built (``auto:even``, ``auto:first``, ``given``, ...).
    """

    model: Model
    states: tuple[sp.Symbol, ...]
    auxiliary: tuple[sp.Symbol, ...]
    controls: tuple[sp.Symbol, ...]
    A: sp.Matrix
    B: sp.Matrix
    f: sp.Matrix            # f(x, u) of the controlled states, parameters symbolic
    method: str
    notes: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.states)

    @property
    def m(self) -> int:
        return len(self.controls)

    def residual(self) -> sp.Matrix:
        x = sp.Matrix(self.states)
        u = sp.Matrix(self.controls)
        return self.A * x + self.B * u - self.f

    def index(self) -> list[int]:
        """Positions of the controlled states in ``model.states``."""
        return [self.model.states.index(s) for s in self.states]


# ---------------------------------------------------------------------------------
# building
# ---------------------------------------------------------------------------------

def _split_states(model: Model, auxiliary: Iterable[str | sp.Symbol] = (),
                  states: Iterable[str | sp.Symbol] | None = None):
    def look(s):
        if isinstance(s, sp.Symbol):
            return s
        try:
            sym = model.symbol(str(s))
        except KeyError:
            raise SDCError(f"model {model.name!r} has no state {s!r}; states: "
                           f"{[str(x) for x in model.states]}") from None
        if sym not in model.states:
            raise SDCError(f"{s!r} is not a state of model {model.name!r}")
        return sym

    aux = tuple(look(s) for s in auxiliary)
    if states is None:
        xs = tuple(s for s in model.states if s not in aux)
    else:
        xs = tuple(look(s) for s in states)
        overlap = set(xs) & set(aux)
        if overlap:
            raise SDCError(f"states {sorted(map(str, overlap))} are both controlled and auxiliary")
        # a plant state in neither list is auxiliary (docs/controllers.md), and said to be
        # (unseen46 F2: the run recorded `auxiliary_states: []` beside one)
        aux += tuple(s for s in model.states if s not in xs and s not in aux)
    if not xs:
        raise SDCError("no controlled states left")
    return xs, aux


def _controlled_f(model: Model, xs, aux) -> sp.Matrix:
    full = model.rhs()
    f = sp.Matrix([full[model.states.index(s)] for s in xs])
    if f.has(TIME):
        raise SDCError(f"model {model.name!r}: the dynamics depend explicitly on time t; an SDC "
                       "form A(x)x + B(x)u needs autonomous dynamics")
    return f


def _check_origin_and_affine(model: Model, f: sp.Matrix, xs, aux, us) -> None:
    zero = {s: 0 for s in xs}
    zero.update({u: 0 for u in us})
    f00 = sp.simplify(f.xreplace(zero))
    bad = [(str(xs[i]), f00[i]) for i in range(len(xs)) if f00[i] != 0]
    if bad:
        where = ", ".join(f"d{n}/dt = {sp.sstr(v)}" for n, v in bad)
        left_out = sorted(str(s) for s in set().union(*(v.free_symbols for _, v in bad))
                          if s in model.states and s not in xs)
        if left_out:
            # the plant may well be at an equilibrium: the file left a state out of the
            # controlled ones, and the shift advice below pointed the wrong way (unseen37 F6)
            raise SDCError(
                f"model {model.name!r}: at x = 0, u = 0 {where}, which depends on "
                f"{', '.join(left_out)}: not among the controlled states {[str(x) for x in xs]}. "
                f"A state left out of `states:` is auxiliary (carried by the plant, not regulated), "
                f"and an SDC form needs f(0, 0) = 0 whatever its value; list "
                f"{', '.join(left_out)} in the controller's `states:` (with its weight in Q) to regulate it.")
        extra = (f" (for some value of the auxiliary states {[str(a) for a in aux]})"
                 if aux else "")
        raise SDCError(
            f"model {model.name!r}: f(0, 0) != 0{extra}: at x = 0, u = 0 {where}. An SDC form "
            "f(x,u) = A(x)x + B(x)u gives f(0,0) = A(0)*0 + B(0)*0 = 0 for every A and B, so "
            "none can exist. Shift the state and control to an equilibrium first "
            "(x -> x - x_e, u -> u - u_e with f(x_e, u_e) = 0).")
    for i, fi in enumerate(f):
        for u in us:
            d2 = sp.simplify(sp.diff(fi, u, 2))
            if d2 != 0:
                raise SDCError(f"model {model.name!r}: d{xs[i]}/dt is not affine in control "
                               f"{u} (d2f/d{u}2 = {sp.sstr(d2)}); the form B(x)u needs "
                               "control-affine dynamics")
        for u in us:
            for v in us:
                if sp.simplify(sp.diff(fi, u, v)) != 0:
                    raise SDCError(f"model {model.name!r}: d{xs[i]}/dt has a product of controls "
                                   f"{u}*{v}; the form B(x)u needs control-affine dynamics")


def _poly_factors(term: sp.Expr, xs) -> list[int]:
    """Indices of states that are explicit multiplicative factors (power >= 1) of term."""
    out = []
    _, factors = term.as_coeff_mul()
    for j, s in enumerate(xs):
        for fac in factors:
            base, ex = fac.as_base_exp()
            if base == s and ex.is_Integer and ex >= 1:
                out.append(j)
                break
    return out


def _safe_quotient(expr: sp.Expr, s: sp.Symbol) -> sp.Expr:
    """expr / s, finite at s = 0 (limit filled in when the singularity is removable)."""
    q = sp.cancel(expr / s) if expr.is_polynomial(s) else expr / s
    # sin(s)/s -> sinc(s)
    q = sp.simplify(q.rewrite(sp.sinc)) if q.has(sp.sin) else q
    try:
        at0 = q.xreplace({s: 0})
    except Exception:  # pragma: no cover
        at0 = sp.nan
    if at0.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
        lim = sp.limit(q, s, 0)
        if lim.has(sp.nan, sp.zoo, sp.oo, -sp.oo) or lim.has(sp.Limit):
            raise SDCError(f"cannot divide {sp.sstr(expr)} by {s}: the quotient is unbounded at "
                           f"{s} = 0 (the dynamics are not differentiable at the origin)")
        q = sp.Piecewise((lim, sp.Eq(s, 0)), (q, True))
    return q


def factorise(model: Model, auxiliary: Iterable[str | sp.Symbol] = (),
              states: Iterable[str | sp.Symbol] | None = None, split: str = "even",
              verify: bool = True) -> SDC:
    """Automatic SDC factorisation of ``model`` (see the module docstring for the rule)."""
    if split not in SPLITS:
        raise SDCError(f"unknown split {split!r}; choose one of {SPLITS}")
    xs, aux = _split_states(model, auxiliary, states)
    us = tuple(model.controls)
    f = _controlled_f(model, xs, aux)
    _check_origin_and_affine(model, f, xs, aux, us)
    n, m = len(xs), len(us)
    zero_u = {u: 0 for u in us}
    B = sp.zeros(n, m)
    A = sp.zeros(n, n)
    notes: list[str] = []
    for i in range(n):
        for k, u in enumerate(us):
            B[i, k] = sp.simplify(sp.diff(f[i], u))
        f0 = sp.expand(f[i].xreplace(zero_u))
        remainder = sp.Integer(0)
        for term in sp.Add.make_args(f0):
            cand = _poly_factors(term, xs)
            if not cand:
                remainder += term
                continue
            if split == "first":
                cand = cand[:1]
            elif split == "last":
                cand = cand[-1:]
            share = sp.Rational(1, len(cand))
            for j in cand:
                A[i, j] += share * sp.cancel(term / xs[j])
        if remainder != 0:
            # telescoping along the state order
            prev = remainder.xreplace({s: 0 for s in xs})
            if sp.simplify(prev) != 0:  # pragma: no cover - excluded by the origin check
                raise SDCError(f"row {xs[i]}: remainder does not vanish at the origin")
            for j, s in enumerate(xs):
                cur = remainder.xreplace({t: 0 for t in xs[j + 1:]})
                diff = sp.simplify(cur - prev)
                if diff != 0:
                    A[i, j] += _safe_quotient(diff, s)
                    notes.append(f"row {xs[i]}, column {s}: non-polynomial term divided by {s}")
                prev = cur
        for j in range(n):
            A[i, j] = sp.simplify(A[i, j]) if A[i, j].has(sp.Piecewise, sp.sinc) else sp.factor_terms(A[i, j])
    sdc = SDC(model, xs, aux, us, A, B, f, f"auto:{split}", notes)
    if verify:
        verify_exact(sdc)
    return sdc


def given(model: Model, A, B=None, auxiliary: Iterable[str | sp.Symbol] = (),
          states: Iterable[str | sp.Symbol] | None = None, verify: bool = True) -> SDC:
    """A user-given factorisation (``sdc: given``), checked for exactness.

    ``A`` is an n x n SymPy matrix (or nested lists of expressions); ``B`` an n x m one,
    or None for B = df/du.
    """
    xs, aux = _split_states(model, auxiliary, states)
    us = tuple(model.controls)
    f = _controlled_f(model, xs, aux)
    _check_origin_and_affine(model, f, xs, aux, us)
    A = sp.Matrix(A)
    if A.shape != (len(xs), len(xs)):
        raise SDCError(f"given A is {A.shape[0]}x{A.shape[1]}, expected {len(xs)}x{len(xs)} "
                       f"(controlled states {[str(s) for s in xs]})")
    if B is None:
        B = sp.Matrix([[sp.diff(fi, u) for u in us] for fi in f])
    B = sp.Matrix(B)
    if B.shape != (len(xs), len(us)):
        raise SDCError(f"given B is {B.shape[0]}x{B.shape[1]}, expected {len(xs)}x{len(us)}")
    sdc = SDC(model, xs, aux, us, A, B, f, "given")
    if verify:
        verify_exact(sdc)
    return sdc


def blend(a: SDC, b: SDC, alpha) -> SDC:
    """The convex combination alpha*a + (1-alpha)*b of two factorisations (also exact)."""
    if a.states != b.states or a.controls != b.controls:
        raise SDCError("blend needs factorisations of the same states and controls")
    alpha = sp.sympify(alpha)
    return SDC(a.model, a.states, a.auxiliary, a.controls,
               alpha * a.A + (1 - alpha) * b.A, alpha * a.B + (1 - alpha) * b.B, a.f,
               f"blend({a.method},{b.method},{alpha})")


def verify_exact(sdc: SDC) -> None:
    """Raise SDCError unless A(x)x + B(x)u - f(x,u) simplifies to zero."""
    res = sdc.residual()
    bad = []
    for i, r in enumerate(res):
        r = r.rewrite(sp.sin) if r.has(sp.sinc) else r
        r = sp.piecewise_fold(r)
        if isinstance(r, sp.Piecewise):
            # check the generic branch (the point branches x_j = 0 hold the limits, which
            # are continuous extensions of it)
            r = next(a.expr for a in r.args if not isinstance(a.cond, sp.Eq))
        if sp.simplify(sp.expand(r)) != 0 and sp.simplify(sp.expand_trig(r)) != 0:
            bad.append((str(sdc.states[i]), r))
    if bad:
        rows = "; ".join(f"{n}: {sp.sstr(sp.simplify(r))}" for n, r in bad[:3])
        raise SDCError(f"SDC factorisation ({sdc.method}) is not exact: A(x)x + B(x)u - f(x,u) "
                       f"!= 0 in rows {rows}")


# ---------------------------------------------------------------------------------
# numbers
# ---------------------------------------------------------------------------------

@dataclass
class NumericSDC:
    """Fast NumPy callables A(z), B(z) of the full plant state vector z (model order)."""

    sdc: SDC
    A: Callable[[np.ndarray], np.ndarray]
    B: Callable[[np.ndarray], np.ndarray]
    f: Callable[[np.ndarray, np.ndarray], np.ndarray]   # full plant rhs(z, u)
    index: list[int]                                     # controlled states in z
    B_constant: bool


def _values(model: Model, parameters: Mapping | None):
    vals = dict(model.default_parameters())
    for k, v in (parameters or {}).items():
        key = k if isinstance(k, sp.Symbol) else model.symbol(str(k))
        vals[key] = v
    missing = [str(p) for p in model.parameters if p not in vals]
    return vals, missing


def lambdify_sdc(sdc: SDC, parameters: Mapping | None = None,
                 plant_parameters: Mapping | None = None) -> NumericSDC:
    """NumPy callables for A, B (controller side) and the plant rhs.

    ``parameters`` (names or symbols -> numbers) override the model defaults for A and B;
    ``plant_parameters`` override them for the plant right-hand side only (a perturbed
    plant under a nominal controller).
    """
    model = sdc.model
    vals, missing = _values(model, parameters)
    pvals, pmissing = _values(model, {**{str(k): v for k, v in vals.items()},
                                      **{str(k): v for k, v in (plant_parameters or {}).items()}})
    if missing or pmissing:
        raise SDCError(f"model {model.name!r}: parameters without values: {sorted(set(missing + pmissing))}")
    z = sp.Matrix(model.states)
    u = sp.Matrix(model.controls)
    sub = {k: sp.Float(v) for k, v in vals.items()}
    A = sdc.A.xreplace(sub)
    B = sdc.B.xreplace(sub)
    fz = model.rhs({k: v for k, v in pvals.items()})
    Af = sp.lambdify([list(z)], A, modules="numpy", cse=True)
    Bf = sp.lambdify([list(z)], B, modules="numpy", cse=True)
    ff = sp.lambdify([list(z), list(u)], fz, modules="numpy", cse=True)
    n, m = sdc.n, sdc.m

    # a Piecewise entry (sin(th)/th, (cos(th) - 1)/th with its limit at 0) becomes NumPy's
    # select, which evaluates every branch: 0/0 in the branch not taken is not the user's
    # business (unseen19 c24 printed a RuntimeWarning on stderr)
    def Afun(zv):
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.asarray(Af(zv), dtype=float).reshape(n, n)

    def Bfun(zv):
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.asarray(Bf(zv), dtype=float).reshape(n, m)

    def ffun(zv, uv):
        return np.asarray(ff(zv, uv), dtype=float).reshape(-1)

    return NumericSDC(sdc, Afun, Bfun, ffun, sdc.index(), B_constant=not B.free_symbols)


# ---------------------------------------------------------------------------------
# pointwise checks
# ---------------------------------------------------------------------------------

@dataclass
class PointCheck:
    point: np.ndarray
    rank: int
    n: int
    stabilisable: bool
    unstabilisable_modes: list[complex]

    @property
    def controllable(self) -> bool:
        return self.rank == self.n


def controllability_rank(A: np.ndarray, B: np.ndarray, rtol: float = 1e-9) -> int:
    n = A.shape[0]
    blocks = [B]
    for _ in range(n - 1):
        blocks.append(A @ blocks[-1])
    C = np.hstack(blocks)
    s = np.linalg.svd(C, compute_uv=False)
    return int(np.sum(s > rtol * max(s[0], 1e-300))) if s.size else 0


def pbh_unstabilisable(A: np.ndarray, B: np.ndarray, rtol: float = 1e-9) -> list[complex]:
    """Eigenvalues with Re >= 0 for which rank [A - lam I, B] < n (PBH test)."""
    n = A.shape[0]
    bad = []
    for lam in np.linalg.eigvals(A):
        if lam.real < -1e-12:
            continue
        M = np.hstack([A - lam * np.eye(n), B])
        s = np.linalg.svd(M, compute_uv=False)
        if np.sum(s > rtol * max(s[0], 1e-300)) < n:
            bad.append(complex(lam))
    return bad


def check_pointwise(num: NumericSDC, points: Sequence[np.ndarray]) -> list[PointCheck]:
    """Controllability rank and stabilisability of (A(z), B(z)) at full plant states z."""
    out = []
    names = [str(s) for s in num.sdc.model.states]
    for z in points:
        z = np.asarray(z, float)
        with np.errstate(all="ignore"):
            A, B = np.asarray(num.A(z), float), np.asarray(num.B(z), float)
        for label, M in (("A", A), ("B", B)):
            bad = np.argwhere(~np.isfinite(M))
            if bad.size:
                # a given entry such as g*sin(th)/th is 0/0 at th = 0: said, not LAPACK's "SVD did
                # not converge" (unseen35 F10)
                i, j = (int(k) + 1 for k in bad[0])
                at = ", ".join(f"{n}={v:.4g}" for n, v in zip(names, z))
                raise SDCError(f"{label}[{i},{j}] is not finite ({M[i - 1, j - 1]}) at {at}: an entry such as "
                               "sin(th)/th is 0/0 there; write it so that it has a value there, or use `sdc: auto`")
        out.append(PointCheck(z, controllability_rank(A, B), A.shape[0],
                              not pbh_unstabilisable(A, B), pbh_unstabilisable(A, B)))
    return out


def require_stabilisable(num: NumericSDC, points: Sequence[np.ndarray], what: str = "") -> None:
    """Raise SDCError naming the first point where (A, B) is not stabilisable."""
    names = [str(s) for s in num.sdc.model.states]
    for chk in check_pointwise(num, points):
        if not chk.stabilisable:
            at = ", ".join(f"{n}={v:.4g}" for n, v in zip(names, chk.point))
            modes = ", ".join(f"{m.real:+.3g}{m.imag:+.3g}j" for m in chk.unstabilisable_modes[:6])
            raise SDCError(
                f"{what + ': ' if what else ''}(A(x), B(x)) is not stabilisable at {at}: "
                f"controllability rank {chk.rank} of {chk.n}; modes with Re >= 0 that the "
                f"controls cannot reach: {modes}. No stabilising Riccati solution exists there "
                "(too few independent actuators or a different SDC factorisation is needed).")
