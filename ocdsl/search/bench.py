"""Fitness evaluations per second per core for the seed 1, 10 N paper-mode problem.

``python -m ocdsl.search.bench [config] [--particles N] [--scipy-evals M]`` prints the
rate of the compiled DOP853 kernel (one thread, batched over a random swarm drawn from
the search box, the configured tolerance and Sundman regularisation) against SciPy's
``solve_ivp(method="DOP853")`` driving the very same compiled right-hand side and
control series, and their ratio. The target of issue 9 is >= 300 evaluations/s/core.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

DEFAULT = Path(__file__).resolve().parents[2] / "configs" / "seed1_10N_paper.yaml"


def measure(config: str | Path = DEFAULT, particles: int = 64, scipy_evals: int = 6, seed: int = 0,
            repeats: int = 3) -> dict:
    from ocdsl.simulate import scipy_final_state
    from ocdsl.spec.compile import load

    from .problem_file import shooting_problem

    lf = load(config)
    pp = shooting_problem(lf)
    pp.threads = False
    lo, hi, is_int = pp.bounds()
    rng = np.random.default_rng(seed)
    X = lo + rng.random((particles, len(lo))) * (hi - lo)
    X[:, is_int] = np.round(X[:, is_int])
    t0 = time.perf_counter()
    pp.fitness(X[:2])                          # load / compile the kernel
    compile_s = time.perf_counter() - t0
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        pp.fitness(X)
        best = min(best, time.perf_counter() - t0)
    mine = particles / best
    cm = pp.compiled
    var, tf, CD = pp.decode(X[:scipy_evals])
    P = pp._P(var, scipy_evals)
    t0 = time.perf_counter()
    diffs = []
    for b in range(scipy_evals):
        y_ref, _ = scipy_final_state(cm, pp.y0, float(tf[b]), P[b], pp.layout, CD[b], rtol=pp.rtol, atol=pp.atol)
        Yf, st, *_ = pp.final(X[b:b + 1], parallel=False)
        if st[0] == 1:  # reached tf (not stopped by an impact/escape guard, which SciPy lacks)
            diffs.append(float(np.max(np.abs(y_ref - Yf[0]) / np.maximum(1.0, np.abs(y_ref)))))
    worst = float(np.median(diffs)) if diffs else float("nan")
    t_scipy = time.perf_counter() - t0
    # subtract the (tiny) time of our own re-evaluations inside the loop
    t_own = scipy_evals / mine
    scipy_rate = scipy_evals / max(t_scipy - t_own, 1e-9)
    return {"evals_per_s_per_core": mine, "scipy_evals_per_s_per_core": scipy_rate,
            "ratio": mine / scipy_rate, "compile_or_load_s": compile_s,
            "median_rel_diff_vs_scipy": worst, "compared": len(diffs), "rtol": pp.rtol, "atol": pp.atol,
            "particles": particles, "load_avg": os.getloadavg()[0]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default=str(DEFAULT))
    ap.add_argument("--particles", type=int, default=64)
    ap.add_argument("--scipy-evals", type=int, default=6)
    a = ap.parse_args(argv)
    r = measure(a.config, a.particles, a.scipy_evals)
    print(f"seed 1, 10 N fitness (rtol {r['rtol']:g}, atol {r['atol']:g}), one core:")
    print(f"  ocdsl DOP853 (Numba)      {r['evals_per_s_per_core']:10.1f} evals/s/core   (target >= 300)")
    print(f"  SciPy solve_ivp(DOP853)   {r['scipy_evals_per_s_per_core']:10.1f} evals/s/core   (same compiled RHS)")
    print(f"  ratio                     {r['ratio']:10.1f} x")
    print(f"  kernel compile/load {r['compile_or_load_s']:.1f} s; median rel. final-state difference vs SciPy "
          f"{r['median_rel_diff_vs_scipy']:.2e} (median of {r['compared']} runs reaching tf); 1-min load average {r['load_avg']:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
