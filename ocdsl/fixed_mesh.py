"""What a fixed mesh's single solve is checked and corrected with after it converges, beside
the verification: a control that jumps at the problem's first or last instant tied and solved
again (``tie_jumping_end_controls``), a bang switch held on a breakpoint solved with the
breakpoint free (``pinned_switches``), and J against the same problem with every segment
bisected where inequalities bind inside a phase or no flight judged J (``fixed_mesh_arcs``,
``bisection_check``, which mesh refinement's confirmation uses too)."""
from __future__ import annotations

import math

from .result import Result
from .spec.compile import LoadedFile
from .verify.objective_size import objective_size, own_size


def tie_jumping_end_controls(file: LoadedFile, info, tr, meshes, timer, *, verbose=False) -> tuple:
    """A control collocated at the problem's first or last instant that jumps off its
    segment's other nodes (``solve.mesh.junction.jumping_ends``: a value the end conditions
    do not price, set by the NLP at will, which bends the segment's states: u(t_f) = 0 after
    u = 1 with the final speed free, tf right to 1e-10, not verified) is tied to its segment's
    polynomial and the problem solved once more from the solution, as mesh refinement does.
    The tied solution is kept only where it converges and J moves by no more than the
    tolerance times its size (a genuine switch between the last two nodes would cost more);
    the run's notes say so. Returns (info, tr, notes)."""
    from .run import _scale
    from .solve import ipopt
    from .solve.mesh.junction import jumping_ends, limit_junction_controls
    from .transcribe.guess import solved_guesses
    from .transcribe.pseudospectral import build

    if info.status not in ("optimal", "acceptable") or info.objective is None:
        return info, tr, []
    with timer.measure("post"):
        ends = jumping_ends(tr)
    if not ends:
        return info, tr, []
    with timer.measure("build"):
        tied = build(file.problem, meshes, solved_guesses(file.problem, tr))
        _scale(file, tied)
        limit_junction_controls(tied, outer=ends, junctions=False)
        tied.tied_ends = ends      # the checks that rebuild it on other meshes tie the same ends
    with timer.measure("solve"):
        again = ipopt.solve(tied.model, file.spec.solver.options, verbose=verbose, transcription=tied)
    shown = "; ".join(f"{'t_f' if e == 'end' else 't0'}" + (f" of phase {k}" if len(file.problem.phases) > 1 else "")
                      for k, v in ends.items() for e in sorted(v))
    constant = file.problem.objective_constant
    size = objective_size(info.objective, own_size(info.objective, constant), constant)  # relative below 1
    if again.status not in ("optimal", "acceptable") or again.objective is None:
        return info, tr, [f"the control at {shown} jumps off its segment's other nodes; tied to its segment's "
                          f"polynomial the problem ended {again.status}: the untied solution is reported"]
    if abs(again.objective - info.objective) > file.spec.verify.tolerance * size:
        # J moved: a genuine switch between the last two nodes, or an untied J below the
        # optimum that the free node bought (a two-phase transfer: untied 1.999938, not
        # verified; tied 1.9999999996, the exact 2 to 2e-10, unseen33): the verification decides
        with timer.measure("post"):
            untied_ok, tied_ok = _verifies(file, tr, info, meshes), _verifies(file, tied, again, meshes)
        if tied_ok and not untied_ok:
            return again, tied, [f"the control at {shown} jumped off its segment's other nodes (a value the end "
                                 "conditions do not price); tied to its segment's polynomial the problem solved "
                                 f"again to J {info.objective:.10g} -> {again.objective:.10g}, and that solution "
                                 "is verified where the untied one was not: it is reported"]
        return info, tr, [f"the control at {shown} jumps off its segment's other nodes; tied to its segment's "
                          f"polynomial the problem ended {again.status} with J = {again.objective}: the untied "
                          "solution is reported"]
    return again, tied, [f"the control at {shown} jumped off its segment's other nodes (a value the end "
                         "conditions do not price); it is tied to its segment's polynomial and the problem "
                         f"solved again: J {info.objective:.10g} -> {again.objective:.10g}"]


def _verifies(file: LoadedFile, tr, info, meshes) -> bool:
    """Whether the solution in ``tr`` passes the file's verification."""
    from .run import bare_result
    from .verify import VerifySettings, verify_result

    result, _ = bare_result(file, tr, info, meshes)
    return verify_result(file.problem, result, VerifySettings.of(file.spec.verify))["status"] == "verified"


def fixed_mesh_arcs(file: LoadedFile, result: Result, tr, meshes, timer, *, verbose=False,
                    progress=False) -> list[str]:
    """A converged single solve whose inequalities bind inside a phase, or whose J no flight of
    the minimum principle's control judged: its J is that mesh's optimum, which the
    verification (a feasibility check) cannot judge; so the problem is
    solved once more with every segment bisected, from this solution (and bisected again where
    the first difference does not decide), and where J does not agree (``solve.arcs.Bisection``)
    ``result`` becomes ``mesh_not_converged``. A bang-bang switch held on a breakpoint where
    J still moves with that breakpoint does the same (``pinned_switches``). Returns the run's
    notes."""
    if result.status not in ("optimal", "acceptable"):
        return []
    pinned_switches(file, result, tr, timer)
    if result.status not in ("optimal", "acceptable"):
        return []
    from .solve import arcs

    with timer.measure("post"):
        # a control entering its bound inside a segment leaves every node stationary and the
        # trajectory flying; the certificate's flown control judges that where it applies, the
        # bisection everywhere else (unseen18: x' = u, |u| <= 0.9, x(2) = 0 as two phases, LGR
        # 3 x 3: optimal, verified, certificate pass, J 7.3e-5 off; one phase: refuted)
        flown = (result.certificate or {}).get("flown_control")
        # a flight that predicted a refuting gain and did not realise it judged nothing (unseen23
        # FC3), nor one that could not be corrected onto the final conditions or missed them
        # (seed 4's unrestricted run: `optimal`, J 1.7e-5 above its bisected mesh's; seed 0's
        # paper mesh 8.7e-5: the docs always said "where no flight judged J")
        judged = flown is not None and not flown.get("inconclusive") and flown.get("judged", True)
        # the flight's own reason: doubted, not flown, or not corrected onto the final conditions
        unjudged = (flown or {}).get("inconclusive") or (
            flown.get("note") if flown is not None and flown.get("judged") is False else None)
        found = arcs.binding_arcs(tr, controls=not judged)
    if not found and judged:
        return []
    # nothing binds and no flight judged J: the certificate's conditions at the nodes hold for
    # any mesh's own optimum, and the verification judges feasibility, so a coarse mesh was
    # "optimal, verified" 13 % from J* (unseen20: Dido's problem, an integral constraint, LGL
    # 2 x 2); the bisection is then the only check of J
    multi = len(file.problem.phases) > 1
    if not file.spec.verify.bisection_check:
        return [arcs.note(found, multi, None, unjudged)]
    with timer.measure("bisection"):
        check = bisection_check(file, tr, result.objective, meshes, verbose=verbose, progress=progress,
                                objective_scale=result.extra.get("objective_scale"))
    result.extra["bisection"] = check.record()
    if check.agrees is False:
        result.status = "mesh_not_converged"
        result.message = arcs.mismatch_message(found, multi, check, unjudged)
        from .solve.certify import stopped_short

        if stopped_short(result.certificate):
            # a spurious KKT point (SI orbit raising, thrust angle on its bound: 1.65 % off, the
            # bisection elsewhere again) is no mesh matter (unseen61 F4)
            result.message += (". But the certificate finds the control neither H's minimiser nor stationary "
                               "(the note says where): the solve stopped at a point of the NLP's equations that "
                               "is no extremal of the problem, which refining does not cure; start from another "
                               "guess, or give the variables their sizes (`scaling: {mode: auto, variables: ...}`)")
        return []
    flat = arcs.final_time_spread([(result.objective, arcs.free_final_times(tr))]
                                  + [(lv.objective, lv.final_times) for lv in check.levels], file.spec.verify.tolerance)
    return [arcs.note(found, multi, check, unjudged)] + ([flat] if flat else [])


def pinned_switches(file: LoadedFile, result: Result, tr, timer) -> None:
    """A fixed mesh whose control switches from one bound to the other exactly on a breakpoint
    holds the switch there whether or not it belongs there: J is then this mesh's optimum for a
    switch at that breakpoint, which the bisection (same breakpoints) and the verification (the
    trajectory flies) cannot judge (unseen14: x' = u x, max int (1 - u) x on [0, 3.15], LGR 3 x
    5: the switch at t = 2.10 for 2.15, J 1.2e-3 low, optimal, verified, certificate pass).
    Where the envelope gradient dJ*/ds of such a breakpoint (``breakpoint_gradient``) says a
    move of a neighbouring segment's width could change J by more than the verification's
    tolerance, the problem is solved once more with those breakpoints as unknowns and the bang
    controls held (``with_free_switches``; the gradient alone cannot decide: with every control
    node on a bound the multipliers are a family, and the double integrator's exact switch has
    one); where that moves a switch and improves J by more than the tolerance, ``result`` is
    ``mesh_not_converged``."""
    import numpy as np
    import pyomo.core as pyo

    problem = file.problem
    if not any(all(map(math.isfinite, ph.bounds_of(c)[:2])) for ph in problem.phases for c in ph.controls):
        return                 # no control with two finite bounds: no bang-bang switch
    from .solve import ipopt
    from .solve.mesh.locate import locate_switches
    from .solve.mesh.switches import breakpoint_gradient, with_free_switches

    def rebuild(ms, **kw):
        return _rebuilt(file, tr, ms, **kw)

    tol = file.spec.verify.tolerance
    J = float(result.objective or 0.0)
    size = objective_size(J, result.extra.get("objective_scale"), problem.objective_constant)
    with timer.measure("post"):
        params = {s: float(pyo.value(tr.scalars[s])) for s in problem.free_parameters}
        suspects: dict[str, list[int]] = {}
        for pb in tr.phases:
            bps = np.asarray(pb.layout.mesh.breakpoints, float)
            try:
                switches = locate_switches(tr, pb, params, 1e-6)
            except Exception:  # noqa: BLE001  (an aid: the verification stands)
                continue
            t0, tf = float(pyo.value(pb.block.t0)), float(pyo.value(pb.block.tf))
            crossings = _switching_crossings(result.certificate, pb.phase.name, len(tr.phases))
            for f in switches:
                q = int(np.argmin(np.abs(bps - f)))
                if not (0 < q < len(bps) - 1) or abs(bps[q] - f) > 1e-12:
                    continue
                g = breakpoint_gradient(tr, rebuild, pb.phase.name, q)
                # where PMP puts the switch: the switching function's nearest sign change (the
                # certificate's), else anywhere in the neighbouring segments
                t_b = t0 + (tf - t0) * bps[q]
                near = [c for c in crossings if bps[q - 1] <= (c - t0) / (tf - t0) <= bps[q + 1]]
                gap = (min(abs(c - t_b) for c in near) / (tf - t0) if near
                       else min(bps[q] - bps[q - 1], bps[q + 1] - bps[q]))
                # J*(s) ~ quadratic about the switch's place: moving there gains |g| gap / 2
                if math.isfinite(g) and 0.5 * abs(g) * gap > tol * size:
                    suspects.setdefault(pb.phase.name, []).append(q)
    if not suspects:
        return
    with timer.measure("post"):
        try:
            freed = with_free_switches(tr, rebuild, lambda t: ipopt.solve(t.model, file.spec.solver.options,
                                                                         transcription=t), suspects, 1e-6)
        except Exception:  # noqa: BLE001  (an aid: the verification stands)
            freed = None
    if freed is None:
        return
    J_free, meshes = freed
    better = (J - J_free) if problem.objective.sense == "minimize" else (J_free - J)
    if better <= tol * size:
        return
    moves = []
    for pb in tr.phases:
        if pb.phase.name in meshes:
            t0, tf = float(pyo.value(pb.block.t0)), float(pyo.value(pb.block.tf))
            old, new = pb.layout.mesh.breakpoints, meshes[pb.phase.name].breakpoints
            moves += [(pb.phase.name, t0 + (tf - t0) * float(old[q]), float(new[q])) for q in suspects[pb.phase.name]]
    result.extra["pinned_switches"] = {"objective_with_switches_free": J_free,
                                       "moves": [{"phase": p, "t": t, "s_free": s} for p, t, s in moves]}
    where = ", ".join(f"t = {t:.6g}" for _, t, _ in moves[:3])
    result.status = "mesh_not_converged"
    result.message = (f"a control switches from one bound to the other exactly on a breakpoint of this fixed mesh "
                      f"({where}), and with that breakpoint free J = {J_free:.10g} against {J:.10g} here (better by "
                      f"{better / max(abs(J), 1e-300):.1e} relative): the mesh holds the switch in the wrong place, so "
                      "J is this mesh's optimum, not the problem's. `mesh:` locates the switches (docs/mesh.md)")


def _rebuilt(file: LoadedFile, tr, meshes, **kw):
    """``file``'s problem built on ``meshes`` (``build``'s keywords ``kw``), started from the
    solution in ``tr`` and scaled as the run's first build was."""
    from .run import _scale
    from .transcribe.guess import solved_guesses
    from .transcribe.pseudospectral import build

    built = build(file.problem, meshes, solved_guesses(file.problem, tr), **kw)
    _scale(file, built)
    ends = getattr(tr, "tied_ends", None)
    if ends:
        # the bisection of a tied solution bisected untied found the free node's J again, below
        # the optimum (a two-phase transfer: 1.999985, 1.999996 against the tied 2, unseen33)
        from .solve.mesh.junction import limit_junction_controls

        limit_junction_controls(built, outer=ends, junctions=False)
        built.tied_ends = ends
    return built


def _switching_crossings(certificate: dict | None, phase: str, phases: int) -> list[float]:
    """The times where the certificate found a control's switching function change sign."""
    cert = certificate or {}
    if phases > 1:
        cert = (cert.get("phases") or {}).get(phase) or {}
    per = ((cert.get("bang_bang") or {}).get("per_control") or {})
    return [float(t) for c in per.values() for t in (c.get("switch_times") or [])]


def bisection_check(file: LoadedFile, tr, objective: float, meshes, *, verbose=False, progress=False,
                    build_model=None, options=None, objective_scale: float | None = None):
    """Solve ``file``'s problem on ``meshes`` with every segment bisected, started from the
    solution in ``tr``, and once more bisected where the first difference does not decide;
    compare J (``solve.arcs.Bisection``). ``build_model(meshes, guesses)`` and ``options``:
    how the caller builds and solves its models (mesh refinement: junction controls, its Ipopt
    tolerance); by default a plain build and the file's solver options. ``objective_scale``:
    the objective's terms' size (verify/objective_size.py), below 1 the unit of Ipopt's
    accuracy in J (an absolute 1e-7 accepted a J of 7.8e-11 that moved by 8.6e-5 of itself)."""
    from .solve import ipopt
    from .solve.arcs import Bisection, Level, free_final_times
    from .transcribe.guess import solved_guesses

    problem = file.problem
    options = file.spec.solver.options if options is None else options
    # Ipopt's own accuracy: its tolerance on the (scaled) objective's optimality, in units of
    # the objective's own size where that is below 1
    floor = 10 * float(options.get("tol", 1e-8)) * (objective_size(0.0, objective_scale))
    check = Bisection(float(objective), (), file.spec.verify.tolerance, floor, problem.objective_constant)
    while not check.levels or check.needs_second:
        meshes = {name: mesh.bisected() for name, mesh in meshes.items()}
        if build_model is None:
            tr = _rebuilt(file, tr, meshes)
        else:
            tr = build_model(meshes, solved_guesses(problem, tr))
        # from the primal point alone: the mesh refinement's multiplier warm start (warm_start.py)
        # took 3 iterations instead of 12 on Bryson-Denham but 29 instead of 18 on Goddard's
        # three phases, and 33 as before on Goddard
        info = ipopt.solve(tr.model, options, verbose=verbose,
                           progress=ipopt.Progress(progress, "[bisected mesh]"), transcription=tr)
        good = info.status in ("optimal", "acceptable") and info.objective is not None
        level = Level(float(info.objective) if good else None, info.status,
                      int((info.nlp or {}).get("variables", 0)), int(info.iterations or 0),
                      free_final_times(tr) if good else {})
        check = Bisection(check.objective, check.levels + (level,), check.tolerance, floor, check.constant)
        if not good:
            break
    return check
