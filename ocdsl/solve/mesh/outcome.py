"""How a mesh refinement ended: which mesh is reported, with what status and message."""
from __future__ import annotations

import math

from ...verify.objective_size import own_size

GOOD = ("optimal", "acceptable")


#: the advice to a refinement that ran out of iterations (drive.py replaces it where the
#: certificate shows the run follows a local extremal)
RAISE_ADVICE = "Raise max_iterations or max_degree, or loosen the tolerance."


def _path_bound_hint(problem, tr=None) -> str:
    """What to do when a control is bounded by path constraints (`u <= 1 + x`, `-p <= u <= p`):
    the switch locators and the switch-time solves know box bounds only, so a control that
    switches between two such constraints is refined around, never located (unseen11 F2:
    12 meshes, tf 1.1e-3 off; written with a box-bounded control, converged to 1e-12). With
    the reported mesh's transcription ``tr``, only constraints that bind on it are named (a
    never-binding x + u <= 100 was blamed: unseen23)."""
    import sympy as sp

    binding = None
    if tr is not None:
        try:
            from ..arcs import _binding_rows

            binding = {text for _pb, rows in _binding_rows(tr) for text, _s in rows}
        except Exception:  # noqa: BLE001  (a hint: without the solution every candidate is named)
            binding = None
    texts = []
    for ph in problem.phases:
        controls = set(ph.controls)
        for c in ph.path:
            if c.is_equality or (binding is not None and (c.text or str(c.expr)) not in binding):
                continue
            e = sp.sympify(ph.substitute(c.expr))
            used = e.free_symbols & controls
            if (len(used) == 1 and not (sp.diff(e, next(iter(used))).free_symbols & used)
                    and c.text not in texts):       # a chained `lo <= g <= hi` is two rows of one text
                texts.append(c.text)
    if not texts:
        return ""
    return (f" If a control switches between path constraints that bound it ({'; '.join(texts[:3])}), "
            "the mesh cannot locate those switches (it locates switches between box bounds): write the "
            "control as a box-bounded one scaled by the bound, e.g. for |u| <= b(x, t): u = b*w with "
            "-1 <= w <= 1 (docs/mesh.md).")


def _objective_disagreement(converged: list, tolerance: float, constant: float = 0.0) -> str | None:
    """Meshes within the error tolerance must agree in J to it too: on Fuller's problem three
    of them (the second and third by coarsening) gave J 5e-4 apart, still falling, while every
    segment's state error was 2e-8; the estimate does not see an unresolved chattering control,
    and the smallest of them was called converged 1.1e-3 above the optimum. A relative spread
    (with a floor of 1e-8 for objectives near zero) above the tolerance is no convergence;
    ``constant``: J's constant part (verify/objective_size.py), not J's size."""
    values = [c[3].objective for c in converged if c[3].objective is not None]
    if len(values) < 2:
        return None
    spread = (max(values) - min(values)) / max(max(own_size(v, constant) for v in values), 1e-8)
    if spread <= tolerance:
        return None
    iterations = [c[1] for c in converged]
    return (f"the meshes within tolerance {tolerance:.1e} (iterations {iterations}) disagree in the "
            f"objective by {spread:.2e} (relative): the error estimate does not see what moves J")


def _cycle_advice(history: list, spec) -> str:
    """Where meshes within the tolerance had their switches moved off a breakpoint and the
    refinement from the moved meshes never met it again: it cycles, and more iterations repeat
    the cycle (unseen60 F2: chemotherapy, within tolerance at iterations 13 and 22, 12 -> 25
    iterations gave the same verdict after "Raise max_iterations")."""
    moved = [h for h in history if h.get("switches_moved") and (h.get("max_error") or math.inf) <= spec.tolerance]
    if not moved:
        return ""
    last = history[-1]
    return (f"Meshes within the tolerance (iteration(s) {[h['iteration'] for h in moved]}, J = "
            f"{moved[-1]['objective']:.10g} at the last) held a switch on a breakpoint that the switch-time solve "
            "moved, and the meshes from the moved switches did not meet the tolerance again: the refinement "
            f"cycles, and more iterations repeat it (J = {last['objective']:.10g} at iteration {last['iteration']}, "
            "its switches where the NLP puts them).")


def outcome(converged: list, best, last, history: list, status: str | None, message: str, stalled: str,
            spec, problem):
    """How a refinement ended: (status, the chosen mesh's record, message, the disagreement of
    the meshes within tolerance or None, stalled). ``converged``, ``best``, ``last``: the
    drive's records (max_err, iteration, tr, info, meshes, errors); ``status`` None when the
    loop ran out of iterations or met the tolerance."""
    chosen = None
    disagree = _objective_disagreement(converged, spec.tolerance,
                                       problem.objective_constant if problem is not None else 0.0)
    if status is None and disagree:
        # the finest mesh within the error tolerance, as the message says (not the last mesh
        # solved: harmonic oscillator, iteration 25 with error 2.3e-6 was reported as it; nor
        # the last within tolerance: a coarsened 5-variable LGL mesh, its estimate 8.7e-16 and
        # its J 24 % off, was reported beside two right ones, unseen23)
        status = "mesh_not_converged"
        chosen = max(converged, key=lambda c: (c[3].nlp.get("variables", 0), c[1]))
    elif status is None:
        if converged:
            chosen = min(converged, key=lambda c: (c[3].nlp.get("variables", 0), c[0]))
            status = "optimal" if chosen[3].status == "optimal" else chosen[3].status
            message = (f"mesh converged: iteration {chosen[1]} of {len(history)} is the smallest mesh within "
                       f"tolerance {spec.tolerance:.1e} (largest estimated error {chosen[0]:.3e}, "
                       f"{chosen[3].nlp.get('variables', 0)} NLP variables)")
            rejected = [h["iteration"] for h in history if h.get("coarsening_rejected")]
            if rejected:
                message += f"; coarsened meshes that missed it: iteration(s) {rejected}"
        else:
            status = "mesh_not_converged"
            chosen = best
    elif status not in GOOD and best is not None:
        # the last solve was cut short or failed, earlier meshes solved: the best of those is
        # the result (its trajectory and objective), not the failed iterate; a later mesh ending
        # 'infeasible' from its warm start says nothing of the problem (unseen8: a pendulum whose
        # third mesh ended infeasible after two solved was reported infeasible, exit 1)
        chosen = best
        if status in ("time_limit", "interrupted"):
            message += (f"; the result is mesh iteration {best[1]}'s solution, the best completed mesh "
                        f"(Ipopt {best[3].status}, J = {best[3].objective:.10g}, largest estimated error "
                        f"{best[0]:.3e} against the tolerance {spec.tolerance:.1e})")
        else:
            stalled = (f"mesh iteration {last[1]}'s solve, started from the mesh before, ended '{status}' "
                       f"({last[3].message}); the result is the best completed mesh")
            status = "mesh_not_converged"
    else:
        chosen = last
    max_err, it_c, _tr, _info, _meshes, errors_c = chosen
    if status == "mesh_not_converged" and disagree:
        message = (f"mesh refinement did not converge: {disagree}. The finest of them (iteration {it_c}) "
                   "is reported; tighten the tolerance, or see docs/mesh.md (chattering controls, "
                   "singular arcs).")
    elif status == "mesh_not_converged":
        above = [e for es in errors_c.values() for e in es if e.error > spec.tolerance]
        worst = max(above, key=lambda e: e.error) if above else None
        off_c = history[it_c - 1].get("features_off_breakpoints", {})
        term_c = history[it_c - 1].get("terminal_error", 0.0)
        where = (f"in phase '{worst.phase}' segment {worst.segment} (t in [{worst.t_start:.6g}, "
                 f"{worst.t_end:.6g}], state {worst.state}); {len(above)} segment(s) above tolerance"
                 if worst else
                 f"at the terminal condition {history[it_c - 1].get('terminal_where')} "
                 f"({history[it_c - 1].get('terminal_flown')}) "
                 f"({term_c:.3e})" if term_c > spec.tolerance else
                 "within tolerance, but located switches/corners lie off the breakpoints by more than "
                 f"corner_tolerance {spec.corner_tolerance:g}: {_features_shown(off_c)}" if any(off_c.values()) else
                 "within tolerance, but a constraint starts or stops binding between two nodes inside "
                 f"{_inner_shown(errors_c)}, where the states integrate the controls exactly and the estimate "
                 "cannot see the junction's error")
        message = (f"mesh refinement did not reach the tolerance {spec.tolerance:.1e} in "
                   f"{len(history)} of {spec.max_iterations} iterations: best mesh (iteration {it_c}) has "
                   f"largest estimated error {max_err:.3e} {where}. "
                   + (f"Stopped early because {stalled}." if stalled else
                      _cycle_advice(history, spec) or RAISE_ADVICE)
                   + _path_bound_hint(problem, _tr))
    return status, chosen, message, disagree, stalled


def _inner_shown(errors: dict) -> str:
    """The segments holding a junction between two of their nodes, as a user reads them."""
    parts = [f"phase '{e.phase}' segment {e.segment} (t in [{e.t_start:.6g}, {e.t_end:.6g}])"
             for es in errors.values() for e in es if e.inner_junction]
    return "; ".join(parts[:4]) + (f" and {len(parts) - 4} more" if len(parts) > 4 else "") or "a segment"


def _features_shown(off: dict) -> str:
    """Features per phase as a user reads them: normalised time is 0 at t0 and 1 at tf."""
    parts = [f"phase '{k}' at " + ", ".join(f"{v:.6g}" for v in vs) for k, vs in off.items() if vs]
    return "; ".join(parts) + " (normalised time: 0 at t0, 1 at tf)"


def record(result, problem, spec, status: str, history: list, tables: dict, errors_c: dict, max_err: float,
           it_c: int, info_c, symbolic_notes: list, confirmed, notes: list, start_records: list) -> None:
    """The refinement's record in ``result``: its history, the chosen mesh's errors (table
    ``mesh_error`` and ``extra.mesh``), the confirmation's checks, notes and first starts."""
    import numpy as np

    err_tab = {k: [] for k in ("phase", "segment", "t_start", "t_end", "degree", "error",
                               "discrepancy", "violation", "nonsmooth")}
    names = [ph.name for ph in problem.phases]
    for es in errors_c.values():
        for e in es:
            for key in err_tab:
                v = getattr(e, key)
                err_tab[key].append(names.index(v) if key == "phase" else
                                    int(v) if key in ("segment", "degree", "nonsmooth") else float(v))
    result.extra["mesh_history"] = history
    if confirmed.unregularised is not None:
        result.extra["unregularised"] = confirmed.unregularised.record()
    if confirmed.bisection is not None:
        result.extra["bisection"] = confirmed.bisection.record()
    if notes:
        result.extra["notes"] = notes
    if start_records:
        result.extra["starts"] = start_records     # the first mesh's starts (refined from the best)
    result.extra["mesh"] = {"tolerance": spec.tolerance, "iterations": len(history), "chosen_iteration": it_c,
                            "chosen_status": info_c.status,
                            "symbolic_notes": list(dict.fromkeys(symbolic_notes)),
                            "converged": status == "optimal" or (status in GOOD and max_err <= spec.tolerance),
                            "max_error": max_err,
                            "error_map": {ph: [[e.t_start, e.t_end, e.error] for e in es]
                                          for ph, es in errors_c.items()}}
    result.tables["mesh_history"] = {k: np.asarray(v) for k, v in tables.items()}
    result.tables["mesh_error"] = {k: np.asarray(v) for k, v in err_tab.items()}
