"""A refinement whose answer the certificate's flown control beats by more than the mesh
tolerance (``flown_control``) is refined once more with breakpoints pinned where that control
reaches or leaves a bound.

The error estimate cannot see such a corner when the segment's polynomials integrate the
dynamics exactly (x' = u with u = clip(t - 1): estimate 1e-16, J 6.4e-5 off, unseen14 F2), and
the corner locator reads the solution's own control polynomials, which smooth it away. The
minimum principle's control, built from the states and costates, has the corner sharp: its
times become breakpoints of the next start mesh and features every later mesh keeps.
"""
from __future__ import annotations

import math

import numpy as np

from ..certificate.flown_control import FLIGHT_RESOLUTION
from ...verify.objective_size import own_size




def _margin(tolerance: float, objective: float, result) -> float:
    """What a J must differ by to count: the mesh tolerance x (1 + |J - C|), at least the
    flight's resolution; C J's constant part (verify/objective_size.py, from the certificate)."""
    constant = float(result.extra.get("objective_constant", 0.0))
    return max(tolerance, FLIGHT_RESOLUTION) * (1.0 + own_size(objective, constant))


def _shown(corners: dict) -> str:
    return ", ".join(f"{p:.6g}" for ps in corners.values() for p in ps)


def refuted_corners(result, tolerance: float) -> dict[str, list[float]]:
    """Phase name -> normalised times of the flown control's corners and bang switches, when the certificate's
    ``flown_control`` flew a feasible trajectory better than the result by more than the mesh
    ``tolerance`` x (1 + |J|) (single-phase problems only; the certificate itself fails at the
    verification's tolerance), or was inconclusive with a predicted gain above that (unseen23
    FC2: a corner inside an LGR segment of x' = u, predicted gain 8.5e-4, the corrected flight
    worse, J 3.0e-4 off; with the corners kept, J* to 1e-8); empty otherwise."""
    check = (result.certificate or {}).get("flown_control") or {}
    # where the flown control reaches or leaves a bound, and where it switches between bounds
    times = list(check.get("corners") or []) + list(check.get("switches") or [])
    if not times or len(result.phases) != 1:
        return {}
    margin = _margin(tolerance, check["claimed"], result)
    beaten = check.get("feasible") and check.get("gain", 0.0) > margin
    doubted = bool(check.get("inconclusive")) and check.get("predicted_gain", 0.0) > margin
    if not (beaten or doubted):
        return {}
    traj = result.phases[0]
    t = np.asarray(traj.time, float)
    t = t[np.isfinite(t)]
    t0, tf = float(t[0]), float(t[-1])
    if not tf > t0:
        return {}
    # the switches of a flight over a moved free final time are in its own time, the corners
    # (H's minimiser before any correction) in the solution's
    stretch = float((check.get("corrected") or {}).get("stretch", 1.0))
    points = sorted([(c - t0) / (tf - t0) for c in check.get("corners") or []]
                    + [(c - t0) / (stretch * (tf - t0)) for c in check.get("switches") or []])
    return {traj.name: [p for p in points if math.isfinite(p) and 0.0 < p < 1.0]}


def beaten_meshes(result, converged: list, sense: str, tolerance: float) -> list[int]:
    """Iterations among ``converged`` (drive.py's records) whose J the certificate's flown
    control of ``result`` (feasible) beats by more than the mesh ``tolerance`` x (1 + |J|) (at
    least the flight's resolution): whatever their estimates say, they are no optimum (unseen14
    F8: a first mesh blind to a corner, J 1.1e-4 off with estimate 4e-12, kept every later
    agreement failing). Empty without such a flight."""
    check = (result.certificate or {}).get("flown_control") or {}
    if not check.get("feasible") or check.get("flown") is None:
        return []
    flown = float(check["flown"])
    margin = _margin(tolerance, flown, result)
    sign = 1.0 if sense == "minimize" else -1.0
    return [c[1] for c in converged if c[3].objective is not None and sign * (c[3].objective - flown) > margin]


def with_breakpoints(mesh, points, tolerance: float):
    """``mesh`` with a breakpoint at each of ``points`` (normalised) farther than ``tolerance``
    from every breakpoint it has; a split segment's halves keep its degree."""
    from ...transcribe.mesh import Mesh

    bps, degrees = list(map(float, mesh.breakpoints)), list(mesh.degrees)
    for p in sorted(points):
        if min(abs(b - p) for b in bps) <= tolerance:
            continue
        k = int(np.searchsorted(bps, p)) - 1
        bps.insert(k + 1, p)
        degrees.insert(k, degrees[k])
    return Mesh(mesh.scheme_name, np.asarray(bps), tuple(degrees))


def _continued(again, history: list, tables: dict) -> None:
    """The second refinement's record after the first's: one history, iterations numbered on."""
    n = len(history)
    later = again.extra.get("mesh_history") or []
    for rec in later:
        rec["iteration"] = rec.get("iteration", 0) + n
    again.extra["mesh_history"] = history + later
    mesh = again.extra.get("mesh")
    if isinstance(mesh, dict):
        mesh["iterations"] = n + int(mesh.get("iterations", 0))
        if mesh.get("chosen_iteration") is not None:
            mesh["chosen_iteration"] = int(mesh["chosen_iteration"]) + n
    old = again.tables.get("mesh_history") or {}
    if old and all(k in tables for k in old):
        first = {k: np.asarray(tables[k]) for k in old}
        if "iteration" in first:
            old = {**old, "iteration": np.asarray(old["iteration"]) + n}
        again.tables["mesh_history"] = {k: np.concatenate([first[k], np.asarray(old[k])]) for k in old}


def second_pass_recorded(again, history: list, tables: dict) -> None:
    """A second refinement whose answer did not replace the first's, recorded after the
    first's all the same (``history`` and ``tables`` extended in place, numbered on, each
    entry marked ``second_pass``): its meshes were printed and solved, and the docs promise
    both passes in the record (unseen38 F6: 7 + 7 meshes printed, 7 in result.json)."""
    n = len(history)
    for rec in again.extra.get("mesh_history") or []:
        history.append({**rec, "iteration": rec.get("iteration", 0) + n, "second_pass": True})
    later = again.tables.get("mesh_history") or {}
    if later and all(k in tables for k in later):
        for k, v in later.items():
            tables[k].extend((np.asarray(v) + (n if k == "iteration" else 0)).tolist())


def announce_again(result, corners: dict, objective: float) -> str:
    """The progress line of a second refinement with ``corners`` kept."""
    flown = result.certificate["flown_control"]
    why = (f"the control the minimum principle flies beats J = {objective:.10g}"
           if not flown.get("inconclusive") else
           f"the control that minimises H predicts a gain of {flown['predicted_gain']:.1e} over J = "
           f"{objective:.10g} (its flight proves nothing)")
    return f"mesh: {why}; refining again with breakpoints kept at {_shown(corners)} (normalised time)"


def refined_again(again, result, corners: dict, history: list, tables: dict, chosen: int):
    """``again`` (the second refinement, with ``corners`` kept) recorded after the first (its
    ``history`` and ``tables``; ``result`` its answer at mesh iteration ``chosen``)."""
    _continued(again, history, tables)
    flown = result.certificate["flown_control"]
    beat = (f"which the control the minimum principle flies beat (J = {flown['flown']:.10g})"
            if not flown.get("inconclusive") else
            f"where the control that minimises H predicted a gain of {flown['predicted_gain']:.1e} "
            "that its flight did not realise")
    again.extra.setdefault("notes", []).append(
        f"the first refinement ended at J = {flown['claimed']:.10g} (mesh iteration {chosen}), {beat}; "
        f"refined again with breakpoints kept where that control reaches or leaves a bound ({_shown(corners)}, "
        "normalised time)")
    again.extra["first_refinement"] = {"objective": flown["claimed"], "flown": flown.get("flown"),
                                       "predicted_gain": flown.get("predicted_gain"),
                                       "iterations": len(history), "corners": corners}
    return again


def second_pass_no_better(first, again, sense: str, tolerance: float) -> str | None:
    """The note that keeps the first refinement's answer, or None (the second pass's is the
    result). Where the flown control only doubted the first answer (a predicted gain its
    flight did not realise), the second pass with the corners kept is the test: finding no J
    better by more than the mesh tolerance x (1 + |J|), the first answer stands (unseen25: on
    LG, J right to 1e-10, predicted 2.6e-3 from LG's costates, and the second pass's meshes
    disagreed: `mesh_not_converged`, exit 1). A flight that beat the first answer proves it
    wrong: the second pass's answer stands whatever it is."""
    check = (first.certificate or {}).get("flown_control") or {}
    if not check.get("inconclusive") or first.objective is None:
        return None
    if again.objective is not None and math.isfinite(float(again.objective)):
        sign = 1.0 if sense == "minimize" else -1.0
        if sign * (float(first.objective) - float(again.objective)) > _margin(tolerance, first.objective, first):
            return None
    shown = "none" if again.objective is None else f"{float(again.objective):.10g}"
    return (f"the control that minimises H predicted a gain of {check['predicted_gain']:.1e} its flight did not "
            f"realise; a second refinement with that control's corners kept found no better J ({shown}, "
            f"{again.status}): this refinement's answer stands")
