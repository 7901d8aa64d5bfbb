"""DOP853 (Dormand-Prince 8(5,3), Hairer's ``dop853``) with dense output, in NumPy alone.

Why not ``scipy.integrate.solve_ivp``: importing ``scipy.integrate`` pulls in
scipy.optimize, linalg, special and sparse, about 0.35-0.8 s of CPU, more than the whole
verification of a small problem. The stepping here is the one ``solve_ivp(method="DOP853")``
does (same initial step, error norm, step-size control and 7th-degree interpolant), so the
two agree to round-off (``tests/test_dop853.py`` checks that against SciPy on smooth and
stiff-ish systems). The coefficient table is SciPy's own file
(``scipy/integrate/_ivp/dop853_coefficients.py``, which needs only NumPy), read from where
SciPy is installed without importing the ``scipy.integrate`` package.
"""
from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass

import numpy as np

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ERROR_EXPONENT = -1.0 / 8.0      # error estimator of order 7
N_STAGES = 12


def _coefficients():
    name = "ocdsl.verify._dop853_coefficients"
    mod = sys.modules.get(name)
    if mod is not None:
        return mod
    spec = importlib.util.find_spec("scipy")    # locates SciPy; does not import it
    path = None
    if spec is not None and spec.submodule_search_locations:
        from pathlib import Path

        cand = Path(list(spec.submodule_search_locations)[0]) / "integrate" / "_ivp" / "dop853_coefficients.py"
        path = cand if cand.is_file() else None
    if path is None:                              # another layout: the ordinary import
        from scipy.integrate._ivp import dop853_coefficients as mod
        return mod
    fspec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(fspec)
    fspec.loader.exec_module(mod)
    sys.modules[name] = mod
    return mod


class _Table:
    def __init__(self):
        c = _coefficients()
        self.A = np.asarray(c.A, float)
        self.B = np.asarray(c.B, float)
        self.C = np.asarray(c.C, float)
        self.D = np.asarray(c.D, float)
        self.E3 = np.asarray(c.E3, float)
        self.E5 = np.asarray(c.E5, float)
        self.n_extended = int(c.N_STAGES_EXTENDED)
        self.power = int(c.INTERPOLATOR_POWER)
        # per stage its row of A (contiguous) and its node as a float: the stepping loop
        # indexes them 12 times a step
        self.rows = [np.ascontiguousarray(self.A[s, :s]) for s in range(self.n_extended)]
        self.nodes = [float(x) for x in self.C]


_TABLE: list[_Table] = []


def _table() -> _Table:
    if not _TABLE:
        _TABLE.append(_Table())
    return _TABLE[0]


@dataclass
class Solution:
    """What the callers read of SciPy's OdeResult with ``t_eval``: the requested times reached
    ``t`` and the solution there ``y`` (n, len(t)), ``success``, ``message``; besides, where
    the integration stopped ``t_end``, the accepted steps ``steps`` and ``nfev``."""

    t: np.ndarray
    y: np.ndarray
    success: bool
    message: str
    t_end: float
    steps: int
    nfev: int


def _rms(x) -> float:
    return float(np.linalg.norm(x) / np.sqrt(x.size)) if x.size else 0.0


def _initial_step(fun, t0, y0, f0, t_bound, rtol, atol) -> float:
    """Hairer, Norsett, Wanner, Solving ODEs I, sec. II.4 (as SciPy's ``select_initial_step``)."""
    if y0.size == 0:
        return np.inf
    length = abs(t_bound - t0)
    if length == 0.0:
        return 0.0
    direction = np.sign(t_bound - t0)
    scale = atol + np.abs(y0) * rtol
    d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, length)
    f1 = fun(t0 + h0 * direction, y0 + h0 * direction * f0)
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100 * h0, h1, length)


def solve(fun, t_span, y0, t_eval, rtol: float, atol, check=None, max_first_step: float = np.inf) -> Solution:
    """Integrate ``y' = fun(t, y)`` over ``t_span`` with DOP853 at ``rtol`` and ``atol``
    (scalar or per component); the solution at the sorted times ``t_eval`` (inside the span)
    from each step's dense output. A failed run (the step size too small, e.g. where the
    right-hand side is not finite) returns ``success=False`` with the values reached so far.
    ``check(t)``, if given, is called before every step (a time budget may raise there).
    ``max_first_step`` caps the initial step (Hairer's estimate): where the first step came
    out near the whole span, the error estimate accepted it at 60 times rtol (a Goddard piece
    starting where the control leaves its bound; SciPy's DOP853 does the same)."""
    T = _table()
    B, rows, nodes = T.B, T.rows, T.nodes
    t0, t_bound = float(t_span[0]), float(t_span[1])
    direction = 1.0 if t_bound >= t0 else -1.0
    rtol = max(float(rtol), 100 * np.finfo(float).eps)
    y = np.array(y0, dtype=float)
    n = y.size
    atol = np.asarray(atol, float)
    t_eval = np.asarray(t_eval, float)
    out = np.full((n, len(t_eval)), np.nan)
    nfev = [0]

    def f(tt, yy):
        nfev[0] += 1
        return np.asarray(fun(tt, yy), dtype=float)

    K = np.empty((T.n_extended, n))
    fy = f(t0, y)
    h_abs = min(_initial_step(f, t0, y, fy, t_bound, rtol, atol), max_first_step)
    t = t0
    ts = [t0]
    i_eval = 0
    if direction > 0:
        seek = lambda tt: np.searchsorted(t_eval, tt, side="right")   # noqa: E731
    else:
        seek = lambda tt: np.searchsorted(-t_eval, -tt, side="right")   # noqa: E731

    def result(ok: bool, message: str) -> Solution:
        return Solution(t_eval[:i_eval], out[:, :i_eval], ok, message, t, len(ts) - 1, nfev[0])

    if t0 == t_bound:
        i_eval = int(np.sum(t_eval == t0))
        out[:, :i_eval] = y[:, None]
    while direction * (t - t_bound) < 0:
        min_step = 10 * abs(np.nextafter(t, direction * np.inf) - t)
        h_abs = max(h_abs, min_step)
        rejected = False
        while True:
            if h_abs < min_step:
                return result(False, "Required step size is less than spacing between numbers.")
            t_new = t + h_abs * direction
            if direction * (t_new - t_bound) > 0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            if check is not None:
                check(t)
            # the Runge-Kutta step: 12 stages, the 8th-order solution, f at its end
            K[0] = fy
            for s in range(1, N_STAGES):
                K[s] = f(t + nodes[s] * h, y + np.dot(rows[s], K[:s]) * h)
            y_new = y + h * np.dot(B, K[:N_STAGES])
            f_new = f(t_new, y_new)
            K[N_STAGES] = f_new
            scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
            Kh = K[:N_STAGES + 1]
            err5 = np.dot(T.E5, Kh) / scale
            err3 = np.dot(T.E3, Kh) / scale
            e5, e3 = float(np.dot(err5, err5)), float(np.dot(err3, err3))
            # a non-finite step gives err = nan: rejected and shrunk by MIN_FACTOR, as in SciPy
            err = 0.0 if e5 == 0 and e3 == 0 else abs(h) * e5 / np.sqrt((e5 + 0.01 * e3) * n)
            if err < 1:
                factor = MAX_FACTOR if err == 0 else min(MAX_FACTOR, SAFETY * err ** ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * err ** ERROR_EXPONENT)
            rejected = True
        j = seek(t_new)
        if j > i_eval:     # requested times in this step: the 7th-degree dense output
            for s in range(N_STAGES + 1, T.n_extended):
                K[s] = f(t + nodes[s] * h, y + np.dot(rows[s], K[:s]) * h)
            F = np.empty((T.power, n))
            dy = y_new - y
            F[0] = dy
            F[1] = h * K[0] - dy
            F[2] = 2 * dy - h * (f_new + K[0])
            F[3:] = h * (T.D @ K)
            x = ((t_eval[i_eval:j] - t) / h)[:, None]
            Y = np.zeros((len(x), n))
            for i, Fi in enumerate(F[::-1]):
                Y += Fi
                Y *= x if i % 2 == 0 else 1 - x
            out[:, i_eval:j] = (Y + y).T
            i_eval = j
        t, y, fy = t_new, y_new, f_new
        ts.append(t)
    return result(True, "The solver successfully reached the end of the integration interval.")


@dataclass
class Ensemble:
    """Many independent pieces integrated side by side: ``y`` (len(positions), P, w), the
    solution of each piece at the common ``positions`` of its own time s in [0, 1];
    ``success`` (False: some piece failed, ``message`` says which), ``steps`` accepted over
    all pieces, ``nfev`` vectorised right-hand side calls."""

    y: np.ndarray
    success: bool
    message: str
    steps: int
    nfev: int


def _rms_rows(x) -> np.ndarray:
    return np.sqrt(np.mean(x * x, axis=1)) if x.shape[1] else np.zeros(len(x))


def solve_ensemble(fun, y0, positions, rtol: float, atol, max_first_step: float = np.inf) -> Ensemble:
    """Integrate P independent systems ``dY_k/ds = fun(idx, s, Y)[k]`` over s in [0, 1], each
    with its own step size, exactly as :func:`solve` integrates one (same initial step, error
    norm per piece, step control and dense output), the right-hand side evaluated for all
    pieces still running in one call: ``fun(idx, s, Y)`` gets the pieces' indices (q,), their
    times (q,) and states (q, w), and returns (q, w). ``positions`` are sorted, in [0, 1].
    ``max_first_step`` caps every piece's initial step, as in :func:`solve`."""
    T = _table()
    A, B, C = T.A[:N_STAGES, :N_STAGES], T.B, T.C[:N_STAGES]
    y = np.array(y0, dtype=float)
    P, w = y.shape
    rtol = max(float(rtol), 100 * np.finfo(float).eps)
    atol = np.broadcast_to(np.asarray(atol, float), (w,))
    positions = np.asarray(positions, float)
    out = np.full((len(positions), P, w), np.nan)
    nfev = [0]

    def f(idx, ss, yy):
        nfev[0] += 1
        return np.asarray(fun(idx, ss, yy), dtype=float)

    every = np.arange(P)
    s = np.zeros(P)
    fy = f(every, s, y)
    # the initial step of each piece (as _initial_step, row by row, over a span of 1)
    sc = atol + np.abs(y) * rtol
    d0, d1 = _rms_rows(y / sc), _rms_rows(fy / sc)
    h0 = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / np.where(d1 > 0, d1, 1.0))
    h0 = np.minimum(h0, 1.0)
    f1 = f(every, h0, y + h0[:, None] * fy)
    d2 = _rms_rows((f1 - fy) / sc) / h0
    with np.errstate(divide="ignore"):
        h1 = np.where((d1 <= 1e-15) & (d2 <= 1e-15), np.maximum(1e-6, h0 * 1e-3),
                      (0.01 / np.maximum(d1, d2)) ** (1.0 / 8.0))
    h_abs = np.minimum(np.minimum(np.minimum(100 * h0, h1), 1.0), max_first_step)
    i_eval = np.full(P, int(np.searchsorted(positions, 0.0, side="right")))
    out[:i_eval[0]] = y[None]
    rejected = np.zeros(P, bool)       # the current step of the piece was rejected before
    steps = 0
    K = np.empty((T.n_extended, P, w))
    while True:
        idx = np.flatnonzero(s < 1.0)
        if len(idx) == 0:
            break
        si, yi = s[idx], y[idx]
        min_step = 10 * np.abs(np.nextafter(si, np.inf) - si)
        fresh = ~rejected[idx]
        h = np.where(fresh, np.maximum(h_abs[idx], min_step), h_abs[idx])
        if np.any(h < min_step):
            bad = int(idx[np.argmax(h < min_step)])
            return Ensemble(out, False, f"piece {bad}: required step size is less than spacing "
                            "between numbers.", steps, nfev[0])
        s_new = np.minimum(si + h, 1.0)
        h = s_new - si
        Ki = K[:, :len(idx)]
        Ki[0] = fy[idx]
        for st in range(1, N_STAGES):
            Ki[st] = f(idx, si + C[st] * h, yi + np.einsum("kqw,k->qw", Ki[:st], A[st, :st]) * h[:, None])
        y_new = yi + h[:, None] * np.einsum("kqw,k->qw", Ki[:N_STAGES], B)
        f_new = f(idx, s_new, y_new)
        Ki[N_STAGES] = f_new
        scale = atol + np.maximum(np.abs(yi), np.abs(y_new)) * rtol
        err5 = np.einsum("kqw,k->qw", Ki[:N_STAGES + 1], T.E5) / scale
        err3 = np.einsum("kqw,k->qw", Ki[:N_STAGES + 1], T.E3) / scale
        e5, e3 = np.sum(err5 ** 2, axis=1), np.sum(err3 ** 2, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            err = np.where((e5 == 0) & (e3 == 0), 0.0, h * e5 / np.sqrt((e5 + 0.01 * e3) * w))
            grow = np.where(err == 0, MAX_FACTOR, np.minimum(MAX_FACTOR, SAFETY * err ** ERROR_EXPONENT))
            shrink = np.maximum(MIN_FACTOR, SAFETY * err ** ERROR_EXPONENT)
        ok = err < 1                     # a non-finite step: err = nan, rejected and shrunk
        shrink = np.where(np.isfinite(shrink), shrink, MIN_FACTOR)
        grow = np.where(rejected[idx], np.minimum(1.0, grow), grow)
        h_abs[idx] = np.where(ok, h * grow, h * shrink)
        rejected[idx] |= ~ok
        acc = np.flatnonzero(ok)
        if len(acc) == 0:
            continue
        steps += len(acc)
        j = np.searchsorted(positions, s_new[acc], side="right")
        need = acc[j > i_eval[idx[acc]]]
        if len(need):      # requested positions in these steps: the 7th-degree dense output
            q = idx[need]
            Kn = K[:, need]
            hn = h[need][:, None]
            for st in range(N_STAGES + 1, T.n_extended):
                a = T.A[st]
                Kn[st] = f(q, si[need] + T.C[st] * h[need],
                           yi[need] + np.einsum("kqw,k->qw", Kn[:st], a[:st]) * hn)
            dy = y_new[need] - yi[need]
            F = np.empty((T.power, len(need), w))
            F[0] = dy
            F[1] = hn * Kn[0] - dy
            F[2] = 2 * dy - hn * (f_new[need] + Kn[0])
            F[3:] = hn[None] * np.einsum("pk,kqw->pqw", T.D, Kn)
            first, last = i_eval[q], np.searchsorted(positions, s_new[need], side="right")
            counts = last - first
            rows = np.repeat(np.arange(len(need)), counts)
            at = np.concatenate([np.arange(a0, b0) for a0, b0 in zip(first, last)])
            x = ((positions[at] - si[need][rows]) / h[need][rows])[:, None]
            Fr = F[:, rows]
            Y = np.zeros((len(rows), w))
            for i, Fi in enumerate(Fr[::-1]):
                Y += Fi
                Y *= x if i % 2 == 0 else 1 - x
            out[at, q[rows]] = Y + yi[need][rows]
            i_eval[q] = last
        done = idx[acc]
        s[done], y[done], fy[done] = s_new[acc], y_new[acc], f_new[acc]
        rejected[done] = False
    return Ensemble(out, True, "every piece reached the end of its interval.", steps, nfev[0])
