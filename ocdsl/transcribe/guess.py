"""Initial guesses of one phase, as functions of normalised time s in [0, 1].

Sources, in order of precedence: a previous run folder (warm start, interpolated onto
the new mesh), the file's ``guess:`` values (constant, ``[start, end]`` or a table),
boundary values fixed by equalities (linear between them), the middle of finite bounds,
and zero. ``random: true`` draws controls uniformly inside their bounds from ``seed``.

``method: {starts: N}`` (:func:`start_guesses`): start 0 is that guess, exactly as a single
start; start i >= 1 is the guess with every state and control moved by a smooth seeded
random curve (clipped into the bounds, boundary values fixed by equalities kept) and the
free t0/tf drawn around their guess inside their bounds (:func:`perturb`).
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
    offsets: dict[str, "Offset"] | None = None          # a perturbed start's curves (perturb)
    bounds: dict[str, tuple[float, float]] | None = None  # what the offsets are clipped into

    def _at(self, names: list[str], s: np.ndarray) -> np.ndarray:
        out = np.zeros((len(s), len(names)))
        for j, n in enumerate(names):
            out[:, j] = np.interp(s, self.s_table[n], self.v_table[n])
            if self.offsets and n in self.offsets:
                out[:, j] = np.clip(out[:, j] + self.offsets[n](s), *self.bounds[n])
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


@dataclass
class Offset:
    """A smooth curve added to one variable's guess in normalised time s: ``sine[k-1]
    sin(k pi s)`` (k = 1..K, zero at both ends) plus ``start (1 - s) + end s``, the ends'
    own moves (zero where the boundary value is fixed). Exactly zero at a fixed end, so a
    boundary value fixed by an equality keeps its guess bit for bit."""
    sine: np.ndarray
    start: float
    end: float

    def __call__(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        k = np.arange(1, len(self.sine) + 1)
        inner = np.sin(np.pi * np.outer(s, k)) @ self.sine
        inner[(s <= 0.0) | (s >= 1.0)] = 0.0        # sin(k pi) is 1e-16, not 0
        return inner + self.start * (1.0 - s) + self.end * s


#: A perturbed start's curves: MODES sine modes whose coefficients are normal with standard
#: deviation AMPLITUDE * scale / k (the k-th mode's weight falls as 1/k, so the curves are
#: smooth and mostly one or two humps: a different shape of the trajectory, not noise that
#: the collocation smooths away), plus moves of the free ends of the same size. ``scale`` is
#: the variable's bound span when both bounds are finite, else the span of its guess, else
#: its magnitude, else 1. On the cart-pole swing-up (tests/test_multistart_explore.py) 0.25
#: leaves the straight-line basin (58.81) for the lower minimum 57.94 from several of 7
#: perturbed starts; much larger amplitudes mostly clip at the bounds.
MODES = 3
AMPLITUDE = 0.25
#: Free t0 and tf are drawn uniformly within TIME_WINDOW times the guessed duration of their
#: guess, inside their bounds: a time's bounds are often loose limits ([0, 1000]), from which
#: a uniform draw would land far from any sensible duration. The duration is kept at least
#: a tenth of the guessed one.
TIME_WINDOW = 0.3


def _scale(lo: float, hi: float, values: np.ndarray) -> float:
    if math.isfinite(lo) and math.isfinite(hi) and hi > lo:
        return hi - lo
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size and v.max() > v.min():
        return float(v.max() - v.min())
    if v.size and np.abs(v).max() > 0:
        return float(np.abs(v).max())
    return 1.0


def perturb(problem: Problem, ph: Phase, guess: PhaseGuess, rng: np.random.Generator) -> PhaseGuess:
    """``guess`` with every state and control (not controls drawn at random) moved by an :class:`Offset` drawn from ``rng`` and the phase's free
    t0/tf drawn around their guess (module constants above). Draws in a fixed order
    (states, controls, t0, tf), so a seed gives the same start every time."""
    fixed = _fixed_boundary(problem, ph)
    offsets, bounds = {}, {}
    names = list(guess.state_names) + ([] if guess.random_controls is not None else list(guess.control_names))
    variables = {v.name: v for v in ph.states + ph.controls}
    for n in names:
        lo, hi = ph.bounds_of(variables[n])
        amp = AMPLITUDE * _scale(lo, hi, guess.v_table[n])
        sine = amp * rng.standard_normal(MODES) / np.arange(1, MODES + 1)
        a, z = amp * rng.standard_normal(2)
        offsets[n] = Offset(sine, 0.0 if (n, "t0") in fixed else float(a), 0.0 if (n, "tf") in fixed else float(z))
        bounds[n] = (lo, hi)
    t0, tf = guess.t0, guess.tf
    span = tf - t0 if tf > t0 else 1.0
    draws = rng.uniform(-TIME_WINDOW, TIME_WINDOW, 2) * span
    if ph.t0 is None:
        t0 = float(np.clip(t0 + draws[0], *ph.t0_bounds))
    if ph.tf is None:
        tf = float(np.clip(tf + draws[1], *ph.tf_bounds))
    if tf - t0 < 0.1 * span:          # a perturbed duration stays a real one
        t0, tf = guess.t0, guess.tf
    return PhaseGuess(guess.state_names, guess.control_names, guess.s_table, guess.v_table, t0, tf,
                      guess.random_controls, guess.control_bounds, offsets, bounds)


def start_guesses(problem: Problem, previous: dict, start: int, seed: int | None, base_seed: int) -> dict:
    """Phase name -> the guess of start ``start`` of ``method: {starts: N}``.

    Start 0 is exactly the single start's guess (``make_guess(..., seed=seed)``, ``seed`` the
    run's ``--seed`` or a study's), so N starts never do worse than one. Start i >= 1 draws
    from ``base_seed + i`` (``method.seed``, or the run's seed).

    * The usual guess (straight lines, the middle of the bounds, the file's tables, a warm
      start): every phase's states and controls moved by smooth random curves and its free
      times drawn around their guess (:func:`perturb`).
    * Where the single start's controls are random already (``guess: {random: true}`` in a
      phase, or a run seed): a new draw of them from ``base_seed + i`` and nothing else,
      exactly as before perturbed starts existed. That guess is already a random start of
      the file's choosing, and the seed-0 rendezvous files (docs/seed0.md: about 2 in 3 of
      those draws reach the 3-axis optimum) keep their measured starts and results."""
    if start == 0:
        return {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=seed) for ph in problem.phases}
    s = base_seed + start
    if seed is not None or any(ph.guess.get("random") for ph in problem.phases):
        return {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=s) for ph in problem.phases}
    # one generator for the whole start, drawn phase by phase in order: reproducible
    rng = np.random.default_rng(abs(s))
    return {ph.name: perturb(problem, ph, make_guess(problem, ph, previous.get(ph.name)), rng)
            for ph in problem.phases}


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


def solved_guesses(problem: Problem, tr) -> dict:
    """Phase name -> the guess that starts a new model (another mesh, another objective) from
    the solution of the solved transcription ``tr``."""
    from .solution import extract

    solved = {t.name: t for t in extract(tr)}
    return {ph.name: make_guess(problem, ph, solved[ph.name]) for ph in problem.phases}


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
    # a guessed time outside its bounds (guess: {tf: 20} with 0.5 <= tf <= 10) starts at the bound
    t0, tf = min(max(t0, ph.t0_bounds[0]), ph.t0_bounds[1]), min(max(tf, ph.tf_bounds[0]), ph.tf_bounds[1])
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


def guess_notes(problem: Problem) -> list[str]:
    """The file's guesses that lie outside their bounds (each starts at the bound instead, as
    ``make_guess`` does): said, not silent (unseen12 F11: `tf: 50` with `tf <= 10`, `u: 7`
    with |u| <= 1 were accepted without a word)."""
    notes = []
    for ph in problem.phases:
        where = f"phase '{ph.name}': " if len(problem.phases) > 1 else ""
        for key, free, (lo, hi) in (("t0", ph.t0 is None, ph.t0_bounds), ("tf", ph.tf is None, ph.tf_bounds)):
            value = ph.guess.get(key)
            if free and isinstance(value, (int, float)) and not lo <= float(value) <= hi:
                notes.append(f"{where}the guess {key} = {float(value):g} is outside its bounds [{lo:g}, {hi:g}]: "
                             f"the solve starts from {min(max(float(value), lo), hi):g}")
        for var in ph.states + ph.controls:
            given = ph.guess.get("values", {}).get(var.name)
            if given is None:
                continue
            lo, hi = ph.bounds_of(var)
            try:
                values = _table(given, 0.0, 1.0)[1]
            except (KeyError, TypeError, ValueError):
                continue
            out = values[(values < lo) | (values > hi)]
            if out.size:
                notes.append(f"{where}the guess of {var.name} ({float(out[0]):g}) is outside its bounds "
                             f"[{lo:g}, {hi:g}]: it is moved onto them")
    return notes


def _table(value, t0: float, tf: float) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(value, (int, float)):
        return np.array([0.0, 1.0]), np.full(2, float(value))
    if isinstance(value, list):
        v = np.asarray(value, float)
        return np.linspace(0.0, 1.0, len(v)), v
    t = np.asarray(value["t"], float)
    v = np.asarray(value["values"], float)
    return (t - t0) / (tf - t0 if tf != t0 else 1.0), v


def flown_guess(problem: Problem, ph: Phase, guess: PhaseGuess, points: int = 101) -> PhaseGuess | None:
    """``guess`` with the states the guessed controls give flown from x(t0), where every state
    not guessed in the file has a fixed initial value and the phase has no free parameters;
    None otherwise, or where the flight leaves the numbers. The file's constant guess of x(t0)
    contradicts the dynamics wherever the controls move the state (unseen57 F1: a fed-batch
    fermenter from `guess: {u: 3}` ended `infeasible`, the volume guessed at 10 throughout where
    u = 3 takes it to 193, while that control flown from the start is feasible)."""
    from scipy.integrate import solve_ivp

    from ..verify.functions import PhaseFunctions

    fixed = _fixed_boundary(problem, ph)
    given = ph.guess.get("values", {})
    states = [x.name for x in ph.states]
    if guess.random_controls is not None or any((n, "t0") not in fixed for n in states if n not in given):
        return None
    if any(n in given for n in states):
        return None             # the file's own state guess stands
    try:
        funcs = PhaseFunctions(ph, {}, {})
    except Exception:  # noqa: BLE001  (free parameters, or symbols only a solve values: no flight)
        return None
    t0, tf = guess.t0, guess.tf
    if not tf > t0:
        return None

    def rhs(t, y):
        u = guess.controls_at(np.array([(t - t0) / (tf - t0)]))[0]
        return funcs.augmented_point(t, np.asarray(y, float), u)[:len(states)]

    s = np.linspace(0.0, 1.0, points)
    y0 = [fixed[(n, "t0")] for n in states]
    with np.errstate(all="ignore"):
        sol = solve_ivp(rhs, (t0, tf), y0, t_eval=t0 + s * (tf - t0), rtol=1e-6, atol=1e-9)
    if not sol.success or sol.y.shape[1] != points or not np.all(np.isfinite(sol.y)):
        return None
    s_table, v_table = dict(guess.s_table), dict(guess.v_table)
    for j, n in enumerate(states):
        s_table[n], v_table[n] = s, np.clip(sol.y[j], *ph.bounds_of(ph.states[j]))
    return PhaseGuess(guess.state_names, guess.control_names, s_table, v_table, t0, tf, None,
                      guess.control_bounds)
