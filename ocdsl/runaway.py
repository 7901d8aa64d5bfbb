"""A free final time that ran away: where J keeps improving as t_f grows, the problem has no
optimum, and Ipopt stops wherever J's slope in t_f has fallen below its tolerance.

x' = u from 0 to 1, minimise int u^2 with t_f free and unbounded: J = 1/t_f, and the run
ended `optimal`, verified, exit 0 at t_f = 1.0e8 (the rest-to-rest double integrator, J =
6/t_f^3, at t_f = 1e5 with a certificate pass; unseen47 F1). The NLP's stationarity is met
there in absolute terms (dJ/dt_f = -1e-16), and the verification checks the trajectory, which
is feasible. So a phase whose free t_f, unbounded above, ended far beyond its guess is solved
once more with t_f fixed at twice its duration, from the solution: a better J there means the
reported point is no minimum.
"""
from __future__ import annotations

import math

from .result import Result
from .verify.objective_size import objective_size

# a free duration this many times its guess's (and 1) is checked
RUNAWAY = 100.0
STRETCH = 2.0


def _guessed_durations(file) -> dict[str, float]:
    from .transcribe.guess import start_guesses

    guesses = start_guesses(file.problem, {}, 0, None, 0)
    return {name: float(g.tf - g.t0) for name, g in guesses.items()}


def runaway_final_time(file, result: Result, tr, meshes, timer, *, verbose=False, progress=False) -> None:
    """Turn ``result`` ``diverged`` (with the reason in its message and
    ``extra["runaway_final_time"]``) when a stretched final time improves J. A mesh refinement's
    result is checked too: it was `mesh_not_converged`, J "off by 89 %" on its bisected mesh,
    with the advice to tighten the tolerance."""
    import pyomo.core as pyo

    from .fixed_mesh import _rebuilt
    from .solve import ipopt

    if result.status not in ("optimal", "acceptable", "mesh_not_converged") or result.objective is None:
        return
    candidates = [pb for pb in tr.phases if pb.phase.tf is None and not math.isfinite(pb.phase.tf_bounds[1])]
    if not candidates:
        return
    guessed = _guessed_durations(file)
    sense = 1.0 if file.problem.objective.sense == "minimize" else -1.0
    J = float(result.objective)
    threshold = file.spec.verify.tolerance * objective_size(J, result.extra.get("objective_scale"),
                                                            file.problem.objective_constant)
    for pb in candidates:
        t0, tf = float(pyo.value(pb.block.t0)), float(pyo.value(pb.block.tf))
        if tf - t0 <= RUNAWAY * max(guessed.get(pb.phase.name, 1.0), 1.0):
            continue
        with timer.measure("post"):
            stretched = _rebuilt(file, tr, meshes)
            block = next(b.block for b in stretched.phases if b.phase.name == pb.phase.name)
            target = t0 + STRETCH * (tf - t0)
            block.tf.setub(None)
            block.tf.fix(target)
            info = ipopt.solve(stretched.model, file.spec.solver.options, verbose=verbose,
                               progress=ipopt.Progress(progress, "[t_f stretched]"), transcription=stretched)
        if info.status != "optimal" or info.objective is None:
            continue
        gain = sense * (J - float(info.objective))
        record = {"phase": pb.phase.name, "final_time": tf, "objective": J, "stretched_final_time": target,
                  "stretched_objective": float(info.objective), "gain": gain, "threshold": threshold}
        result.extra["runaway_final_time"] = record
        if gain > threshold:
            where = "" if len(tr.phases) == 1 else f"phase {pb.phase.name!r}'s "
            result.status = "diverged"
            result.message = (
                f"J keeps improving as {where}t_f grows: J = {J:.10g} at t_f = {tf:.6g} (its guess "
                f"{t0 + guessed.get(pb.phase.name, 1.0):.6g}), and {float(info.objective):.10g} with t_f fixed at "
                f"{target:.6g}: this is no minimum, and the problem likely has none with t_f free and "
                "unbounded above (J falling on as t_f grows; Ipopt stopped where J's slope in t_f fell "
                "below its tolerance). Bound t_f (`tf <= ...`) or give the time a cost")
            return
