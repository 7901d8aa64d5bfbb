"""Where do the local stages of a parametric file end from random starts? (docs/seed1.md)

    .venv/bin/python -m ocdsl.search.multistart configs/seed1_10N_paper.yaml STARTS [SEED]

Draws STARTS decision vectors uniformly in the swarm's box (integers rounded, tf uniform in
its bounds), drives each into the zeta box with least squares (tf free, coefficients in the
refinement's widened box), then runs the file's refinement (`refine`) from every start that
got inside. Prints one line per start and the sorted local minima: the distribution of what
the gradient stages find in the series class, without the swarm.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from ocdsl.search.run import build, polish, refine_box, refine_tf
from ocdsl.spec.compile import load
from ocdsl.spec.parametric import PolishSpec


def local_minima(path: str, starts: int, seed: int = 0, verbose: bool = True,
                 restore_iterations: int = 500) -> list[float]:
    """tf of the refined point of every start that least squares got inside the zeta box."""
    lf = load(path)
    integers = [n for n, p in lf.method.parameters.items() if p.integer]
    pp = build(lf.problem, lf.method, integers)
    lo, hi, is_int = pp.bounds()
    refine = lf.method.refine
    wide = refine_box(pp, refine.box_scale)
    itf = len(pp.variables)
    rng = np.random.default_rng(seed)
    restore = PolishSpec(method="least_squares", max_iterations=restore_iterations, free_tf=True)
    minima = []
    for k in range(starts):
        x = lo + (hi - lo) * rng.random(len(lo))
        x[is_int] = np.round(x[is_int])
        t0 = time.perf_counter()
        xs, _ = polish(pp, x, restore, stop_ratio=refine.target_ratio, bounds=wide)
        ratio = pp.details(xs)["ratio"].max()
        if not ratio <= 1.0:
            if verbose:
                print(f"start {k}: least squares ends at max |e|/zeta {ratio:.3g}, not refined", flush=True)
            continue
        xr, info = refine_tf(pp, xs, refine)
        minima.append(float(xr[itf]))
        if verbose:
            print(f"start {k}: inside at tf {xs[itf]:.5f} -> refined {xr[itf]:.5f} ({info['refine'][:50]}), "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    if verbose:
        print("local minima (tf, sorted):", " ".join(f"{v:.5f}" for v in sorted(minima)))
    return minima


if __name__ == "__main__":
    local_minima(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 0)
