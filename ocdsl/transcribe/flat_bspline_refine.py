"""Refinement of a flat B-spline solution to a verification tolerance (``method:
{transcription: flat-bspline, tolerance: ...}``; docs/flatness.md, "Convergence").

The file's level is verified by :mod:`ocdsl.verify` (the one verification every back end
gets); while it fails, the next level (:func:`_next_level`) is solved from the previous
one. Every level is recorded in ``extra["refinement"]["levels"]`` (:func:`_level`), the
first being the file's own setting (for seed 2: the paper's collocated 15/15)."""
from __future__ import annotations

import time

from ..result import Result
from .flat_bspline_problem import solved_result

#: Ipopt options of a refined level, which starts at the previous level's solution: a small
#: barrier parameter and bound push keep it there (seed 2, 45 -> 85 control points: 18
#: iterations; with the default mu_init = 0.1 Ipopt left the start and ended infeasible)
REFINED_LEVEL_OPTIONS = {"mu_init": 1e-6, "bound_push": 1e-9, "bound_frac": 1e-9}


def _level(result, opts, verification: dict, wall_s: float) -> dict:
    """One row of ``extra["refinement"]``: the setting, NLP size, t_f, objective, dense
    residual, the verification's verdict and its largest miss."""
    failed = [c for c in verification.get("checks", []) if not c["passed"]]
    worst = max(verification.get("checks", []), key=lambda c: c["value"] / c["limit"] if c["limit"] else 0,
                default=None)
    dyn = [c["value"] for c in verification.get("checks", []) if c["name"] == "dynamics from x(t0)"]
    return {"control_points": opts.n_ctrl, "collocation_points": opts.n_col, "residual": opts.residual,
            "status": result.status, "variables": result.nlp.get("variables"),
            "constraints": result.nlp.get("constraints"), "tf": result.tf, "objective": result.objective,
            "max_residual_dense": max(result.extra["max_residual_dense"].values(), default=0.0),
            "reintegration_miss": max(dyn, default=None),
            "reduction": result.extra["flat_reduction"]["total"],
            "verification": verification.get("status"), "failed_checks": len(failed),
            "worst_check": None if worst is None else
            {k: worst[k] for k in ("name", "phase", "value", "limit", "where") if k in worst},
            "verification_summary": verification.get("summary"), "wall_time_s": round(wall_s, 3)}


def refine(file, mp, first: Result, options: dict, verbose: bool,
            first_wall_s: float) -> Result:
    """Verify at the method's tolerance; while a level fails, double the knot spans of
    every function (and the residual equations with them) and solve again from the level
    before. Stops at the first verified level, after ``refinements`` doublings, or when a
    level's solve does not converge (the last converged level is returned)."""
    from ..solve import ipopt
    from ..verify import CONVERGED, VerifySettings, attach_verification

    method = file.method
    tol = float(method.tolerance)
    settings = VerifySettings(tolerance=tol, rtol=min(1e-10, 1e-5 * tol))
    start = time.perf_counter()
    attach_verification(file.problem, first, settings)
    levels = [_level(first, mp.opts, first.verification, first_wall_s)]
    best = first
    current = mp
    for _ in range(method.refinements):
        if best.verification.get("status") == "verified":
            break
        t = time.perf_counter()
        nxt = current.with_options(_next_level(current.opts, method.refine_residual))
        nlp = nxt.build()
        nxt.warm_from(current)
        info = ipopt.solve(nlp.model, {**REFINED_LEVEL_OPTIONS, **options}, verbose=verbose)
        res = solved_result(file, nxt, nlp, info)
        attach_verification(file.problem, res, settings)
        levels.append(_level(res, nxt.opts, res.verification, time.perf_counter() - t))
        if res.status not in CONVERGED:
            break
        best, current = res, nxt
    best.extra["starts"] = first.extra.get("starts", [])
    best.extra["refinement"] = {"tolerance": tol, "levels": levels,
                                "wall_time_s": round(time.perf_counter() - start, 3)}
    best.message = (f"{best.message}; refined to {current.opts.n_ctrl} control points / "
                    f"{current.opts.n_col} {current.opts.residual} equations in {len(levels) - 1} step(s), "
                    f"verification {best.verification.get('status')} at {tol:g}")
    return best


def _next_level(opts, residual: str):
    """The same setting with ``residual`` if the level had another one (the seed's
    collocation, then its Galerkin form at the same size); else twice the knot spans, the
    residual equations growing by as many as the control points."""
    from dataclasses import replace

    if opts.residual != residual:
        return replace(opts, residual=residual, n_col=max(opts.n_col, opts.degree + 1))
    pieces = 2 * (opts.n_ctrl - opts.degree)
    n_ctrl = pieces + opts.degree
    return replace(opts, n_ctrl=n_ctrl, n_col=max(opts.n_col + n_ctrl - opts.n_ctrl, opts.degree + 1),
                   residual=residual)
