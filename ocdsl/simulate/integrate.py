"""Python front end of the compiled DOP853 kernel: controls, single runs, batches."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .compile import CompiledModel

KINDS = {"constant": 0, "fourier": 1, "polynomial": 2, "table": 3}


@dataclass(frozen=True)
class ControlLayout:
    """How each control is parametrised; coefficients of all controls form one vector.

    kinds[j] in ``KINDS``; orders[j]: Fourier order N (coefficients a0, a1..aN, b1..bN:
    2N+1 numbers), polynomial degree (N+1 numbers in tau = t/T), table length n (times
    then values: 2n numbers), constant: 1 number.
    """

    kinds: tuple[str, ...]
    orders: tuple[int, ...]

    @staticmethod
    def size_of(kind: str, order: int) -> int:
        return {"constant": 1, "fourier": 2 * order + 1, "polynomial": order + 1,
                "table": 2 * order}[kind]

    @property
    def sizes(self) -> list[int]:
        return [self.size_of(k, o) for k, o in zip(self.kinds, self.orders)]

    @property
    def n_coeffs(self) -> int:
        return int(sum(self.sizes))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ck = np.array([KINDS[k] for k in self.kinds], np.int64)
        cp = np.concatenate([[0], np.cumsum(self.sizes)[:-1]]).astype(np.int64) if self.kinds else np.zeros(0, np.int64)
        co = np.array(self.orders, np.int64)
        return ck, cp, co

    @classmethod
    def constant(cls, n_controls: int) -> "ControlLayout":
        return cls(("constant",) * n_controls, (0,) * n_controls)

    @classmethod
    def table(cls, n_controls: int, n_points: int) -> "ControlLayout":
        return cls(("table",) * n_controls, (n_points,) * n_controls)


def table_coefficients(times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Coefficient vector of a piecewise-linear control table (values: (n, n_controls))."""
    values = np.asarray(values, float).reshape(len(times), -1)
    return np.concatenate([np.concatenate([times, values[:, j]]) for j in range(values.shape[1])])


def evaluate_controls(layout: ControlLayout, coeffs: np.ndarray, t: np.ndarray, T: float) -> np.ndarray:
    """Controls at times t (NumPy, for outputs and tests): shape (len(t), n_controls)."""
    t = np.atleast_1d(np.asarray(t, float))
    out = np.empty((len(t), len(layout.kinds)))
    ptr = 0
    for j, (kind, n) in enumerate(zip(layout.kinds, layout.orders)):
        c = coeffs[ptr:ptr + layout.size_of(kind, n)]
        ptr += len(c)
        if kind == "constant":
            out[:, j] = c[0]
        elif kind == "fourier":
            k = np.arange(1, n + 1)
            w = np.pi * np.outer(t, k) / T
            out[:, j] = 0.5 * c[0] + np.cos(w) @ c[1:n + 1] + np.sin(w) @ c[n + 1:]
        elif kind == "polynomial":
            out[:, j] = np.polyval(c[::-1], t / T)
        else:
            out[:, j] = np.interp(t, c[:n], c[n:])
    return out


@dataclass
class Trajectory:
    status: int
    s: np.ndarray            # independent variable at the recorded points
    y: np.ndarray            # states, (len(s), n)
    state_names: list[str]
    n_steps: int
    n_fev: int
    events: list[tuple[int, float, np.ndarray]] = field(default_factory=list)  # (index, s, y)
    clock: int = -1

    @property
    def t(self) -> np.ndarray:
        """Physical time (the clock state for Sundman models)."""
        return self.y[:, self.clock] if self.clock >= 0 else self.s

    @property
    def final(self) -> np.ndarray:
        return self.y[-1]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.y[:, self.state_names.index(name)]


@dataclass(frozen=True)
class Event:
    """Crossing of ``state == value``; direction +1 upward, -1 downward, 0 both."""

    state: str
    value: float = 0.0
    direction: int = 0
    terminal: bool = False


def _event_arrays(cm: CompiledModel, events: Sequence[Event]):
    return (np.array([cm.state_names.index(e.state) for e in events], np.int64),
            np.array([e.value for e in events], float),
            np.array([e.direction for e in events], np.int64),
            np.array([int(e.terminal) for e in events], np.int64))


def _atol(cm: CompiledModel, atol) -> np.ndarray:
    a = np.broadcast_to(np.asarray(atol, float), (cm.n,)).copy()
    return a


def _kernel_args(args: tuple) -> tuple:
    """Every array argument of a kernel C-contiguous and writable: Numba compiles a kernel
    once per distinct signature, and a read-only array (a broadcast view, a cached table) is
    another type. With some arguments read-only on some calls, the integrator was compiled
    three times and the parallel batch twice: 29 s of a cold parametric run's 38 (unseen35 F11)."""
    return tuple(np.require(a, requirements=("C", "W")) if isinstance(a, np.ndarray) else a for a in args)


def simulate(cm: CompiledModel, y0, T: float, p=None, layout: ControlLayout | None = None,
             coeffs=None, rtol: float = 1e-10, atol=1e-12, events: Sequence[Event] = (),
             record: bool = True, n_dense: int = 0, max_steps: int = 1_000_000,
             s_max: float | None = None, first_step: float = 0.0) -> Trajectory:
    """Integrate one run from t = 0 to t = T.

    For models with a clock state (Sundman form) the independent variable runs from 0
    until the clock reaches T (``s_max`` bounds it, default 1e3*T); otherwise it runs
    to T. ``layout``/``coeffs`` give the controls as functions of physical time on
    [0, T]. Returns a :class:`Trajectory` with every accepted step (+ ``n_dense`` dense
    points per step) and the located events.
    """
    layout = layout or ControlLayout.constant(len(cm.control_names))
    ck, cp, co = layout.arrays()
    cd = np.zeros(max(layout.n_coeffs, 1)) if coeffs is None else np.asarray(coeffs, float)
    p = cm.default_p if p is None else np.asarray(p, float)
    y0 = np.asarray(y0, float).copy()
    if cm.clock >= 0:
        s_end, t_stop = (s_max if s_max is not None else 1e3 * abs(T) + 1.0), float(T)
    else:
        s_end, t_stop = float(T), math.inf
    ev_idx, ev_val, ev_dir, ev_term = _event_arrays(cm, events)
    st, s, y, ns, nf, traj, evs = cm.module.integrate(*_kernel_args((
        y0, 0.0, s_end, p, ck, cp, co, cd, float(T), cm.clock, t_stop, float(rtol),
        _atol(cm, atol), float(first_step), int(max_steps), ev_idx, ev_val, ev_dir, ev_term,
        int(n_dense), bool(record))))
    if not record:
        traj = np.concatenate([[s], y])[None, :]
    ev_list = [(int(r[0]), float(r[1]), r[2:].copy()) for r in evs]
    return Trajectory(int(st), traj[:, 0].copy(), traj[:, 1:].copy(), cm.state_names, int(ns),
                      int(nf), ev_list, cm.clock)


def final_states(cm: CompiledModel, Y0: np.ndarray, T: np.ndarray, P: np.ndarray,
                 layout: ControlLayout, CD: np.ndarray, rtol: float = 1e-9, atol=1e-11,
                 max_steps: int = 200_000, parallel: bool = False,
                 s_max_factor: float = 1e3, events: Sequence[Event] = ()
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched runs: row b integrates Y0[b] with parameters P[b] and control coefficients
    CD[b] over [0, T[b]]. Returns (final states (B, n), status (B,), steps (B,)); status
    as :func:`simulate` (0/1 reached T, 2 stopped by a terminal event, < 0 failed).
    ``events`` are typically terminal guards (impact, escape) that end hopeless runs early.

    ``parallel`` splits the rows over threads, one per core (the serial kernel releases the
    GIL). It replaced a ``parallel=True`` Numba kernel whose compilation cost 8-22 s of every
    new model's first run (unseen35 F11: 38 s for a double integrator's first PSO run).
    """
    B = len(T)
    Y0 = np.ascontiguousarray(np.broadcast_to(np.asarray(Y0, float), (B, cm.n)))
    P = np.ascontiguousarray(np.broadcast_to(np.asarray(P, float), (B, len(cm.default_p))))
    CD = np.ascontiguousarray(np.asarray(CD, float).reshape(B, -1))
    if CD.shape[1] == 0:
        CD = np.zeros((B, 1))
    T = np.ascontiguousarray(np.asarray(T, float))
    ck, cp, co = layout.arrays()
    if cm.clock >= 0:
        s_end = s_max_factor * np.abs(T) + 1.0
        t_stop = T.copy()
    else:
        s_end = T.copy()
        t_stop = np.full(B, np.inf)
    Yf = np.empty((B, cm.n))
    status = np.empty(B, np.int64)
    steps = np.empty(B, np.int64)
    # the runs' own arrays (one row per run) and those they share, each C-contiguous and writable
    Y0, s_end, P, CD, T, t_stop = _kernel_args((Y0, s_end, P, CD, T, t_stop))
    ck, cp, co, atol_ = _kernel_args((ck, cp, co, _atol(cm, atol)))
    ev = _kernel_args(_event_arrays(cm, events))

    def run(a: int, b: int) -> None:
        # rows a:b of every per-run array: C-contiguous views the kernel writes through
        cm.module.final_batch(Y0[a:b], s_end[a:b], P[a:b], ck, cp, co, CD[a:b], T[a:b], cm.clock, t_stop[a:b],
                              float(rtol), atol_, int(max_steps), *ev, Yf[a:b], status[a:b], steps[a:b], 0, False)

    chunks = [c for c in np.array_split(np.arange(B), max(1, min(B, _cores())) if parallel else 1) if len(c)]
    if len(chunks) == 1:
        run(chunks[0][0], chunks[0][-1] + 1)
    elif chunks:
        list(_pool().map(lambda c: run(c[0], c[-1] + 1), chunks))
    return Yf, status, steps


_POOL = None


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _pool():
    global _POOL
    if _POOL is None:
        from concurrent.futures import ThreadPoolExecutor

        _POOL = ThreadPoolExecutor(max_workers=_cores(), thread_name_prefix="ocdsl-batch")
    return _POOL


def scipy_final_state(cm: CompiledModel, y0, T: float, p, layout: ControlLayout, coeffs,
                      rtol: float = 1e-9, atol=1e-11, method: str = "DOP853"):
    """Reference: SciPy ``solve_ivp`` (DOP853 unless ``method`` names another of its
    integrators, e.g. RK45, the Dormand-Prince 5(4) pair of MATLAB's ode45) on the same
    compiled RHS and controls."""
    from scipy.integrate import solve_ivp

    ck, cp, co = layout.arrays()
    cd = np.asarray(coeffs, float)
    u = np.empty(max(len(ck), 1))
    out = np.empty(cm.n)
    mod = cm.module
    p = np.asarray(p, float)

    def fun(s, y):
        res = np.empty(cm.n)
        mod.deriv(s, y, p, ck, cp, co, cd, T, cm.clock, u, res)
        return res

    if cm.clock >= 0:
        ev = lambda s, y: y[cm.clock] - T  # noqa: E731
        ev.terminal = True
        sol = solve_ivp(fun, (0.0, 1e3 * T + 1), np.asarray(y0, float), method=method,
                        rtol=rtol, atol=atol, events=ev)
        out[:] = sol.y_events[0][0] if len(sol.t_events[0]) else sol.y[:, -1]
    else:
        sol = solve_ivp(fun, (0.0, T), np.asarray(y0, float), method=method, rtol=rtol, atol=atol)
        out[:] = sol.y[:, -1]
    return out, sol
