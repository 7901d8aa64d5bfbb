"""Execute a compiled problem file with the back end its ``method:`` names."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sympy as sp

from .result import Result
from .spec.compile import LoadedFile
from .fixed_mesh import fixed_mesh_arcs, tie_jumping_end_controls
from .runaway import runaway_final_time
from .spec.schema import PseudospectralMethod


def execute(file: LoadedFile, timer, *, seed: int | None = None, warm_start: str | Path | None = None,
            verbose: bool = False, progress: bool = False) -> Result:
    method = file.method
    if isinstance(method, PseudospectralMethod):
        if method.mesh is not None:
            from .solve.mesh import solve_adaptive

            return solve_adaptive(file, timer, seed=seed, warm_start=warm_start, verbose=verbose,
                                  progress=progress)
        return solve_pseudospectral(file, timer, seed=seed, warm_start=warm_start, verbose=verbose,
                                    progress=progress)
    from .methods import runner

    return runner(method.transcription)(file, timer, seed=seed, warm_start=warm_start, verbose=verbose,
                                        progress=progress)


def _better(info, best, sense: str) -> bool:
    good = ("optimal", "acceptable")
    if best is None:
        return True
    if info.status in good and best.status not in good:
        return True
    if info.status not in good or best.status not in good or info.objective is None:
        return False
    return info.objective < best.objective if sense == "minimize" else info.objective > best.objective


def _start_record(start: int, seed, info) -> dict:
    """One row of ``result.extra['starts']``."""
    return {"start": start, "seed": seed, "status": info.status, "objective": info.objective,
            "iterations": info.iterations, "solve_time_s": round(info.solve_time, 4)}


def previous_phases(file: LoadedFile, warm_start=None) -> dict:
    """Phase name -> the PhaseTrajectory a phase's guess starts from: the ``warm_start`` run
    folder, else ``guess: {from: RUN_DIR}`` in the file (relative to the file), phase by phase."""
    previous = {}
    if warm_start is not None:
        return {p.name: p for p in Result.read(warm_start).phases}
    for ph in file.problem.phases:
        source = ph.guess.get("from")
        if source:
            folder = (file.path.parent / source) if not Path(source).is_absolute() else Path(source)
            prev = {p.name: p for p in Result.read(folder).phases}
            if ph.name in prev:
                previous[ph.name] = prev[ph.name]
            elif len(prev) == 1:
                previous[ph.name] = next(iter(prev.values()))
    return previous


def start_notes(file: LoadedFile, previous: dict) -> list[str]:
    """What the run's start did not take as written: a warm start's mismatches, guesses
    outside their bounds."""
    from .transcribe.guess import guess_notes

    return warm_start_notes(file, previous) + guess_notes(file.problem) + unused_control_notes(file.problem)


def unused_control_notes(problem) -> list[str]:
    """Controls that nothing depends on (no dynamics, path constraint, integral or boundary
    value): any of their values is optimal, so the run's are arbitrary; said, not silent
    (unseen40 F5: `controls: [u, w]` with w used nowhere, 50 NLP variables of noise)."""
    used_at_ends = {bv.var for bv in problem.boundary_values.values()}
    notes = []
    for ph in problem.phases:
        exprs = list(ph.rhs()) + [c.expr for c in ph.path] + list(ph.integrals.values())
        used = set().union(*(ph.substitute(e).free_symbols for e in exprs)) if exprs else set()
        idle = [c.name for c in ph.controls if c not in used and c not in used_at_ends]
        if idle:
            where = f"phase '{ph.name}': " if len(problem.phases) > 1 else ""
            notes.append(f"{where}control{'s' if len(idle) > 1 else ''} {', '.join(idle)} "
                         f"{'appear' if len(idle) > 1 else 'appears'} in no dynamics, path constraint, integral "
                         f"or boundary condition: any value is optimal, so the run's are arbitrary (remove "
                         f"{'them' if len(idle) > 1 else 'it'} from `controls:`)")
    return notes


def warm_start_notes(file: LoadedFile, previous: dict) -> list[str]:
    """What a warm start (``--warm-start`` or ``guess: {from:}``) did not match: a phase it has
    no trajectory for, states or controls it lacks (they keep the file's guess) or has that this
    problem does not (an unrelated run, probably): said, never silent."""
    if not previous:
        return []
    notes = []
    for ph in file.problem.phases:
        prev = previous.get(ph.name)
        if prev is None:
            notes.append(f"the warm start has no trajectory of phase '{ph.name}': it keeps the file's guess")
            continue
        names = [v.name for v in ph.states + ph.controls]
        given = [*prev.states, *prev.controls]
        missing = [n for n in names if n not in given]
        foreign = [n for n in given if n not in names]
        if missing or foreign:
            where = f"phase '{ph.name}': " if len(file.problem.phases) > 1 else ""
            parts = []
            if missing:
                parts.append(f"it has no {', '.join(missing)} (kept at the file's guess)")
            if foreign:
                parts.append(f"its {', '.join(foreign)} are not in this problem (a run of another problem?)")
            notes.append(f"{where}warm start: " + "; ".join(parts))
    return notes


def solve_built(file: LoadedFile, tr, meshes, timer, *, verbose=False, progress=False) -> Result:
    """Solve an already built (and started) transcription once and make its Result (the
    reused-model path of a study point, ocdsl/solve/reuse.py)."""
    from .solve import ipopt

    with timer.measure("solve"):
        info = ipopt.solve(tr.model, file.spec.solver.options, verbose=verbose, transcription=tr,
                           progress=ipopt.Progress(progress, ""))
    with timer.measure("post"):
        result = _result(file, tr, info, timer, meshes)
        result.extra["starts"] = [_start_record(0, None, info)]
    notes = fixed_mesh_arcs(file, result, tr, meshes, timer, verbose=verbose, progress=progress)
    if notes:
        result.extra["notes"] = notes
    result.wall_time_s = timer.breakdown()
    return result


def solve_pseudospectral(file: LoadedFile, timer, *, seed=None, warm_start=None, verbose=False,
                         progress=False, meshes=None) -> Result:
    from .startup import loading

    with loading("pseudospectral"):     # Pyomo, cyipopt: the rest of a run's start-up (startup.py)
        from .solve import ipopt
        from .solve.reuse import SolvedState, restart
        from .transcribe.guess import start_guesses
        from .transcribe.mesh import Mesh
        from .transcribe.pseudospectral import build

        ipopt.check_available()
    problem, method = file.problem, file.method
    meshes = meshes or {ph.name: Mesh.uniform(method.transcription, method.segments, method.degree)
                        for ph in problem.phases}
    previous = previous_phases(file, warm_start)
    starts = method.starts
    best = best_tr = tr = saved = None
    records = []
    # several starts solve one model, each from the values a fresh build would give it
    # (solve/reuse.py restart), so the model and its NLP structure are made once; automatic
    # scaling is computed from each start's guess, so it keeps a build per start
    one_model = starts > 1 and file.spec.scaling.mode != "auto"
    base = method.seed if seed is None else seed
    for i in range(starts):
        # start 0 is the single start (seed: the run's, None without --seed); start i >= 1 a
        # perturbed copy drawn from base + i (transcribe/guess.py start_guesses)
        s = seed if i == 0 else base + i
        with timer.measure("build"):
            guesses = start_guesses(problem, previous, i, seed, base)
            if tr is not None and one_model:
                restart(tr, guesses, problem)
            else:
                tr = build(problem, meshes, guesses)
                scaled = _scale(file, tr)
        with timer.measure("solve"):
            bar = ipopt.Progress(progress, f"[{i + 1}/{starts}]" if starts > 1 else "")
            info = ipopt.solve(tr.model, file.spec.solver.options, verbose=verbose, progress=bar,
                               transcription=tr)
        records.append(_start_record(i, s, info))
        if _better(info, best, problem.objective.sense):
            best, best_tr = info, tr
            saved = SolvedState(tr.model) if one_model and i < starts - 1 else None
    if saved is not None:
        with timer.measure("build"):
            saved.restore()       # the best start's solution back in the shared model
    if best.status == "infeasible":
        recovered = recover_from_infeasibility(file, meshes, previous, timer, seed=seed, options=file.spec.solver.options,
                                               info=best, tr=best_tr, verbose=verbose, progress=progress)
        best, best_tr = recovered.info, recovered.tr
        records += recovered.records
        if recovered.scaled is not None:
            scaled = recovered.scaled
    best, best_tr, tied = tie_jumping_end_controls(file, best, best_tr, meshes, timer, verbose=verbose)
    with timer.measure("post"):
        result = _result(file, best_tr, best, timer, meshes)
        result.extra["starts"] = records
        notes = start_notes(file, previous) + tied
    runaway_final_time(file, result, best_tr, meshes, timer, verbose=verbose, progress=progress)
    notes += fixed_mesh_arcs(file, result, best_tr, meshes, timer, verbose=verbose, progress=progress)
    if notes:
        result.extra["notes"] = notes
    if scaled:
        result.extra["scaling"] = scaled
    result.wall_time_s = timer.breakdown()
    return result


@dataclass
class Recovered:
    """What ``recover_from_infeasibility`` leaves: the solve to report and its transcription,
    the records of the starts it added, the guesses of the start that succeeded (None when
    none did) and its scaling."""
    info: object
    tr: object
    records: list
    guesses: dict | None = None
    scaled: dict | None = None


def recover_from_infeasibility(file: LoadedFile, meshes, previous, timer, *, seed, options, info, tr,
                               verbose=False, progress=False, build_model=None) -> Recovered:
    """A solve that ended locally infeasible: one more start from seeded random controls
    (seed ``base + N``, the seed a start N + 1 would draw from, but always random controls:
    they break the degeneracy of controls at 0; not where a previous run gives every phase its
    guess), and if that ends infeasible too, the elastic diagnosis names the conditions that
    cannot hold together (solve/diagnose.py) in the message. Used by the single solve and by
    the first mesh of an adaptive one (``build_model(guesses)``: its own build of that mesh)."""
    from .solve import ipopt
    from .transcribe.guess import flown_guess, make_guess
    from .transcribe.pseudospectral import build

    problem, method = file.problem, file.method
    starts = method.starts
    base = method.seed if seed is None else seed
    guesses = {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=seed) for ph in problem.phases}
    starts_tried = [guesses]
    tried = "the guess" if starts == 1 else f"{starts} starts"
    out = Recovered(info, tr, [])

    def solve_from(start: dict, label: str):
        """(transcription, SolveInfo, scaling) of the problem built from ``start`` and solved."""
        with timer.measure("diagnose"):
            if build_model is None:
                t = build(problem, meshes, start)
                scaled = _scale(file, t)
            else:
                t, scaled = build_model(start), None
            return t, ipopt.solve(t.model, options, verbose=verbose, progress=ipopt.Progress(progress, label),
                                  transcription=t), scaled

    flown = {ph.name: flown_guess(problem, ph, guesses[ph.name]) if ph.name not in previous else None
             for ph in problem.phases}
    if any(g is not None for g in flown.values()):
        # the guessed controls flown from x(t0) give states that meet the dynamics: a start the
        # file's constant state guess was not (unseen57 F1)
        flown_guesses = {k: g if g is not None else guesses[k] for k, g in flown.items()}
        ftr, finfo, fscaled = solve_from(flown_guesses, "[from the flown guess]")
        out.records.append({**_start_record(len(out.records) + starts, None, finfo), "flown_guess": True})
        tried += " and from the guessed controls flown from x(t0)"
        starts_tried.append(flown_guesses)
        if finfo.status in ("optimal", "acceptable"):
            finfo.message += (" (Solved from the guessed controls flown from x(t0): from the file's state guess, "
                              "which does not meet the dynamics, Ipopt had converged to a point of local "
                              "infeasibility.)")
            return Recovered(finfo, ftr, out.records, flown_guesses, fscaled)
    if any(ph.name not in previous for ph in problem.phases):
        # a point of local infeasibility is a fact about one start (a guess with the controls
        # at 0 makes z' = x u2 - y u1 degenerate): before diagnosing, one more start from
        # seeded random controls
        rs = base + starts
        retry_guesses = {ph.name: make_guess(problem, ph, previous.get(ph.name), seed=rs) for ph in problem.phases}
        rtr, rinfo, rscaled = solve_from(retry_guesses, "[retry]")
        out.records.append({**_start_record(starts, rs, rinfo), "retry": True})
        tried += f" and from seeded random controls (seed {rs})"
        starts_tried.append(retry_guesses)
        if rinfo.status in ("optimal", "acceptable"):
            rinfo.message += (f" (Solved from seeded random controls, seed {rs}: from {tried.split(' and ')[0]} "
                              "Ipopt had converged to a point of local infeasibility.)")
            return Recovered(rinfo, rtr, out.records, retry_guesses, rscaled)
    from .solve.diagnose import copy_values, elastic

    with timer.measure("diagnose"):
        named = elastic(problem, meshes, starts_tried, file.spec.solver.options, tried=tried, n_starts=starts)
    # names the conditions themselves, not the rows Ipopt stopped on
    info.message = named.message.strip() + " (Ipopt: " + info.message.split(" Constraints that Ipopt")[0] + ")"
    if named.feasible is not None:
        # the relaxed solve met every condition: a feasible point of the problem itself
        # (phase 1 of a two-phase method); the problem is solved once more from it
        with timer.measure("diagnose"):
            ftr = build(problem, meshes, guesses) if build_model is None else build_model(guesses)
            try:
                copy_values(named.feasible, ftr.model)
            except ValueError:      # another structure: the diagnosis stands as it is
                return out
            fscaled = _scale(file, ftr) if build_model is None else None
            finfo = ipopt.solve(ftr.model, options, verbose=verbose,
                                progress=ipopt.Progress(progress, "[from the feasible point]"), transcription=ftr)
        out.records.append({**_start_record(len(out.records) + starts, None, finfo), "from_feasible_point": True})
        if finfo.status in ("optimal", "acceptable"):
            finfo.message += (f" (Solved from a feasible point: from {tried} Ipopt had converged to a point of "
                              "local infeasibility; with the boundary conditions and links relaxed to penalties "
                              "Ipopt found a point that meets them all, and the problem was solved from it.)")
            from .transcribe.guess import solved_guesses

            # what later meshes' trial models start from
            return Recovered(finfo, ftr, out.records, solved_guesses(problem, ftr), fscaled)
    return out


def _scale(file: LoadedFile, tr) -> dict | None:
    """``scaling: {mode: auto}``: the typical magnitudes put on the model (solve/scaling.py)."""
    spec = file.spec.scaling
    if spec.mode != "auto":
        from .solve.scaling import spread

        tr.start_spread = spread(tr)       # for the hint of a failed solve (solve/failure_hints.py)
        return None
    from .solve.scaling import apply, sizeless, spread

    # at the start, before Ipopt moves them: what auto scaling found no size for, and the spread
    tr.start_spread, tr.start_sizeless = spread(tr), sizeless(tr, dict(spec.variables))
    return apply(tr, spec)


def bare_result(file: LoadedFile, tr, info, meshes) -> tuple[Result, dict]:
    """The solution in ``tr`` as a Result (rows, final times, parameters, objective), and the
    values of the transcription's scalars: what the verification reads."""
    import pyomo.core as pyo

    from .transcribe.solution import extract

    problem = file.problem
    values = {s: _value(v) for s, v in tr.scalars.items()}
    tf = {ph.name: float(pyo.value(pb.block.tf)) for ph, pb in zip(problem.phases, tr.phases)}
    return Result(
        name=file.spec.name, status=info.status, message=info.message, objective=info.objective,
        tf=tf["main"] if len(tf) == 1 and "main" in tf else tf,
        iterations=info.iterations, nlp=info.nlp,
        method={**file.method.model_dump(), "meshes": {k: m.describe() for k, m in meshes.items()}},
        parameters={**file.parameters, **{s.name: values[s] for s in problem.free_parameters}},
        phases=extract(tr), problem=problem.description), values


def _result(file: LoadedFile, tr, info, timer, meshes, *, always_fly: bool = False) -> Result:
    from .solve.costates import costates, path_multipliers
    from .solve.failure_hints import failure_hints

    problem = file.problem
    result, values = bare_result(file, tr, info, meshes)
    texts = {}
    if info.status in ("optimal", "acceptable"):
        for traj, lam, mu, ph in zip(result.phases, costates(tr), path_multipliers(tr), problem.phases):
            traj.costates = lam
            traj.extra.update(mu)       # mu_<k>: multiplier of phase.path[k] (costates.py)
            if mu:
                texts[ph.name] = {f"mu_{k}": c.text for k, c in enumerate(ph.path)}
    result.message += failure_hints(file, tr, info.status)
    if problem.free_parameters:
        result.extra["free_parameters"] = [s.name for s in problem.free_parameters]
    result.extra["ipopt_history"] = [list(h) for h in info.history[-200:]]
    if texts:
        result.extra["path_multipliers"] = texts     # phase -> {mu_<k>: constraint text}
    if info.status in ("optimal", "acceptable"):
        result.extra["boundary_multipliers"] = boundary_multipliers(tr)
    result.expect = check_expectations(file, values, info.objective)
    _certify(file, result, always_fly)
    return result


def _value(v) -> float:
    """A scalar's value, NaN where it has none (an integral of log(x - 2.5) at a guess with
    x = 0, a run that stopped at the guess): never a raw "math domain error" from Pyomo."""
    import pyomo.core as pyo

    from .pyomo_logs import evaluation_unlogged

    with evaluation_unlogged():
        try:
            return float(pyo.value(v))
        except (ValueError, ArithmeticError, TypeError):
            return math.nan


def boundary_multipliers(tr) -> list[dict]:
    """The NLP multiplier of every boundary constraint that is a row of the NLP (not a
    variable bound), with its index in ``problem.boundary``, in the convention of the
    costates (Lagrangian ``J + nu c`` of the minimisation form): the certificate adds
    ``nu dc/ds`` to the weight of integral s's integrand in L (ocdsl/solve/certify.py)."""
    m = tr.model
    index = {id(c): i for i, c in enumerate(tr.problem.boundary)}
    out = []
    for row, c in enumerate(tr.boundary_general):
        nu = m.dual.get(m.boundary[row + 1])
        out.append({"index": index.get(id(c)), "text": c.text,
                    "multiplier": None if nu is None else float(nu)})
    return out


def _certify(file: LoadedFile, result: Result, always_fly: bool = False) -> None:
    """Attach the optimality certificate when the module is available and the solve converged
    (``always_fly``: the flown control's J wanted whatever gain it predicts, mesh/drive.py; the
    flights' step budget follows the last solve's size, ``flight_budget``)."""
    if result.status not in ("optimal", "acceptable"):
        return
    from .solve.certificate.flown_control import flight_budget
    from .solve.certify import certify_result

    try:
        mesh = getattr(file.method, "mesh", None)
        result.certificate = certify_result(file.problem, result, file.spec.verify.tolerance,
                                            mesh.tolerance if mesh is not None else None, always_fly,
                                            flight_budget_steps=flight_budget(result.iterations,
                                                                              (result.nlp or {}).get("variables")))
    except Exception as e:  # the certificate must never lose a solved run
        result.certificate = {"error": f"{type(e).__name__}: {e}", "passed": False}
        return
    from .solve.certify import minimum_condition_notes

    notes = result.extra.setdefault("notes", [])
    notes += [n for n in minimum_condition_notes(result.certificate) if n not in notes]


def check_expectations(file: LoadedFile, values: dict[sp.Symbol, float], objective: float | None) -> list[dict]:
    checks = []
    for key, item in file.spec.expect.items():
        expr = file.expect.get(key)
        # constants first (multi-phase expectations are parsed outside any phase, so they keep
        # parameter names), then the solution's values
        subs = {sp.Symbol(k, real=True): v for k, v in file.parameters.items()}
        subs.update(values)
        subs[sp.Symbol("objective", real=True)] = objective if objective is not None else math.nan
        try:
            value = float(expr.xreplace({k: sp.Float(v) for k, v in subs.items()}))
        except (TypeError, ValueError):
            value = math.nan
        checks.append(expect_check(key, value, item.value, item.rtol, item.atol, item.compare))
    return checks


def expect_check(name: str, value: float, reference: float, rtol: float | None, atol: float | None,
                 compare: str = "equal") -> dict[str, Any]:
    """One expect check; with neither tolerance given, rtol = 1e-6, and atol = 1e-6 for a
    reference of zero (where any relative tolerance asks for exactly 0: `expect: {objective:
    0.0}` of an exact-tracking problem, J = 4e-18, could never pass; unseen20)."""
    if rtol is None and atol is None:
        if reference == 0:
            atol = 1e-6
        else:
            rtol = 1e-6
    err = abs(value - reference)
    rel = err / abs(reference) if reference != 0 else math.inf
    slack = max(rtol * abs(reference) if rtol is not None else 0.0, atol or 0.0)
    if compare == "at_most":
        passed = value <= reference + slack
    elif compare == "at_least":
        passed = value >= reference - slack
    else:
        passed = err <= slack
    passed = bool(passed and math.isfinite(value))
    return {"name": name, "value": value, "reference": reference, "rtol": rtol, "atol": atol,
            "compare": compare, "error": err, "relative_error": rel, "passed": passed}
