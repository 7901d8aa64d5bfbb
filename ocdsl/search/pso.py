"""Particle swarm optimisation, continuous and mixed-integer ("discrete", Jin et al.).

Global-best PSO with a linearly decreasing inertia weight w(k) from ``inertia[0]`` to
``inertia[1]``, cognitive/social coefficients c1, c2, velocities clipped to
``velocity_limit`` times each box width, and positions kept in the box (a particle that
hits a wall stops there: its velocity component is zeroed).

Integer coordinates (``discrete``):

- ``"jin"`` (default): my reading of the discrete PSO of Jin, Cheng, Yan & Zhang
  (Electric Power Systems Research 77, 2007), which seed 1 cites but whose equations are
  not reproduced in the seed paper and which I could not consult. Integer coordinates
  live on the integer lattice at all times: the velocity is updated by the usual
  continuous rule, and the position moves by the *rounded* velocity,
  x <- clip(x + round(v)). The personal/global bests are therefore always feasible
  integer points, and no information is lost by rounding only at evaluation. When the
  rounded velocity of every integer coordinate of the swarm has been zero for a while the
  swarm has simply agreed on the integer; this is the intended convergence.
- ``"round"``: plain continuous PSO on the relaxed coordinate, rounded to the nearest
  integer when evaluated (the digest's "usual reading", §4); the stored position stays
  continuous.

A problem without integer coordinates is plain continuous PSO either way.

Topology (``topology``): ``"global"`` (default) attracts every particle to the swarm's
best; ``"ring"`` (local-best PSO) attracts particle i to the best personal best among
particles i-1, i, i+1 (indices modulo the swarm size), which spreads information slowly
and keeps several basins alive longer. The reported best is the swarm's best either way.

Restarts (``restarts`` > 1): independent swarms with seeds seed, seed+1, ...; the one
with the lowest best fitness is returned (its history and swarm), with the evaluations,
iterations and wall time of all of them summed and a summary of each in ``restarts``.

The objective is evaluated a batch at a time: ``fitness(X) -> f`` with X of shape
(n, d). ``executor`` is a ``map``-like callable (``executor(fn, chunks)`` returning an
iterable of results, as ``concurrent.futures.Executor.map`` or the builtin ``map``); the
swarm is split into ``chunks`` row blocks so that a process pool or the studies executor
can spread them. The default evaluates in-process.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

import numpy as np

Fitness = Callable[[np.ndarray], np.ndarray]
MapLike = Callable[[Callable, Iterable], Iterable]


@dataclass
class PSOSettings:
    particles: int = 64
    iterations: int = 500
    inertia: tuple[float, float] = (0.9, 0.4)
    c1: float = 2.0
    c2: float = 2.0
    velocity_limit: float = 0.2
    discrete: str = "jin"
    stall_iterations: int = 0
    tolerance: float = 0.0
    target: float | None = None
    seed: int = 0
    chunks: int = 0
    topology: str = "global"
    restarts: int = 1

    @classmethod
    def from_spec(cls, spec) -> "PSOSettings":
        d = spec.model_dump() if hasattr(spec, "model_dump") else dict(spec)
        d.pop("name", None)
        return cls(**d)


@dataclass
class PSOResult:
    x: np.ndarray
    f: float
    iterations: int
    n_evals: int
    history: dict[str, np.ndarray]
    stop_reason: str
    wall_time_s: float
    swarm_x: np.ndarray = field(repr=False, default=None)
    swarm_f: np.ndarray = field(repr=False, default=None)
    restarts: list = field(default_factory=list)


def _evaluate(fitness: Fitness, X: np.ndarray, executor: MapLike | None, chunks: int) -> np.ndarray:
    if executor is None or chunks <= 1:
        return np.asarray(fitness(X), float).reshape(len(X))
    blocks = np.array_split(X, min(chunks, len(X)))
    parts = list(executor(fitness, blocks))
    return np.concatenate([np.asarray(p, float).reshape(-1) for p in parts])


def pso(fitness: Fitness, lower: Sequence[float], upper: Sequence[float],
        integer: Sequence[bool] | None = None, settings: PSOSettings | None = None,
        executor: MapLike | None = None, callback: Callable[[dict], None] | None = None,
        initial: np.ndarray | None = None) -> PSOResult:
    """Minimise ``fitness`` over the box [lower, upper] (integer coordinates flagged).

    ``callback(info)`` is called after each iteration with ``iteration``, ``best_f``,
    ``best_x``, ``n_evals``, ``evals_per_s``; returning True stops the search.
    ``initial`` optionally seeds the first particles' positions.
    Reproducible: the same ``settings.seed`` gives the same swarm and result.
    """
    s = settings or PSOSettings()
    if s.restarts > 1:
        from dataclasses import replace
        runs = [pso(fitness, lower, upper, integer, replace(s, restarts=1, seed=s.seed + k), executor,
                    callback, initial) for k in range(s.restarts)]
        best = min(range(len(runs)), key=lambda k: runs[k].f)
        out = runs[best]
        summary = [{"seed": s.seed + k, "best_f": r.f, "iterations": r.iterations, "evaluations": r.n_evals,
                    "stop_reason": r.stop_reason, "x": r.x.tolist()} for k, r in enumerate(runs)]
        return PSOResult(out.x, out.f, sum(r.iterations for r in runs), sum(r.n_evals for r in runs),
                         out.history, out.stop_reason, sum(r.wall_time_s for r in runs),
                         out.swarm_x, out.swarm_f, summary)
    lo = np.asarray(lower, float)
    hi = np.asarray(upper, float)
    d = len(lo)
    if np.any(hi < lo):
        raise ValueError("pso: upper bound below lower bound")
    is_int = np.zeros(d, bool) if integer is None else np.asarray(integer, bool)
    if s.discrete not in ("jin", "round"):
        raise ValueError(f"pso: discrete must be 'jin' or 'round', not {s.discrete!r}")
    if s.topology not in ("global", "ring"):
        raise ValueError(f"pso: topology must be 'global' or 'ring', not {s.topology!r}")
    rng = np.random.default_rng(s.seed)
    n = s.particles
    width = hi - lo
    vmax = s.velocity_limit * np.where(width > 0, width, 1.0)
    vmax = np.where(is_int, np.maximum(vmax, 1.0), vmax)  # integers must be able to move
    chunks = s.chunks if s.chunks > 0 else 1

    X = lo + rng.random((n, d)) * width
    if initial is not None:
        init = np.atleast_2d(np.asarray(initial, float))[:n]
        X[:len(init)] = np.clip(init, lo, hi)
    if np.any(is_int):
        X[:, is_int] = np.round(X[:, is_int])
        X[:, is_int] = np.clip(X[:, is_int], np.ceil(lo[is_int]), np.floor(hi[is_int]))
    V = (rng.random((n, d)) * 2 - 1) * vmax * 0.5
    if s.discrete == "jin":
        V[:, is_int] = np.round(V[:, is_int])

    def point(Xs):
        if s.discrete == "round" and np.any(is_int):
            Xs = Xs.copy()
            Xs[:, is_int] = np.round(Xs[:, is_int])
        return Xs

    t_start = time.perf_counter()
    F = _evaluate(fitness, point(X), executor, chunks)
    F = np.where(np.isfinite(F), F, np.inf)
    n_evals = n
    P, PF = X.copy(), F.copy()
    g = int(np.argmin(PF))
    G, GF = P[g].copy(), float(PF[g])
    hist = {k: [] for k in ("iteration", "best_f", "mean_f", "evals", "wall_s", "inertia")}

    def log(it, w):
        hist["iteration"].append(it)
        hist["best_f"].append(GF)
        finite = PF[np.isfinite(PF)]
        hist["mean_f"].append(float(np.mean(finite)) if len(finite) else np.inf)
        hist["evals"].append(n_evals)
        hist["wall_s"].append(time.perf_counter() - t_start)
        hist["inertia"].append(w)

    log(0, s.inertia[0])
    stall = 0
    reason = "iterations"
    it = 0
    for it in range(1, s.iterations + 1):
        frac = (it - 1) / max(s.iterations - 1, 1)
        w = s.inertia[0] + (s.inertia[1] - s.inertia[0]) * frac
        r1 = rng.random((n, d))
        r2 = rng.random((n, d))
        if s.topology == "ring":
            nb = np.stack([np.roll(np.arange(n), 1), np.arange(n), np.roll(np.arange(n), -1)])
            L = P[nb[np.argmin(PF[nb], axis=0), np.arange(n)]]
        else:
            L = G
        V = w * V + s.c1 * r1 * (P - X) + s.c2 * r2 * (L - X)
        V = np.clip(V, -vmax, vmax)
        if s.discrete == "jin" and np.any(is_int):
            step = V.copy()
            step[:, is_int] = np.round(V[:, is_int])
            Xn = X + step
        else:
            Xn = X + V
        hit = (Xn < lo) | (Xn > hi)
        X = np.clip(Xn, lo, hi)
        V[hit] = 0.0
        F = _evaluate(fitness, point(X), executor, chunks)
        F = np.where(np.isfinite(F), F, np.inf)
        n_evals += n
        better = F < PF
        P[better] = X[better]
        PF[better] = F[better]
        g = int(np.argmin(PF))
        improved = GF - PF[g] > s.tolerance
        if PF[g] < GF:
            G, GF = P[g].copy(), float(PF[g])
        stall = 0 if improved else stall + 1
        log(it, w)
        if callback is not None:
            el = time.perf_counter() - t_start
            info = {"iteration": it, "best_f": GF, "best_x": point(G[None, :])[0], "n_evals": n_evals,
                    "evals_per_s": n_evals / el if el > 0 else 0.0}
            if callback(info):
                reason = "callback"
                break
        if s.target is not None and GF <= s.target:
            reason = "target"
            break
        if s.stall_iterations and stall >= s.stall_iterations:
            reason = "stall"
            break
    best = point(G[None, :])[0]
    return PSOResult(best, GF, it, n_evals, {k: np.asarray(v, float) for k, v in hist.items()},
                     reason, time.perf_counter() - t_start, point(P), PF)
