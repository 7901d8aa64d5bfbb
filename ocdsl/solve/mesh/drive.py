"""The mesh iteration loop: solve, estimate, locate, refine or coarsen, warm-start the next
mesh; returns the Result with the mesh history."""
from __future__ import annotations

import dataclasses
import functools
import math
import time

import numpy as np

from ...progress import say
from ...result import PhaseTrajectory, Result
from ..arcs import free_final_times
from .coarsen import coarsen, nlp_size
from .estimate import estimate_errors, flight_amplification, flight_rtol, phase_end, segment_ends
from .junction import jumping_ends, limit_junction_controls
from .flown import (announce_again, beaten_meshes, refined_again, refuted_corners, second_pass_no_better,
                    second_pass_recorded, with_breakpoints)
from .locate import locate_features, locate_switches, misplaced
from .confirm import confirm
from .outcome import GOOD, RAISE_ADVICE, _objective_disagreement, outcome, record
from .refine import MeshStalled, refine, same_mesh
from .switches import solve_switch_times
from .regularise import chattering_segments, merge_intervals, regularise
from .segments import close_mesh, control_polys, dense_trajectory
from .terminal import TerminalError, terminal_error
from .budget import Budget
from ...verify.objective_size import own_size

# above this amplification of the open-loop flight (``flight_amplification``) the terminal
# conditions are judged piece by piece (``segment_ends``): the segment errors (1e-6 and more)
# times 1e6 would be all the flight from x(t0) sees
AMPLIFICATION = 1e6


# meshes started from the file's guess because the one before zigzagged where an integral's
# quadrature missed (restart.exploits_quadrature): the hanging chain needed two; every mesh
# restarted (a catenary on LGR-start, unseen20 p14, from 3 segments) lost the warm start that
# had converged it (10 meshes, J 1.3e-4 low, where it had converged to 1.9e-8)
GUESS_RESTARTS = 2
# two refinements that multiply the NLP by this much, to at least GROWTH_FLOOR variables, while
# the error falls by less than ten times end the refinement (``solve_adaptive``); small meshes
# grow fast on their way (Goddard: 14 -> 72 variables in its first two refinements, then
# converged at 1,092)
GROWTH_LIMIT = 5.0
GROWTH_FLOOR = 2000
# and three refinements that grow it by half, to at least GROWTH_FLOOR, with no tenth off the
# error: the slow form of the same (unseen36 F5: LGL on a singular arc, the error 2.47e-4 at
# 3,804 variables and 2.43e-4 at 8,534 eight meshes later)
FLAT_GROWTH, FLAT_MESHES = 1.5, 3

# a converged mesh is coarsened only to a mesh of at most this share of its NLP: a solve (and a
# refinement back when it misses) for a few percent fewer unknowns costs more than it saves
# (COPS hang glider: 1,173 -> 583 missed, 588 converged, then 518 missed, 533 converged, 508
# missed: three of its twelve meshes for 10 % of a small NLP)
COARSEN_GAIN = 0.8


def starting_mesh(method) -> dict:
    """``segments`` and ``degree`` of the first mesh: the method's where the file gives them,
    else the mesh block's."""
    given = method.model_fields_set
    return {key: getattr(method if key in given else method.mesh, key) for key in ("segments", "degree")}


def initial_meshes(file) -> dict:
    from ...transcribe.mesh import Mesh

    method, spec = file.method, file.method.mesh
    segments, degree = starting_mesh(method).values()
    if isinstance(degree, int):
        degree = min(max(degree, spec.min_degree), spec.max_degree)
    return {ph.name: Mesh.uniform(method.transcription, segments, degree) for ph in file.problem.phases}


def _scale(file, tr) -> None:
    from ...run import _scale as scale

    scale(file, tr)


def _blind(errors: dict) -> bool:
    """Some segment holds a junction between two of its nodes that the estimate cannot see."""
    return any(e.inner_junction for es in errors.values() for e in es)


def solve_adaptive(file, timer, *, seed=None, warm_start=None, verbose=False, progress=False,
                   pinned: dict | None = None, first: dict | None = None, start: dict | None = None) -> Result:
    """Solve with adaptive mesh refinement; returns a Result with the mesh history. ``pinned``
    (phase -> normalised times every mesh keeps as features), ``first`` (start meshes) and
    ``start`` (start trajectories): the refinement once more after the flown control refuted
    the first answer (flown.py), a second pass of at most max_iterations meshes whose record
    follows the first's."""
    import pyomo.core as pyo

    from ...run import _result
    from ...runaway import runaway_final_time
    from ...transcribe.guess import make_guess, solved_guesses, start_guesses
    from ...transcribe.mesh import Layout
    from ...transcribe.pseudospectral import build
    from .. import ipopt
    from .. import warm_start as ws
    from ..failure_hints import failure_hints
    from ..certify import minimum_condition_notes
    from .restart import bisect_first, exploits_quadrature, multiplier_cap, restart, warm_cap

    from ...run import _better, _start_record, recover_from_infeasibility

    ipopt.check_available()
    problem, spec = file.problem, file.method.mesh
    n_starts = file.method.starts
    base_seed = file.method.seed if seed is None else seed
    start_records: list = []
    meshes = first or initial_meshes(file)
    snapshot = None      # the previous mesh's solution, multipliers included (warm_start.py)
    from ...run import previous_phases, start_notes

    previous: dict[str, PhaseTrajectory] = start if start is not None else previous_phases(file, warm_start)
    given = previous      # what the first mesh started from (a later mesh's retry starts there too)
    # the guesses of the start that won on the first mesh when it was not start 0 (``starts:``):
    # a later mesh solved again "from the guess" (``restart``) starts from these
    start_won: dict | None = None
    notes = start_notes(file, previous)
    options = dict(file.spec.solver.options)
    # the NLP must be solved well below the mesh tolerance, or solver noise (Ipopt's
    # relaxation of the bounds, its stopping tolerance) is what the estimate measures
    options.setdefault("tol", min(1e-8, 1e-2 * spec.tolerance))
    options.setdefault("bound_relax_factor", min(1e-8, 1e-3 * spec.tolerance))
    history, tables = [], {k: [] for k in ("iteration", "phase", "segments", "min_degree", "max_degree", "nlp_variables",
                                          "nlp_constraints", "ipopt_iterations", "objective",
                                          "max_error", "max_error_segment", "max_error_t", "time_s")}
    best = None          # (max_error, iteration, tr, info, meshes, errors)
    status, message = None, ""
    stalled = ""         # why the refinement stopped before max_iterations without converging
    growth: list = []    # (NLP variables, largest error) of each refined (not coarsened) mesh
    guess_restarts = 0   # meshes started from the file's guess because the one before zigzagged
    last = None
    solved_before = None   # (meshes, largest error) of the previous iteration that missed the tolerance
    nudge_grace = True     # the first solve-again after a breakpoint nudge refines the segments it held
    converged = []       # iterations within tolerance with every located switch on a breakpoint
    moved_at = 0         # the first mesh after a fixed-time switch was moved (best-mesh choice)
    coarsening = False   # the current mesh came from coarsening a converged one
    tried: list = []     # the coarsened meshes tried so far (each is tried once)
    nudged: dict = {}    # per phase: the switches ``refine`` moved breakpoints onto last time, and their (b, f)
    junction_memory: dict = {}   # per phase: the previous junction estimates (locate_junctions' secant)
    chatter: dict = {}   # per phase: the chattering arcs found so far (regularise)
    reg_weight = spec.regularise
    located: dict = {}   # per phase: the features located on the previous mesh (limit_junction_controls)
    tied_ends: dict = {}  # per phase: outer ends whose collocated control jumped on some mesh (tied from then on)
    budget = Budget.of(spec)   # the symbolic steps' time and memory bounds (budget.py)
    terminal_notes: list = []  # where the terminal conditions were judged piece by piece (unstable dynamics)
    amplification: dict = {}   # per phase: the last measured flight amplification
    if not spec.symbolic:
        budget.notes.append("symbolic steps off (mesh: {symbolic: false}): no boundary controls, "
                            "state-constrained arcs located from the control polynomials only")
    noted = 0            # budget notes already printed
    first_iterations = None   # Ipopt's iterations on the first mesh (warm_cap)
    last_iterations = None    # ... and on the mesh before (multiplier_cap)
    from ...progress import Stage

    stage = Stage("mesh refinement", spec.max_iterations, enabled=progress, at_most=True, interval=0.0)
    for it in range(1, spec.max_iterations + 1):
        t_iter = time.perf_counter()
        with timer.measure("build"):
            # the first mesh starts from the guess (start 0 of ``starts:``, the single start's);
            # later meshes from the previous mesh's solution (``previous``)
            guesses = {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=seed if it == 1 else None)
                       for ph in problem.phases}
            built_with = ({k: list(v) for k, v in chatter.items()}, dict(located),
                          {k: set(v) for k, v in tied_ends.items()})

            def rebuild(ms, guesses=guesses, built_with=built_with, collect=False, free_breakpoints=None,
                        regularised=True):
                """The model on meshes ``ms``, built as this iteration's (switches.py: trial
                models, built without the collection that precedes the iteration's own);
                ``regularised=False``: without the regularisation and the located features'
                ties, the tied end controls kept (confirm.py's check of the unregularised J)."""
                chatter_arcs, features, ends = built_with if regularised else ({}, {}, built_with[2])
                t = build(problem, ms, guesses, collect=collect, free_breakpoints=free_breakpoints)
                _scale(file, t)
                if spec.regularise:
                    regularise(t, chatter_arcs, reg_weight)
                if spec.junction_control == "limit":
                    limit_junction_controls(t, features, spec.corner_tolerance, ends)
                return t

            tr = rebuild(meshes, collect=True)
            reg = getattr(tr.model, "mesh_regularisation", None)
            ws.prepare(tr.model)
            mult = ws.apply(snapshot, tr) if snapshot is not None else None
        with timer.measure("solve"):
            bar = ipopt.Progress(progress, f"[mesh {it}]")
            capped = warm_cap(options, first_iterations) if it > 1 else None
            mcap = multiplier_cap(last_iterations)
            info = ipopt.solve(tr.model, options if capped is None else {**options, "max_iter": capped},
                               verbose=verbose, progress=bar, multipliers=mult, transcription=tr,
                               multipliers_max_iter=mcap)
            if it == 1 and n_starts > 1:
                # ``starts:`` with ``mesh:``: the starts on the first mesh, refinement from the best
                start_records.append(_start_record(0, seed, info))
                for i in range(1, n_starts):
                    g = start_guesses(problem, previous, i, seed, base_seed)    # perturbed copies
                    t = rebuild(meshes, guesses=g, collect=True)
                    ws.prepare(t.model)
                    res = ipopt.solve(t.model, options, verbose=verbose,
                                      progress=ipopt.Progress(progress, f"[mesh 1, start {i + 1}/{n_starts}]"),
                                      transcription=t)
                    start_records.append(_start_record(i, base_seed + i, res))
                    if _better(res, info, problem.objective.sense):
                        tr, info, start_won = t, res, g
                        # trial models of this iteration (switches.py) start from the best start's guess
                        rebuild = functools.partial(rebuild, guesses=g)
                        reg = getattr(tr.model, "mesh_regularisation", None)
        first_iterations = info.iterations if it == 1 else first_iterations
        from_guess = False      # this mesh solved from the file's guess (restart.py)

        def recover(ms, failed, t):
            """A single solve's recovery from a locally infeasible end, on meshes ``ms`` (seeded
            controls, then the relaxed solve's feasible point: run.recover_from_infeasibility)."""
            def build_on(g):
                built = rebuild(ms, guesses=g, collect=True)
                ws.prepare(built.model)
                return built

            return recover_from_infeasibility(file, ms, previous, timer, seed=seed, options=options, info=failed,
                                              tr=t, verbose=verbose, progress=progress, build_model=build_on)
        if it > 1 and info.status not in GOOD and info.status not in ("time_limit", "interrupted"):
            def cold(given=given):
                t = rebuild(meshes, guesses=start_won or {ph.name: make_guess(problem, ph, given.get(ph.name))
                                                          for ph in problem.phases}, collect=True)
                ws.prepare(t.model)
                return t

            def warm():
                t = rebuild(meshes, collect=True)
                ws.prepare(t.model)
                return t, (ws.apply(snapshot, t) if snapshot is not None else None)

            def solve_again(t, m, label):
                return ipopt.solve(t.model, options, verbose=verbose, transcription=t, multipliers=m,
                                   progress=ipopt.Progress(progress, label))

            redone = restart(it, info, capped, cold=cold, warm=warm, solve=solve_again, timer=timer)
            if redone is None and info.status == "infeasible":
                # infeasible from the mesh before and from the guess: the first mesh's recovery
                # (seeded controls, then the relaxed solve's feasible point) before the loop stops
                # (unseen38 F4: the oscillator from (10, 3), LGR 2 x 3 then 6 segments infeasible,
                # the refinement ended at iteration 2 of 15 on mesh 1's answer, 11 % off)
                again = recover(meshes, info, tr)
                if again.guesses is not None:
                    redone = (again.tr, again.info, None)
            if redone is not None:
                tr, info, mult = redone
                from_guess = mult is None
                reg = getattr(tr.model, "mesh_regularisation", None)
        last_iterations = info.iterations


        def first_solve(ms, bisections):
            """The first mesh's model on meshes ``ms`` (bisected ``bisections`` times), solved."""
            t = rebuild(ms, collect=True)
            ws.prepare(t.model)
            return t, ipopt.solve(t.model, options, verbose=verbose, transcription=t,
                                  progress=ipopt.Progress(progress, f"[mesh 1 bisected {bisections}x]"))

        if it == 1 and info.status == "infeasible":
            # as a single solve: one more start from seeded random controls, else the
            # conditions that cannot hold together named (run.recover_from_infeasibility)
            if not start_records:           # one start: recorded beside its retry, as a single solve does
                start_records.append(_start_record(0, seed, info))
            recovered = recover(meshes, info, tr)
            start_records += recovered.records
            if recovered.guesses is not None:
                tr, info = recovered.tr, recovered.info
                rebuild = functools.partial(rebuild, guesses=recovered.guesses)
                reg = getattr(tr.model, "mesh_regularisation", None)
            # the first mesh's polynomials may be what cannot meet the conditions, not the problem
            # (unseen16: v <= 1.1 rest to rest on LG 3 x 3, 'infeasible' blaming x(t0) == 0):
            # bisected, twice at most, before the problem is called infeasible
            if info.status == "infeasible":
                def first_solve_recovered(ms, bisections):
                    """``first_solve``, and where it ends infeasible the recovery the first mesh had:
                    the guess alone left a bisected mesh locally infeasible that a plain solve of
                    the same mesh recovers from (unseen38 F3: the oscillator from (-6, 4) on LG
                    2 x 3, "infeasible, the problem leaves x1(t0) == -6 unmet"; LG 8 x 3 alone solves)"""
                    t, res = first_solve(ms, bisections)
                    if res.status != "infeasible":
                        return t, res
                    again = recover(ms, res, t)
                    return (again.tr, again.info) if again.guesses is not None else (t, res)

                tr, info, meshes = bisect_first(first_solve_recovered, tr, info, meshes,
                                                "was infeasible, the problem is not",
                                                lambda i: i.status == "infeasible", 2, notes)
                reg = getattr(tr.model, "mesh_regularisation", None)
        if it == 1 and info.message.startswith((ipopt.TOO_FEW_FREEDOMS, ipopt.SQUARE)):
            # as many equality constraints as unknowns or more: the boundary conditions of many
            # states leave a coarse start mesh no freedom (unseen21 U2: 8 masses, 32 end values,
            # on 2 x 3; U1: a quaternion slew's one feasible point on 2 x 3, tf 3.81 for 2, from
            # which the next mesh took 20,000 iterations); each bisection adds every control's nodes
            unfree = lambda i: i.message.startswith((ipopt.TOO_FEW_FREEDOMS, ipopt.SQUARE))  # noqa: E731
            tr, info, meshes = bisect_first(first_solve, tr, info, meshes, "left the objective no freedom", unfree, 4,
                                            notes)
            reg = getattr(tr.model, "mesh_regularisation", None)
        reg_value = None
        if reg is not None and info.objective is not None:
            # the objective of the problem itself: the regularisation term taken out
            reg_value = float(pyo.value(reg))
            info.objective += reg_value if tr.model.objective.sense == pyo.maximize else -reg_value
        with timer.measure("mesh"):
            params = {s: float(pyo.value(tr.scalars[s])) for s in problem.free_parameters}
            errors = {pb.phase.name: estimate_errors(pb, params, active_tol=max(1e-9, 0.1 * spec.tolerance),
                                                     rtol=flight_rtol(spec.tolerance),
                                                     smooth_above=spec.tolerance if spec.smooth_control else None)
                      if info.status in GOOD else []
                      for pb in tr.phases}
            term = TerminalError(math.inf, "")
            if info.status in GOOD:
                ends = {pb.phase.name: phase_end(pb, params, flight_rtol(spec.tolerance)) for pb in tr.phases}
                term = terminal_error(problem, ends, params)
                if term.error > spec.tolerance:
                    # the open-loop flight of unstable dynamics measures its own amplification,
                    # not the solution: where it exceeds AMPLIFICATION the phase's terminal
                    # conditions are judged piece by piece instead (each segment flown from its
                    # own start, ``segment_ends``). Measured only when the flight misses them:
                    # a flight that meets them is a trajectory that does, however unstable.
                    # a phase measured far below AMPLIFICATION keeps that measure (the flow's
                    # sensitivity changes little between meshes; a phase that became unstable
                    # would only be judged the stricter way, from x(t0)); near or above it,
                    # every time
                    amp = {pb.phase.name: (amplification[pb.phase.name]
                                           if amplification.get(pb.phase.name, math.inf) <= 1e-2 * AMPLIFICATION
                                           else flight_amplification(pb, params, ends[pb.phase.name]))
                           for pb in tr.phases}
                    amplification.update(amp)
                    unstable = {k: a for k, a in amp.items() if not a <= AMPLIFICATION}
                    if unstable:
                        for pb in tr.phases:
                            if pb.phase.name in unstable:
                                ends[pb.phase.name] = segment_ends(pb, params, errors[pb.phase.name])
                        term = terminal_error(problem, ends, params)
                        term.flown = "each segment flown from its own start"
                        terminal_notes.append("terminal conditions judged with each segment flown from its own "
                                              "start, not the phase from x(t0): "
                                              + ", ".join(f"'{k}' amplifies a change of x(t0) by {a:.1e}"
                                                          for k, a in unstable.items())
                                              + f" (> {AMPLIFICATION:.0e})")
        allerr = [e for es in errors.values() for e in es]
        worst = max(allerr, key=lambda e: e.error) if allerr else None
        local_err = worst.error if worst else math.inf
        # the terminal conditions at the returned t_f (flown from x(t0), or piece by piece) count like a segment's error
        max_err = max(local_err, term.error)
        rec = {"iteration": it, "status": info.status, "objective": info.objective,
               "ipopt_iterations": info.iterations, "nlp": dict(info.nlp), "time_s": None,
               "warm_start": "multipliers" if mult is not None else ("primal" if it > 1 and not from_guess else "none"),
               "max_error": max_err, "terminal_error": term.error, "terminal_where": term.where,
               "terminal_flown": term.flown,
               "where": ({"phase": worst.phase, "segment": worst.segment, "t": [worst.t_start, worst.t_end],
                          "state": worst.state} if worst else None),
               "meshes": {k: m.describe() for k, m in meshes.items()},
               "final_times": free_final_times(tr) if info.status in GOOD else {}}
        if reg is not None:
            rec["regularisation"] = {"weight": reg_weight, "value": reg_value,
                                     "arcs": {k: [list(x) for x in v] for k, v in chatter.items()}}
        if spec.regularise and info.status in GOOD:
            for pb in tr.phases:
                chatter[pb.phase.name] = merge_intervals(chatter.get(pb.phase.name, []), chattering_segments(pb))
        if spec.junction_control == "limit" and info.status in GOOD:
            # a control collocated at the problem's first or last instant that jumps off its
            # segment's other nodes is one the end conditions do not price (free final
            # states): the NLP sets it at will and it bends the segment's states, which no
            # refinement cures (unseen29: psi(t_f) 3.71 after 0.927, 10 meshes, error 2e-6
            # in the last segment); from the next mesh on it is tied like a junction's. Only
            # where it jumps: tied at every outer end, four of eleven mesh files got worse
            for name, ends in jumping_ends(tr).items():
                tied_ends.setdefault(name, set()).update(ends)
            if tied_ends:
                rec["tied_end_controls"] = {k: sorted(v) for k, v in tied_ends.items()}
        history.append(rec)
        rows = len(tables["iteration"])
        for ph in problem.phases:
            m = meshes[ph.name]
            es = errors[ph.name]
            w = max(es, key=lambda e: e.error) if es else None
            tables["iteration"].append(it)
            tables["phase"].append(problem.phases.index(ph))
            tables["segments"].append(m.segments)
            tables["min_degree"].append(min(m.degrees))
            tables["max_degree"].append(max(m.degrees))
            tables["nlp_variables"].append(info.nlp.get("variables", 0))
            tables["nlp_constraints"].append(info.nlp.get("constraints", 0))
            tables["ipopt_iterations"].append(info.iterations)
            tables["objective"].append(info.objective if info.objective is not None else math.nan)
            tables["max_error"].append(max(w.error, term.error) if w else math.nan)
            tables["max_error_segment"].append(w.segment if w else -1)
            tables["max_error_t"].append(0.5 * (w.t_start + w.t_end) if w else math.nan)
            tables["time_s"].append(math.nan)
        if term.error > local_err:
            where = f"terminal condition {term.where} ({term.flown})"
        else:
            where = (f"{worst.phase}[{worst.segment}] t in [{worst.t_start:.6g}, {worst.t_end:.6g}] ({worst.state})"
                     if worst else "-")
        line = (f"mesh {it:2d}: {sum(m.segments for m in meshes.values()):3d} segments, "
                f"{info.nlp.get('variables', 0):5d} variables, Ipopt {info.status} in {info.iterations:4d} it, "
                f"J = {info.objective if info.objective is not None else float('nan'):.10g}, "
                f"max error {max_err:.2e} at {where}")
        try:
            last = (max_err, it, tr, info, dict(meshes), errors)
            if info.status not in GOOD:
                if coarsening and converged and info.status not in ("time_limit", "interrupted"):
                    # a coarsened mesh that does not solve is a coarsening that missed: the
                    # converged meshes stand (below)
                    rec["coarsening_rejected"] = True
                    break
                status = info.status
                message = (f"mesh iteration {it}: Ipopt ended with '{info.status}' ({info.message}); "
                           "mesh refinement stopped")
                break
            best_before = best
            # a mesh after a switch was moved supersedes the meshes that held it on the wrong
            # breakpoint, whatever their estimated errors (which do not see it)
            # and a mesh whose estimate is blind to a junction inside a segment (``inner_junctions``)
            # ranks after every mesh that is not (unseen28: mesh 7 of an obstacle, its exit inside
            # a segment, error 5.8e-9 and J 1.65e-4 high, was reported before meshes 9-10 that
            # held the exit, error 5.2e-8 and J right)
            if best is None or (_blind(errors), max_err) < (_blind(best[5]), best[0]) or best[1] < moved_at:
                best = last
            with timer.measure("mesh"):
                features = {}
                for pb in tr.phases:
                    try:
                        features[pb.phase.name] = locate_features(tr, pb, errors[pb.phase.name], params, spec,
                                                                  control_polys(pb),
                                                                  memory=junction_memory.setdefault(pb.phase.name, {}),
                                                                  budget=budget)
                    except Exception as exc:  # locating is an aid; the estimate still decides
                        # said as what it means for the run, the locator's own words in brackets
                        # (unseen16: a bare "f(a) and f(b) must have different signs" read as a failure)
                        say(progress, f"mesh {it}: no switch or corner located in phase {pb.phase.name} on this "
                                       f"mesh (the locator stopped: {exc}); the error estimate alone decides "
                                       "where to refine")
                        features[pb.phase.name] = []
                for name, times in (pinned or {}).items():
                    features[name] = sorted(set(features.get(name, [])) | set(times))
                # the bound-to-bound switches on their own (``refine`` moves a breakpoint near one onto it)
                bang = {}
                for pb in tr.phases:
                    try:
                        bang[pb.phase.name] = locate_switches(tr, pb, params, max(1e-6, 0.1 * spec.tolerance))
                    except Exception:   # an aid, as the locators
                        bang[pb.phase.name] = []
                free_shift = 0.0     # how far the free-time switch solve moved a breakpoint
                if spec.move_switches:
                    try:
                        # started from this mesh's solution, an aid capped as a warm start (unseen48
                        # F2: the reorientation's ran to 3,000 iterations, 32 s, for nothing)
                        free_options = {**options, "max_iter": min(multiplier_cap(info.iterations), int(
                            options.get("max_iter", ipopt.DEFAULT_OPTIONS["max_iter"])))}

                        def solve_free(t):
                            ws.prepare(t.model)
                            return ipopt.solve(t.model, free_options, transcription=t)

                        def rebuild_here(ms, tr=tr, **kw):
                            """This iteration's build on ``ms``, started from ``tr``'s solution."""
                            return rebuild(ms, guesses=solved_guesses(problem, tr), **kw)

                        features, moved = solve_switch_times(tr, rebuild_here, solve_free, features, bang, spec,
                                                             info.objective if info.objective is not None else 0.0)
                        free_shift = _largest_move(moved, meshes)
                        meshes.update(moved)
                    except Exception as exc:  # an aid, as the locators
                        say(progress, f"mesh {it}: moving switches failed: {exc}")
            if free_shift > spec.corner_tolerance and max_err <= spec.tolerance and it < spec.max_iterations:
                # the switch-time solve moved a switch this mesh held on a breakpoint: its J and
                # t_f are those of the pinned switch, not a converged answer (unseen38 F1: fuel +
                # time, free t_f, switch pinned 1.3e-4 late, within tolerance at every estimate,
                # J 1.1e-7 off, t_f 3.2e-4 off, `optimal`); the moved mesh is solved next and
                # the meshes from it on are the candidates, as for fixed times below
                best, moved_at = best_before, it + 1
                rec["switches_moved"] = {k: [float(b) for b in m.breakpoints] for k, m in moved.items()}
                rec["features"] = features
                previous = {pb.phase.name: dense_trajectory(pb) for pb in tr.phases}
                snapshot = ws.take(tr) if spec.warm_start == "multipliers" else None
                continue
            off = {k: misplaced(meshes[k], f, spec) for k, f in features.items()}
            if max_err <= spec.tolerance and not any(off.values()) and spec.move_switches \
                    and any(bang.get(pb.phase.name) for pb in tr.phases):
                # a mesh within tolerance whose fixed-time phases hold a switch on a breakpoint:
                # would J move with it (the envelope gradient)? Then the switch is solved for as
                # for free times, and the mesh that puts it there is solved next, not this one
                # called converged (unseen13 F1: x' = u x, maximise int (1 - u) x, the switch
                # pinned at t = 1.978 for 2, J 2.3e-4 low, verified, certificate pass)
                try:
                    with timer.measure("mesh"):
                        features, moved = solve_switch_times(tr, rebuild_here, solve_free, features, bang, spec,
                                                             info.objective if info.objective is not None else 0.0,
                                                             times="fixed")
                except Exception as exc:  # an aid: the estimate and the locators stand
                    say(progress, f"mesh {it}: moving fixed-time switches failed: {exc}")
                    moved = {}
                if _largest_move(moved, meshes) <= spec.corner_tolerance:
                    moved = {}           # the switches are where the NLP puts them: nothing to move
                if moved:
                    # this mesh's J (and that of earlier meshes with the switch there) is known to
                    # improve by moving its switch: the meshes from the moved one on are the candidates
                    best, moved_at = best_before, it + 1
                    pinned = {k: [float(b) for b in meshes[k].breakpoints
                                  if min((abs(b - f) for f in features.get(k, [])), default=1.0) > spec.corner_tolerance
                                  and b not in m.breakpoints] for k, m in moved.items()}
                    rec["switches_moved"] = {k: [float(b) for b in m.breakpoints] for k, m in moved.items()}
                    rec["switches_pinned"] = pinned
                    off = {k: misplaced(moved.get(k, meshes[k]), f, spec) for k, f in features.items()}
                    if it == spec.max_iterations:
                        off = {k: features.get(k, []) for k in moved}      # not converged: where they go
                    else:
                        rec["features"] = features
                        rec["features_off_breakpoints"] = off
                        previous = {pb.phase.name: dense_trajectory(pb) for pb in tr.phases}
                        snapshot = ws.take(tr) if spec.warm_start == "multipliers" else None
                        meshes = {**meshes, **moved}
                        continue
            located = features
            rec["features"] = features
            rec["features_off_breakpoints"] = off
            inner = {k: [e.segment for e in errors[k] if e.inner_junction] for k in errors}
            if any(inner.values()):
                rec["inner_junctions"] = inner
            if max_err <= spec.tolerance and not any(off.values()) and not any(inner.values()):
                converged.append(last)
                rec["converged"] = True
                smaller = None
                if spec.coarsen and it < spec.max_iterations:
                    with timer.measure("mesh"):
                        cand = {pb.phase.name: coarsen(pb, errors[pb.phase.name], spec, features[pb.phase.name],
                                                       budget)
                                for pb in tr.phases}
                    size = lambda ms: sum(nlp_size(ms[pb.phase.name], len(pb.phase.states),  # noqa: E731
                                                    len(pb.phase.controls)) for pb in tr.phases)
                    # a coarsening that was tried and missed the tolerance is not tried again (the
                    # bang-off-bang arc mesh (2, 1, 2) missed it, was refined back to 9 segments,
                    # coarsened to (2, 1, 2) again, ... to max_iterations)
                    # a phase left with one collocation node has no certificate (its conditions
                    # need two) and hides what a node would show (unseen14: x' = u x on [0, 1.02],
                    # LG coarsened to one degree-1 node, the arc u = 1 on [0, 0.02] lost, J 2e-4
                    # low, optimal with the certificate skipped)
                    if all(Layout.of(cand[k]).n_colloc >= 2 for k in cand) \
                            and size(cand) <= COARSEN_GAIN * size(meshes) and not any(
                            all(close_mesh(cand[k], r[k], spec.corner_tolerance) for k in cand) for r in tried):
                        smaller = cand
                        tried.append(cand)
                if smaller is None:
                    break
                coarsening = True
                previous = {pb.phase.name: dense_trajectory(pb) for pb in tr.phases}
                snapshot = ws.take(tr) if spec.warm_start == "multipliers" else None
                meshes = smaller
                continue
            # this mesh is the one before, solved again (breakpoints nudged by less than
            # corner_tolerance), and its error fell by less than a tenth
            solved_again = solved_before is not None and max_err >= 0.9 * solved_before[1] and all(
                close_mesh(meshes[k], solved_before[0][k], spec.corner_tolerance) for k in meshes)
            if coarsening:
                # the coarsened mesh missed the tolerance: refine it like any other mesh (the
                # smallest converged mesh so far is kept for the end)
                rec["coarsening_rejected"] = True
                coarsening = False
                if info.iterations > (mcap or 0) and _left_the_optimum(info.objective, converged[-1][3].objective,
                                                                       spec.tolerance, file.problem.objective_constant):
                    # ... unless its warm start did not take and it solved to another optimum:
                    # refining that one only finds its way back (unseen48 F2, with the
                    # multiplier cap: the reorientation converged on mesh 4 at J 28.6304068;
                    # its coarsened mesh took 3,789 iterations to 28.657, and the meshes refined
                    # from it ended `mesh_not_converged` after 94 s)
                    rec["coarsening_left_the_optimum"] = True
                    break
            elif solved_again and not (nudge_grace and any(memory.get("last") for memory in nudged.values())):
                # the mesh solved again (breakpoints nudged by less than corner_tolerance) and
                # its error fell by less than a tenth: refining on would repeat it (a rejected coarse mesh
                # was re-solved in 0 Ipopt iterations to max_iterations; unseen5, planar
                # minimum fuel). A nudge that does help (a breakpoint onto a switch) goes on, and
                # the first one that did not too: the segments it held are refined now (unseen36
                # F3: a switch 1.6e-12 off its breakpoint moved onto, the segments beside it 4.5e-2
                # off, the loop ended at iteration 2 of 15 with t_f 6.99312 for 7); nudges that
                # repeat (unseen5) stop it on the next solve again
                stalled = (f"mesh iteration {it}: the mesh of iteration {it - 1} solved again (no breakpoint "
                           f"moved by more than corner_tolerance {spec.corner_tolerance:g}) with no fall in "
                           f"its largest error ({solved_before[1]:.3e} -> {max_err:.3e})")
                rec["stalled"] = stalled
                break
            elif solved_again:
                nudge_grace = False
            solved_before = (dict(meshes), max_err)
            growth.append((int(info.nlp.get("variables", 0)), max_err))
            reg_term = (rec.get("regularisation") or {}).get("value")
            grown = _not_converging(growth, None if reg_term is None or not info.objective else
                                    (reg_weight, abs(float(reg_term)) / max(abs(float(info.objective)), 1e-300)))
            if grown:
                stalled = f"mesh iteration {it}: the refinement is not converging: {grown}"
                rec["stalled"] = stalled
                break
            if it == spec.max_iterations:
                break
            previous = {pb.phase.name: dense_trajectory(pb) for pb in tr.phases}
            snapshot = ws.take(tr) if spec.warm_start == "multipliers" else None
            if guess_restarts < GUESS_RESTARTS and exploits_quadrature(tr, term, worst, max_err):
                # a control zigzagging from node to node where an integral's quadrature is what
                # misses most: the NLP exploits the quadrature (sqrt(1 + u^2) "shortened" by a
                # zigzag), and a next mesh started from that point found the same kind of
                # optimum (the hanging chain: 4.94, 4.95, 4.83, 4.79 for 5.068 on meshes 1-4,
                # then 753 Ipopt iterations to leave it). It starts from this mesh's states and
                # the file's controls: the states keep the side of an obstacle it passed on
                # (unseen27 FC1: a perturbed start passed on the short side, J 4.4203 on mesh 1;
                # the next mesh, started from the file's guess, passed on the long side:
                # 4.5442, optimal), the zigzagging controls go
                previous = {k: dataclasses.replace(v, controls={}) for k, v in previous.items()}
                snapshot = None
                guess_restarts += 1
                rec["next_mesh_from_guess"] = ("the control zigzags where an integral's quadrature misses: this mesh's "
                                               "states, the guess's controls")
            try:
                # terminal conditions missed while every segment meets the tolerance: the segment
                # errors add up (or are amplified) over the phase, so the segments are held to
                # the tolerance scaled by local / terminal error
                spec_r = spec if term.error <= spec.tolerance else spec.model_copy(
                    update={"tolerance": spec.tolerance * min(1.0, local_err / term.error)})
                with timer.measure("mesh"):
                    new_meshes = {pb.phase.name: refine(meshes[pb.phase.name], errors[pb.phase.name], spec_r,
                                                        features=features[pb.phase.name],
                                                        switches=bang.get(pb.phase.name, []),
                                                        nudged=nudged.setdefault(pb.phase.name, {}))
                                  for pb in tr.phases}
            except MeshStalled as exc:
                stalled = f"mesh iteration {it}: refinement stalled: {exc}"
                rec["stalled"] = str(exc)
                break
            if all(same_mesh(new_meshes[k], meshes[k]) for k in meshes):
                # refine() changes every phase that misses the tolerance; this is a last guard
                stalled = (f"mesh iteration {it}: refinement returned the same mesh while the tolerance "
                           f"{spec.tolerance:.1e} is unmet (largest error {max_err:.3e})")
                rec["stalled"] = stalled
                break
            meshes = new_meshes
        finally:
            # the iteration's time covers its build, solve, estimate, location and refinement
            elapsed = round(time.perf_counter() - t_iter, 4)
            rec["time_s"] = elapsed
            for r in range(rows, len(tables["time_s"])):
                tables["time_s"][r] = elapsed
            stage.update(it, f"{line}, {elapsed:.2f} s")
            for note in budget.notes[noted:]:
                say(progress, f"mesh {it}: {note}")
            rec["symbolic_notes"] = budget.notes[noted:]
            noted = len(budget.notes)
    status, chosen, message, disagree, stalled = outcome(converged, best, last, history, status, message,
                                                         stalled, spec, problem)
    max_err, it_c, tr_c, info_c, meshes_c, errors_c = chosen
    confirmed = confirm(file, chosen, status, message, converged=converged, history=history, timer=timer,
                        options=options, rebuild=rebuild, verbose=verbose, progress=progress)
    status, message, tr_c, info_c, meshes_c = (confirmed.status, confirmed.message, confirmed.tr,
                                               confirmed.info, confirmed.meshes)
    notes += confirmed.notes
    with timer.measure("post"):
        result = _result(file, tr_c, info_c, timer, meshes_c, always_fly=bool(disagree))
    if status == "mesh_not_converged" and disagree:
        beaten = beaten_meshes(result, converged, problem.objective.sense, spec.tolerance)
        kept = [c for c in converged if c[1] not in beaten]
        if (beaten and len(kept) >= 2 and any(c is chosen for c in kept)
                and _objective_disagreement(kept, spec.tolerance, file.problem.objective_constant) is None):
            status = "optimal"
            message = (f"mesh converged: iterations {[c[1] for c in kept]} are within tolerance {spec.tolerance:.1e} "
                       f"and agree in J; iteration(s) {beaten}, also within it, are no optimum: the control the "
                       f"minimum principle flies along iteration {it_c}'s solution beats their J (J = "
                       f"{result.certificate['flown_control']['flown']:.10g}; their estimates missed a corner or a switch)")
    corners = refuted_corners(result, spec.tolerance) if pinned is None and status == "optimal" else {}
    if corners:
        say(progress, announce_again(result, corners, info_c.objective))
        again = solve_adaptive(file, timer, seed=seed, verbose=verbose, progress=progress, pinned=corners,
                               first={k: with_breakpoints(m, corners.get(k, []), spec.corner_tolerance)
                                      for k, m in meshes_c.items()},
                               start={ph.name: ph for ph in result.phases})
        unfounded = second_pass_no_better(result, again, problem.objective.sense, spec.tolerance)
        if not unfounded:
            return refined_again(again, result, corners, history, tables, it_c)
        notes.append(unfounded)
        second_pass_recorded(again, history, tables)
    result.status = status
    # one starting mesh in the record (both pairs were echoed, the unused one as defaults: unseen6)
    for key in ("segments", "degree"):
        result.method["mesh"].pop(key, None)
    result.method.update(starting_mesh(file.method))
    hints = failure_hints(file, tr_c, status)
    if status == "mesh_not_converged":
        hints += _undetermined_controls(result.certificate)
        if minimum_condition_notes(result.certificate):
            # more of the same cannot leave a local extremal (unseen48 F3: Newton's nose at 25
            # iterations had the J of 12)
            extremal = ("The control is not H's minimiser where the note below says: the refinement follows a "
                        "local extremal, which more iterations or a higher degree do not change; start from a guess "
                        "with the better control there.")
            message = (message.replace(RAISE_ADVICE, extremal) if RAISE_ADVICE in message
                       else f"{message.rstrip('.')}. {extremal}")
    result.message = ((f"{message.rstrip('.')}.{hints}" if hints else message)
                      + (f"; symbolic steps: {'; '.join(dict.fromkeys(budget.notes))}" if budget.notes else "")
                      + (f"; {terminal_notes[-1]}" if terminal_notes else ""))
    result.iterations = sum(h["ipopt_iterations"] for h in history)
    record(result, problem, spec, status, history, tables, errors_c, max_err, it_c, info_c, budget.notes,
           confirmed, notes, start_records)
    runaway_final_time(file, result, tr_c, meshes_c, timer, verbose=verbose, progress=progress)
    result.wall_time_s = timer.breakdown()
    stage.close(f"{len(history)} meshes, max error {max_err:.2e}")
    return result


def _undetermined_controls(cert) -> str:
    """A refinement that did not converge where a control's switching function is zero to the
    NLP's precision (the certificate's ``unresolved``): the objective does not determine that
    control, the solver's choice of it is arbitrary, and the estimate chases it (unseen36 F4:
    two axes, minimum time set by one, the other's control free; 15 meshes, t_f right to 7e-10,
    verified, `mesh_not_converged`). Said, as more iterations cannot help."""
    if not isinstance(cert, dict):
        return ""
    per_phase = cert["phases"].items() if isinstance(cert.get("phases"), dict) else [("", cert)]
    free = [f"{name}{f' (phase {ph})' if ph else ''}" for ph, c in per_phase
            for name, rec in (((c or {}).get("stationarity") or {}).get("per_control") or {}).items()
            if isinstance(rec, dict) and rec.get("unresolved")]
    if not free:
        return ""
    return (f" The objective does not determine {', '.join(free)} (its switching function is zero to the NLP's "
            "precision): any control that meets the conditions is optimal, the solver's choice of it is arbitrary "
            "and the error estimate follows it, which more iterations do not cure; J and the verification "
            "judge the answer, or a small cost of that control in the objective (`+ 1e-6*integral(u**2)`) "
            "makes it unique")


def _largest_move(moved: dict, meshes: dict) -> float:
    """How far (normalised time) the breakpoints of ``moved`` lie from those of ``meshes``,
    phase by phase (0 where a phase's segment count changed: that is a new mesh, not a move)."""
    return max((float(np.max(np.abs(np.asarray(m.breakpoints) - np.asarray(meshes[k].breakpoints))))
                for k, m in moved.items() if len(m.breakpoints) == len(meshes[k].breakpoints)), default=0.0)


#: a coarsened mesh whose J differs from the converged mesh's by more than this many
#: tolerances (relative to |J|, at least 1) solved to another optimum
LEFT_THE_OPTIMUM = 100


def _left_the_optimum(objective, converged_objective, tolerance: float, constant: float = 0.0) -> bool:
    """``constant``: J's constant part (verify/objective_size.py), not J's size."""
    if objective is None or converged_objective is None:
        return False
    size = max(1.0, own_size(converged_objective, constant))
    return abs(objective - converged_objective) > LEFT_THE_OPTIMUM * tolerance * size


def _not_converging(growth: list, regularised: tuple[float, float] | None = None) -> str:
    """Why refining on only grows the NLP, from (variables, largest error) of each refined mesh,
    or "": two refinements that multiplied it by GROWTH_LIMIT while the error fell by less than
    ten times (unseen10 F2: a bioreactor's singular feed arcs, 10 -> 813 segments and 15,600
    variables, error 2.2e-1 -> 2.2e-2, no result in 150 s), or FLAT_MESHES that grew it by
    FLAT_GROWTH with no tenth off the error; both only past GROWTH_FLOOR variables.
    ``regularised``: (the weight, its term's share of J) where `regularise` is on: the advice
    then says how strong it is rather than naming a key the file has (unseen61 F2: Goddard in
    metres, w = 1e-8 a term of 2e-9 of J against 2e-7 in Earth radii)."""
    advice = "(a singular arc or a chattering control? `regularise:` in mesh:, docs/mesh.md)"
    if regularised is not None:
        weight, share = regularised
        advice = (f"(a singular arc or a chattering control? `regularise: {weight:g}` is on, its term {share:.1e} "
                  "of J: the weight is in J's units, so a J in other units needs it scaled alike; docs/mesh.md)")
    if len(growth) >= 3 and growth[-1][0] >= max(GROWTH_LIMIT * growth[-3][0], GROWTH_FLOOR) \
            and growth[-1][1] > 0.1 * growth[-3][1]:
        return (f"the NLP grew from {growth[-3][0]} to {growth[-1][0]} variables in two meshes while the largest "
                f"error fell only from {growth[-3][1]:.3e} to {growth[-1][1]:.3e} {advice}")
    past = growth[-1 - FLAT_MESHES] if len(growth) > FLAT_MESHES else None
    if past and growth[-1][0] >= max(FLAT_GROWTH * past[0], GROWTH_FLOOR) and growth[-1][1] > 0.9 * past[1]:
        return (f"the NLP grew from {past[0]} to {growth[-1][0]} variables in {FLAT_MESHES} meshes while the "
                f"largest error stayed at {growth[-1][1]:.3e} (was {past[1]:.3e}; {advice[1:]}")
    return ""
