"""Initial guesses of one phase, as functions of normalised time s in [0, 1].

Sources, in order of precedence: a previous run folder (warm start, interpolated onto
the new mesh), the file's ``guess:`` values (constant, ``[start, end]`` or a table),
boundary values fixed by equalities (linear between them), the middle of finite bounds,
and zero. ``random: true`` draws controls uniformly inside their bounds from ``seed``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..symbolic.problem import Phase, Problem


@dataclass
class PhaseGuess:
    state_names: list[str]
    control_names: list[str]
    s_table: dict[str, np.ndarray]       # name -> normalised times of the table
    v_table: dict[str, np.ndarray]       # name -> values
    t0: float
    tf: float
    random_controls: np.random.Generator | None = None
    control_bounds: dict[str, tuple[float, float]] | None = None

    def _at(self, names: list[str], s: np.ndarray) -> np.ndarray:
        out = np.zeros((len(s), len(names)))
        for j, n in enumerate(names):
            out[:, j] = np.interp(s, self.s_table[n], self.v_table[n])
        return out

    def states_at(self, s: np.ndarray) -> np.ndarray:
        return self._at(self.state_names, np.asarray(s))

    def controls_at(self, s: np.ndarray) -> np.ndarray:
        u = self._at(self.control_names, np.asarray(s))
        if self.random_controls is not None:
            for j, n in enumerate(self.control_names):
                lo, hi = self.control_bounds.get(n, (-1.0, 1.0))
                lo = lo if math.isfinite(lo) else u[:, j].min() - 1.0
                hi = hi if math.isfinite(hi) else u[:, j].max() + 1.0
                u[:, j] = self.random_controls.uniform(lo, hi, size=len(s))
        return u


def _fixed_boundary(problem: Problem, ph: Phase) -> dict[tuple[str, str], float]:
    out = {}
    for c in problem.boundary:
        if isinstance(c.expr, sp.Symbol) and c.expr in problem.boundary_values and c.is_equality:
            bv = problem.boundary_values[c.expr]
            if bv.phase == ph.name:
                out[(bv.var.name, bv.which)] = c.lower
    return out


def _mid(lo: float, hi: float, default: float = 0.0) -> float:
    if math.isfinite(lo) and math.isfinite(hi):
        return 0.5 * (lo + hi)
    if math.isfinite(lo):
        return max(lo, default) if lo <= default else lo
    if math.isfinite(hi):
        return min(hi, default)
    return default


def make_guess(problem: Problem, ph: Phase, previous=None, seed: int | None = None) -> PhaseGuess:
    """The guess of ``ph``; ``previous`` is a PhaseTrajectory of an earlier run (warm start)."""
    given = ph.guess.get("values", {})
    fixed = _fixed_boundary(problem, ph)
    t0_guess = ph.guess.get("t0")
    t0 = ph.t0 if ph.t0 is not None else (float(t0_guess) if t0_guess is not None else _mid(*ph.t0_bounds))
    tf_guess = ph.guess.get("tf")
    if ph.tf is not None:
        tf = ph.tf
    elif tf_guess is not None:
        tf = float(tf_guess)
    else:
        lo, hi = ph.tf_bounds
        tf = _mid(lo, hi, t0 + 1.0) if math.isfinite(hi) else (lo * 2 if math.isfinite(lo) and lo > t0 else t0 + 1.0)
    s_table, v_table = {}, {}
    for var in ph.states + ph.controls:
        n = var.name
        lo, hi = ph.bounds_of(var)
        if n in given:
            s, v = _table(given[n], t0, tf)
        elif var in ph.states and ((n, "t0") in fixed or (n, "tf") in fixed):
            a = fixed.get((n, "t0"), fixed.get((n, "tf")))
            z = fixed.get((n, "tf"), a)
            s, v = np.array([0.0, 1.0]), np.array([a, z])
        else:
            s, v = np.array([0.0, 1.0]), np.full(2, _mid(lo, hi))
        s_table[n], v_table[n] = s, np.clip(v, lo, hi)
    if previous is not None:
        tp = np.asarray(previous.time, float)
        span = tp[-1] - tp[0] if tp[-1] > tp[0] else 1.0
        sp_ = (tp - tp[0]) / span
        bounds = {var.name: ph.bounds_of(var) for var in ph.states + ph.controls}
        for n, arr in {**previous.states, **previous.controls}.items():
            if n in s_table:
                ok = np.isfinite(arr)
                # into the bounds, as the file's guess: a solution's values 1e-8 outside them
                # (Ipopt's bound relaxation) made Pyomo warn once per variable
                s_table[n], v_table[n] = sp_[ok], np.clip(np.asarray(arr)[ok], *bounds[n])
        t0, tf = (float(tp[0]) if ph.t0 is None else t0), (float(tp[-1]) if ph.tf is None else tf)
    rng = None
    random = ph.guess.get("random") or seed is not None
    if random and previous is None:
        rng = np.random.default_rng(seed if seed is not None else ph.guess.get("seed") or 0)
    return PhaseGuess([s.name for s in ph.states], [c.name for c in ph.controls], s_table, v_table,
                      float(t0), float(tf), rng, {c.name: ph.bounds_of(c) for c in ph.controls})


def _table(value, t0: float, tf: float) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(value, (int, float)):
        return np.array([0.0, 1.0]), np.full(2, float(value))
    if isinstance(value, list):
        v = np.asarray(value, float)
        return np.linspace(0.0, 1.0, len(v)), v
    t = np.asarray(value["t"], float)
    v = np.asarray(value["values"], float)
    return (t - t0) / (tf - t0 if tf != t0 else 1.0), v
