"""Where do the local stages of a parametric file end from random starts? (docs/seed1.md)

    .venv/bin/python -m ocdsl.search.multistart configs/seed1_10N_paper.yaml STARTS [SEED] [--class SEGMENTS OUT]

Draws STARTS decision vectors uniformly in the swarm's box (integers rounded, tf uniform in
its bounds), drives each into the zeta box with least squares (tf free, coefficients in the
refinement's widened box), then runs the file's refinement (`refine`) from every start that
got inside. Prints one line per start and the sorted local minima: the distribution of what
the gradient stages find in the series class, without the swarm.

With ``--class SEGMENTS OUT`` (seed 1's files) the local stage is class mode instead
(``ocdsl.search.class_collocation``: the start written as a class member, then the hard
collocation problem at SEGMENTS segments; the optimal-mode file beside the paper file, with
``_paper`` replaced by ``_optimal``, supplies the Cartesian problem); run folders go to OUT.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from ocdsl.search.problem_file import shooting_problem
from ocdsl.search.local import polish, refine_box, refine_objective
from ocdsl.spec.compile import load
from ocdsl.spec.parametric import PolishSpec


def local_minima(path: str, starts: int, seed: int = 0, verbose: bool = True,
                 restore_iterations: int = 500, class_mode: tuple[int, str] | None = None) -> list[float]:
    """tf of the refined point of every start that least squares got inside the zeta box
    (with ``class_mode`` = (segments, out): of the verified class-mode solution)."""
    lf = load(path)
    pp = shooting_problem(lf)
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
        if class_mode is not None:
            tf, how = _class_mode(lf, path, pp, xs, k, *class_mode)
        else:
            xr, info = refine_objective(pp, xs, refine)
            tf, how = float(xr[itf]), info["refine"][:50]
        if tf is not None:
            minima.append(tf)
        if verbose:
            print(f"start {k}: inside at tf {xs[itf]:.5f} -> {how}, {time.perf_counter() - t0:.0f} s", flush=True)
    if verbose:
        print("local minima (tf, sorted):", " ".join(f"{v:.5f}" for v in sorted(minima)))
    return minima


def _class_mode(lf, path: str, pp, x, k: int, segments: int, out: str) -> tuple[float | None, str]:
    """Class mode from the class member x: (its verified tf or None, a short account)."""
    from pathlib import Path

    from ocdsl.search import class_collocation as cc

    itf = len(pp.variables)
    values = {"T": float(x[itf]), **{n: float(v) for n, v in zip(pp.names(), x)
                                      if n != "tf" and not any(n == p.name for p in pp.variables if p.integer)}}
    root = Path(out)
    cc.member_run(lf, values, root / f"member{k}")
    res = cc.refine_class(path, path.replace("_paper", "_optimal"), root / f"class{k}", segments=segments,
                          paper_run=root / f"member{k}", progress=False)
    ratio = res.extra["shooting"]["max_error_over_zeta"]
    return (res.tf if res.status == "feasible" else None), f"class mode {res.status} {res.tf:.5f} (max |e|/zeta {ratio:.3g})"


if __name__ == "__main__":
    args = sys.argv[1:]
    class_mode = None
    if "--class" in args:
        i = args.index("--class")
        class_mode = (int(args[i + 1]), args[i + 2])
        del args[i:i + 3]
    local_minima(args[0], int(args[1]), int(args[2]) if len(args) > 2 else 0, class_mode=class_mode)
