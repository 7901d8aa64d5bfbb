"""Independent verification of a returned trajectory, for every back end.

:func:`verify_result` takes the compiled :class:`~ocdsl.symbolic.problem.Problem` and a
:class:`~ocdsl.result.Result`, i.e. only what the run folder holds: the rows of each phase,
the controls with the interpolation the run folder documents
(:mod:`ocdsl.verify.interpolate`), the final times and the parameters. It never looks at
the NLP. It checks, per phase and then over the problem:

* the dynamics, re-integrated with a tight integrator (:mod:`ocdsl.verify.integrate`)
  from the initial state (``dynamics from x(t0)``) and piece by piece from the solution's
  own states (``dynamics per piece``), error per state relative to its range, at every row;
* every box bound and path constraint on a dense grid between the rows, with the
  re-integrated states and the interpolated controls; the exported controls against their
  bounds;
* every boundary condition, link and integral constraint evaluated with the re-integrated
  states and integrals (integrals are integrated with the dynamics, not read off a
  quadrature), and the objective recomputed from the re-integrated trajectory.

Every value is relative and held to ``tolerance`` (the file's ``verify: {tolerance}``,
default 1e-5). A problem with declared terminal tolerances (parametric ``tolerances:``)
is held to those on the constraints they name. The verification never raises: an
internal failure is reported as ``status: "error"``, which is not a pass.
"""
from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import sympy as sp

from ..result_views import completed_solution
from ..symbolic.model import TIME
from ..symbolic.problem import INF
from .checks import (RESOLUTION, end_control_jumps, evaluate, integral_scales, irregular_controls, path_scales,
                     path_violations, relative_violation,
                     row, sensitivity_scale, state_scale, worst)
from .admissible import project, row_values
from .functions import PhaseFunctions, between_points, controls_at
from .integrate import IntegrationFailure, flight_amplification, reintegrate, time_budget
from .interpolate import (_Tabulated, bounds_of, breakpoints, control_interpolant, control_rows,
                          declared_interpolation)

__all__ = ["VerifySettings", "verify_result", "attach_verification", "STATUSES", "CONVERGED"]

STATUSES = ("verified", "failed", "error", "skipped", "not_applicable")
# results with a trajectory worth verifying; a mesh or flat refinement that missed its own
# tolerance still returns a converged NLP's solution (its best level), and the user should see
# whether that answer holds at the verification's tolerance
CONVERGED = ("optimal", "acceptable", "feasible", "stable", "mesh_not_converged")


@dataclass(frozen=True)
class VerifySettings:
    tolerance: float = 1e-5
    mode: str = "enforce"          # or "warn": reported, does not fail the run
    rtol: float = 1e-10            # the integrator's (well below tolerance)
    per_interval: int = 3          # dense points between consecutive rows
    between: int = 8               # Hermite-interpolated points between dense points, for the
                                   # bound and path checks (functions.between_points)
    open_loop: bool = True         # also fly the control from x(t0); off for closed-loop runs
    time_limit: float = 600.0      # wall seconds for the whole verification of one result

    @classmethod
    def of(cls, spec) -> "VerifySettings":
        """From a file's ``verify:`` block (``ocdsl.spec.schema.VerifySpec``) or None."""
        if spec is None:
            return cls()
        return cls(tolerance=float(spec.tolerance), mode=str(spec.mode),
                   rtol=min(1e-10, float(spec.tolerance) * 1e-5),
                   time_limit=float(spec.time_limit))

    def closed_loop(self) -> "VerifySettings":
        """The same, for a closed-loop run: its control came from feedback on the simulated
        state, so flying it open loop from x(t0) tests the plant's stability, not the run."""
        return replace(self, open_loop=False)


# a phase shorter than this share of the times' size takes no time the NLP can resolve
COLLAPSED_SHARE = 1e-9


def attach_verification(problem, result, settings: VerifySettings | None = None) -> None:
    """Verify ``result`` and keep the verdict in ``result.verification`` and the
    re-integrated trajectories in ``result.tables["reintegration_<phase>"]``."""
    tables: dict[str, dict[str, np.ndarray]] = {}
    result.verification = verify_result(problem, result, settings, tables=tables)
    result.tables.update(tables)


def verify_result(problem, result, settings: VerifySettings | None = None,
                  tables: dict | None = None) -> dict[str, Any]:
    """The verdict as a JSON-able dict (see the module doc); never raises."""
    settings = settings or VerifySettings()
    head = {"mode": settings.mode, "tolerance": settings.tolerance, "integrator_rtol": settings.rtol}
    if problem is None or not result.phases:
        return {**head, "status": "skipped", "checks": [], "summary": "no trajectory to verify"}
    # a closed-loop run simulates every law, whether it regulates or not: each trajectory is
    # checked all the same (one unstable law left the others unverified, unseen9 F9)
    simulated = not settings.open_loop and result.status in ("unstable", "error")
    # a run cut short by its time limit returns the best completed mesh's (or start's)
    # solution: that trajectory is checked like any other (the run still fails on its status)
    if result.status not in CONVERGED and not simulated and completed_solution(result) is None:
        return {**head, "status": "skipped", "checks": [],
                "summary": f"the solver ended '{result.status}': nothing to verify"}
    start = time.perf_counter()
    try:
        with time_budget(settings.time_limit):
            checks, notes = _verify(problem, result, settings, tables if tables is not None else {})
    except IntegrationFailure as e:
        return {**head, "status": "error", "checks": [], "wall_time_s": time.perf_counter() - start,
                "summary": f"could not verify: {e}"}
    except Exception as e:  # noqa: BLE001 - a verdict, never a lost run
        return {**head, "status": "error", "checks": [], "wall_time_s": time.perf_counter() - start,
                "summary": f"could not verify (internal error {type(e).__name__}: {e})",
                "traceback": traceback.format_exc(limit=8)}
    failed = [c for c in checks if c["passed"] is False]
    status = "failed" if failed else "verified"
    out = {**head, "status": status, "checks": checks, "notes": notes,
           "wall_time_s": round(time.perf_counter() - start, 6)}
    judged = [c for c in checks if c["passed"] is not None]
    mesh = (result.method or {}).get("mesh")
    # "the refinement met its tolerance" only of a refinement that did (unseen36 F3: said one
    # line above "largest estimated error 4.544e-02")
    met = bool((result.extra.get("mesh") or {}).get("converged"))
    mesh_tolerance = mesh.get("tolerance") if isinstance(mesh, dict) else None
    # a law whose loop diverged: its failed checks say so, not that the step is too large
    diverged = {} if settings.open_loop else {
        law: rec["message"] for law in result.extra.get("laws", [])
        if isinstance(rec := result.extra.get(law), dict) and "diverged" in str(rec.get("message", ""))}
    out["summary"] = _summary(failed, notes, settings, checks, mesh_tolerance, diverged, met) if failed else \
        f"verified: {len(judged)} checks within {settings.tolerance:g}" + _not_judged(checks)
    out["caveats"] = [c["precision"] for c in checks if c.get("precision")] if not failed else []
    return out


def _not_judged(checks: list[dict]) -> str:
    """The checks left unjudged and why (each reason once)."""
    skipped = [c for c in checks if c["passed"] is None]
    if not skipped:
        return ""
    names = ", ".join(dict.fromkeys(f"{c['name']} ({c['detail']})" if c["name"] != "dynamics from x(t0)"
                                    else c["name"] for c in skipped))
    reasons = "; ".join(dict.fromkeys(c.get("not_judged", "") for c in skipped))
    return f"; not judged: {names}. {reasons}"


# -------------------------------------------------------------------------------------
HINTS = {
    "dynamics per piece": "the trajectory does not satisfy the dynamics between its rows: refine "
                          "the mesh (more segments or degree, or `mesh:`)",
    "dynamics from x(t0)": "the control, flown from the initial state, does not reproduce the "
                           "trajectory: refine the mesh, or the problem is too sensitive to fly open loop",
    "state bounds": "a state leaves its bounds between the rows: refine the mesh",
    "path constraints": "a path constraint is violated between the rows: refine the mesh",
    "control bounds": "an exported control exceeds its bounds",
    "boundary conditions": "a boundary condition or link is not met by the re-integrated "
                           "trajectory: refine the mesh",
    "integral constraints": "an integral of the trajectory differs from the transcription's "
                            "quadrature of it: the solution exploits the quadrature (typical of LGR/LGL "
                            "with a non-smooth integrand); use LG, write the integral as a state, or refine",
    "objective": "the objective recomputed from the re-integrated trajectory differs from the "
                 "solver's: refine the mesh",
    "free final time": "the objective still changes with the final time, which is free and "
                       "constrained by nothing active: the solver stopped short of the optimum "
                       "(often at the guess of tf); refine the mesh or start from another tf",
}


CLOSED_LOOP_HINTS = {
    "cost": "the cost the simulation integrated with its own step differs from its integral "
            "along the same pieces: a smaller `simulate.step`, or `integrator: dop853`",
    "dynamics per piece": "the simulation's integrator is not accurate at its step: a smaller "
                          "`simulate.step`, or `integrator: dop853`",
    "control bounds": "a recorded control exceeds the saturation limits",
}


# the flight from x(t0) misses while every piece meets the dynamics this far inside the
# tolerance: refining adds pieces whose defects (at the NLP's own tolerance) add up
PIECES_FAR_INSIDE = 1e-2


# the checks whose hint is to refine the mesh
REFINE_HINTED = ("dynamics per piece", "dynamics from x(t0)", "state bounds", "path constraints",
                 "boundary conditions", "objective")


def _summary(failed: list[dict], notes: list[str], settings: VerifySettings,
             checks: list[dict] | None = None, mesh_tolerance: float | None = None,
             diverged: dict[str, str] | None = None, mesh_met: bool = True) -> str:
    """The first failed check, and what to change: an irregular control's note where there
    is one (refining is then the wrong advice), else the check's hint. ``diverged``: the
    closed-loop laws whose simulation diverged, with its message."""
    c = failed[0]
    if c.get("phase") in (diverged or {}):
        # unseen37 F5: x' = x + (1 - x)u under LQR escapes at t = 0.66; "a smaller step" was the advice
        notes = [f"law {c['phase']}'s loop diverged ({diverged[c['phase']]}): no step integrates a state "
                 "escaping to infinity accurately; the failure says the law does not regulate from this "
                 "start, not that the step is too large"]
    pieces = [k for k in checks or [] if k["name"] == "dynamics per piece" and k.get("phase") == c.get("phase")]
    if (c["name"] == "dynamics from x(t0)" and not notes and pieces and pieces[0]["passed"]
            and pieces[0]["value"] <= PIECES_FAR_INSIDE * pieces[0]["limit"]):
        # Van der Pol on 4,000 x 6 segments: every piece within 8.6e-8, the flight 2.7e-5 off
        notes = [f"every piece meets the dynamics (to {pieces[0]['value']:.1e}): the miss builds up "
                 "along the flight, from the dynamics amplifying small defects or the solver's "
                 "tolerance summed over many segments; a tighter solver `tol` (solver: {options: "
                 "{tol: 1e-10}}) or fewer segments of higher degree, rather than more of them"]
    where = f" ({c['where']})" if c.get("where") else ""
    phase = f" in phase {c['phase']}" if c.get("phase") and c["phase"] != "main" else ""
    more = f"; {len(failed) - 1} more failed" if len(failed) > 1 else ""
    hints = HINTS if settings.open_loop else {**HINTS, **CLOSED_LOOP_HINTS}
    hint = notes[0] if notes else c.get("hint") or hints.get(c["name"], "")
    if not notes and settings.open_loop and mesh_tolerance is not None and c["name"] in REFINE_HINTED \
            and not mesh_met:
        hint = ("the refinement did not reach its tolerance (its message says where it stopped): the mesh "
                "does not resolve the solution yet")
    elif not notes and settings.open_loop and mesh_tolerance is not None and c["name"] in REFINE_HINTED:
        # "refine the mesh (... or `mesh:`)" to a run that refined its mesh (unseen32: `mesh:
        # {tolerance: 1e-5}`, its estimate 6.3e-6, the verification 1.66e-5 on that segment)
        tol = settings.tolerance
        hint = (f"the refinement met its tolerance {float(mesh_tolerance):g} by its own error estimate, but "
                "the verification's dense re-integration measures between the rows: give `mesh: {tolerance: "
                f"{tol / 10:g}}}` (a tenth of the verification's {tol:g})"
                if float(mesh_tolerance) > tol / 10 else
                f"the refinement's own estimate met {float(mesh_tolerance):g}: more `mesh: {{max_iterations}}` "
                "or a smaller `mesh: {tolerance}`")
    if c.get("scale_note"):
        hint = f"{c['scale_note']}. {hint}"
    return f"not verified: {c['name']}{phase} {c['value']:.3g} > {c['limit']:.3g}{where}{more}. {hint}"


def _numbers(values: dict) -> dict[str, float]:
    out = {}
    for k, v in values.items():
        try:
            out[k] = float(v)
        except (TypeError, ValueError):
            continue
    return out


@dataclass
class _PhaseRun:
    t: np.ndarray
    X: np.ndarray
    scale_x: np.ndarray
    scale_q: np.ndarray
    glob_end: np.ndarray
    local_end: np.ndarray
    uf: Any
    end_rate: np.ndarray | None = None     # d/dt of [states; integrals] at t_f (local pass)
    flight_not_judged: str = ""            # why the flight from x(t0) judges nothing (_too_sensitive)
    notes: list[str] = field(default_factory=list)   # advice that replaces a failed check's hint


def _verify(problem, result, settings: VerifySettings, tables: dict) -> tuple[list[dict], list[str]]:
    tol = settings.tolerance
    params = _numbers(result.parameters)
    checks: list[dict] = []
    notes: list[str] = []
    runs: dict[str, _PhaseRun] = {}
    wide = _wide_state_scales(problem, result)
    for ph in problem.phases:
        traj = result.phase(ph.name) if len(result.phases) > 1 or ph.name == result.phases[0].name \
            else result.phases[0]
        try:
            runs[ph.name] = _verify_phase(ph, traj, declared_interpolation(traj, result.method), params,
                                          settings, checks, tables, wide)
        except IntegrationFailure as e:
            if settings.open_loop:
                raise
            # a closed-loop run's phases are its laws, each simulated on its own: one law whose
            # flight the integrators cannot finish (it diverged) fails alone (unseen29: LQR on
            # x' = x^3 + u blew up and left the stable SDRE law `verification error`)
            runs[ph.name] = _unflown_phase(ph, traj, e, tol, checks)
        dynamics_failed = any(c["phase"] == ph.name and c["name"].startswith("dynamics") and c["passed"] is False
                              for c in checks)
        if dynamics_failed:
            runs[ph.name].notes[:0] = _sign_crossings(ph, runs[ph.name], tol)
        if (result.method or {}).get("transcription") == "LGR" and any(
                c["phase"] == ph.name and c["name"] == "path constraints" and c["passed"] is False
                and c.get("at_start") for c in checks):
            # LGR collocates no point at t0: a path constraint the initial conditions break is
            # never seen by the NLP, and refining (as the hint said) only doubled J (unseen47 F2)
            runs[ph.name].notes.insert(0, "the path constraint is violated at t0 itself, where LGR holds none "
                                          "(it has no collocation point there): if the initial conditions "
                                          "break it the problem is infeasible; LG or LGL hold it at t0")
        notes += [f"phase {ph.name}: {n}" if len(problem.phases) > 1 else n for n in runs[ph.name].notes]
        names_u = [c.name for c in ph.controls]
        if names_u and settings.open_loop:     # collocation advice; a feedback law may chatter
            tr, Ur = control_rows(traj, names_u)
            notes += [f"phase {ph.name}: {n}" if len(problem.phases) > 1 else n
                      for n in irregular_controls(tr, Ur, names_u, (result.method or {}).get("transcription"),
                                                  mesh=(result.method or {}).get("mesh") is not None,
                                                  spans=[hi - lo for lo, hi in bounds_of(ph, names_u, "controls")])
                      + (end_control_jumps(tr, Ur, names_u, (traj.control_interpolation or {}).get("breakpoints"),
                                           mesh=(result.method or {}).get("mesh") is not None)
                         if dynamics_failed else [])]
    _boundary_checks(problem, result, runs, params, tol, checks, settings.open_loop)
    _reported_integral_checks(problem, result, runs, tol, checks)
    return checks, notes


def _wide_state_scales(problem, result) -> dict[str, float]:
    """Each state's scale (``state_scale``) over the rows of every phase that has it."""
    out: dict[str, float] = {}
    if len(problem.phases) < 2:
        return out
    for traj in result.phases:
        for name, column in traj.states.items():
            col = np.asarray(column, float)
            col = col[np.isfinite(col)]
            if col.size:
                out[name] = max(out.get(name, 0.0), float(state_scale(col[:, None])[0]))
    return out


def _sign_crossings(ph, run: _PhaseRun, tol: float) -> list[str]:
    """A state whose rate vanishes where it does (x' = x g(...): x = 0 is a solution, so the
    dynamics keep x's sign) that the rows take across 0 from a start off it: the NLP went where
    the model cannot (unseen32: an SIR model on a coarse mesh, S' = -beta S I - u S, I =
    -64, J = -3.6 for a cost of positive terms; the advice was to refine the mesh)."""
    out = []
    for j, (x, rate) in enumerate(zip(ph.states, ph.rhs())):
        column = run.X[:, j]
        x0 = float(column[0]) if len(column) else 0.0
        if x0 == 0.0 or not np.any(np.sign(column) == -np.sign(x0)):
            continue
        if np.max(-np.sign(x0) * column) <= tol * float(run.scale_x[j]):
            continue
        try:
            # the rate at x = 0 as SymPy evaluates it (0 for x g(...)); no simplify: on seed 1's
            # model it factored polynomials for tens of seconds
            keeps_sign = sp.sympify(rate).subs(x, 0) == 0
        except Exception:  # noqa: BLE001 - an advice only
            keeps_sign = False
        if keeps_sign:
            low = float(np.min(column) if x0 > 0 else np.max(column))
            out.append(f"{x.name} crosses 0 (to {low:.3g}) from {x0:.3g}, which its dynamics cannot do ({x.name}' "
                       f"vanishes at {x.name} = 0): the NLP found a trajectory where the model is not; bound it "
                       f"(`{x.name} {'>=' if x0 > 0 else '<='} 0`)")
    return out


def _unflown_phase(ph, traj, failure: Exception, tol: float, checks: list[dict]) -> _PhaseRun:
    """A phase the integrators could not fly: one failed row says where they stopped; its
    ends and integrals are unknown (NaN), so whatever depends on them fails too."""
    t = np.asarray(traj.time, float)
    X = np.column_stack([np.asarray(traj.states[s.name], float) for s in ph.states]) if ph.states \
        else np.zeros((len(t), 0))
    checks.append(row("dynamics per piece", ph.name, math.inf, tol, str(failure).rstrip("."), "not flown"))
    unknown = np.full(len(ph.states) + len(ph.integrals), np.nan)
    run = _PhaseRun(t, X, state_scale(X), np.ones(len(ph.integrals)), unknown, unknown, None)
    run.notes.append("the verification's integrators cannot fly this trajectory to its end (a law that "
                     "diverges leaves nothing to check after that); the other laws are judged on their own")
    return run


def _reported_integral_checks(problem, result, runs, tol, checks) -> None:
    """Each integral a back end reports (``result.extra["reported_integrals"]``, name ->
    value: a controller's cost from its fixed-step simulation) against the same integral
    carried along the verification's pieces, relative to its size (floored at the NLP's
    resolution)."""
    reported = result.extra.get("reported_integrals") or {}
    for ph in problem.phases:
        run = runs.get(ph.name)
        n = len(ph.states)
        for k, s in enumerate(ph.integrals):
            if s.name not in reported or run is None:
                continue
            flown, said = float(run.local_end[n + k]), float(reported[s.name])
            checks.append(row("cost", ph.name, abs(said - flown) / max(abs(flown), RESOLUTION), tol,
                              f"{s.name}: reported {said:.10g}, along the pieces {flown:.10g}",
                              "the reported integral against the same integral flown piece by piece"))


# a state's scale is at least this share of its travel, the integral of its rate's terms'
# absolute values (what the dynamics move it by before they cancel)
TRAVEL_SHARE = 1e-3


def _travel_floor(ph, funcs, uf, t, X, scale_x) -> np.ndarray:
    """``scale_x`` with each nearly constant state's (range below its scale) raised to
    TRAVEL_SHARE of its travel: x' = V cos(th) + w held at 0 (cos(th) = -w / V, Zermelo
    against a current), its rows 1e-11 apart, was measured against the NLP's resolution 1e-7
    and failed on a miss of 1.5e-12 while its terms move it by 1.15 over the crossing
    (unseen33 F13). Evaluated only where a dynamics check would fail."""
    flat = [j for j in range(funcs.n) if np.ptp(X[:, j]) < scale_x[j]]
    if not flat:
        return scale_x
    from .objective_size import additive_terms

    rates = ph.rhs()
    U = controls_at(uf, t, X)
    args = [TIME, *ph.states, *ph.controls]
    out = scale_x.copy()
    for j in flat:
        size = sp.Add(*(sp.Abs(term) for term in additive_terms(ph.substitute(rates[j]))))
        if size.free_symbols - set(args):
            continue
        with np.errstate(all="ignore"):
            values = np.broadcast_to(np.asarray(sp.lambdify(args, size, "numpy")(t, *X.T, *U.T), float), t.shape)
        travel = float(np.trapezoid(np.nan_to_num(values), t))
        out[j] = max(out[j], TRAVEL_SHARE * travel)
    return out


def _constant_state_note(err, X, scale_x, names_x, value: float, tol: float) -> dict:
    """``{"scale_note": ...}`` when the check fails on a state whose range over the phase is
    below its scale (a nearly constant state, measured against 1e-3 of its size or the NLP's
    resolution): the relative miss then stands for a small absolute one, which the message
    says (unseen21 FA2: a steady state x = 1/2 missed by 9e-8 read as "1.7e-4"). It does
    not invite a looser `verify: {tolerance}`: a state about 1e6 that travels 0.1 reads as nearly
    constant too, and there the miss was a trajectory 6.6e-4 below J* (unseen62 F4)."""
    if not value > tol or not err.size:
        return {}
    j = int(np.argmax(np.nanmax(np.where(np.isfinite(err), err, np.inf), axis=0)))
    spread = float(np.nanmax(X[:, j]) - np.nanmin(X[:, j]))
    if spread >= scale_x[j]:
        return {}
    return {"scale_note": (f"{names_x[j]} is nearly constant over the phase (range {spread:.2g}), so it is "
                           f"measured against {scale_x[j]:.2g}: the miss is {value * scale_x[j]:.2g} in its "
                           "units; a tighter solver `tol` lowers it where the solver is the cause, and a state "
                           "that travels little from a large value resolves better written as a deviation from "
                           f"it ({names_x[j]} = {float(np.nanmean(X[:, j])):.6g} + d{names_x[j]})")}


def _too_sensitive(funcs, uf, t, X, breaks, settings, scale, glob, v_global: float,
                   v_local: float) -> tuple[str, str]:
    """(why the flight from x(t0) cannot judge this phase, or ""; advice when it judges and its
    miss is not the pieces' defects grown along it, or ""). The first where it misses by
    ``v_global`` while every piece meets the dynamics (to ``v_local``), the flight amplifies a
    change of x(t0) by more than tolerance / rtol (beyond that its own integration error,
    amplified, can reach the tolerance), and that amplification of the pieces' defects
    accounts for the miss. x' = 10 x + u over t_f = 5: pieces within 2.8e-8, the flight 1.2e10
    off after e^50, J right to 1.7e-14 (unseen30 B)."""
    tol = settings.tolerance
    if not (tol < v_global < math.inf and v_local <= tol):
        return "", ""
    amp = flight_amplification(funcs, uf, t, X, breaks, settings.rtol, scale, glob)
    limit = tol / settings.rtol
    grown = amp * (len(breaks) - 1) * max(v_local, settings.rtol)
    if limit < amp < math.inf and v_global <= grown:
        return (f"the flight from x(t0) amplifies a change of x(t0) by {amp:.1e} (> tolerance / integrator "
                f"rtol = {limit:.0e}): the pieces' defects (at most {v_local:.1e}) account for its miss of "
                f"{v_global:.1e}, so it judges nothing; the dynamics, the boundary conditions and the objective "
                "are judged piece by piece. Flown open loop, this control will not reproduce the trajectory: "
                "fly it with feedback"), ""
    if math.isfinite(amp) and v_global > grown:
        # Van der Pol with mu = 100: pieces within 4.6e-8, amplification 2.5e4, the flight 87
        # off: a tighter tol left the numbers as they were (unseen30)
        return "", (f"every piece meets the dynamics (to {v_local:.1e}) and a change of x(t0) grows by "
                    f"{amp:.1e} along the flight, yet it misses by {v_global:.2g}, far more than those defects grown that much "
                    "would: it leaves the trajectory for another solution of the dynamics (their "
                    "nonlinearity), which neither a tighter solver `tol` nor more segments change; flown "
                    "open loop this control does not reproduce the trajectory (fly it with feedback), or "
                    "`verify: {mode: warn}` accepts the run")
    return "", ""


def _verify_phase(ph, traj, interpolation, params, settings, checks, tables,
                  wide_scale: dict[str, float] | None = None) -> _PhaseRun:
    tol = settings.tolerance
    stuck_note = sensitive = leaves = ""
    names_x = [s.name for s in ph.states]
    names_u = [c.name for c in ph.controls]
    t_all = np.asarray(traj.time, float)
    X_all = np.column_stack([np.asarray(traj.states[n], float) for n in names_x]) if names_x \
        else np.zeros((len(t_all), 0))
    keep = np.isfinite(t_all) & np.isfinite(X_all).all(axis=1)
    t, X = t_all[keep], X_all[keep]
    ubounds = bounds_of(ph, names_u, "controls")
    # a phase the optimum collapses (a hold of no length): its ends meet to the NLP's accuracy,
    # its rows' times out of order by as much (tf 1e-9 before t0: "the rows' times must
    # increase strictly", verification error on a right answer, unseen34 F3)
    span = max(1.0, float(np.max(np.abs(t)))) if len(t) else 1.0
    collapsed = len(t) >= 2 and ((np.any(np.diff(t) <= 0) and np.ptp(t) <= RESOLUTION * span)
                                 # or in order but of no length the NLP can resolve: a cruise
                                 # phase of 1.3e-10 in a horizon of 2 had v measured against 1e-7
                                 # and failed on a miss of 2.4e-11 (unseen44 F3)
                                 or np.ptp(t) <= COLLAPSED_SHARE * span)
    if len(t) >= 1 and (np.ptp(t) == 0 or collapsed):
        return _zero_duration_phase(ph, traj, t, X, names_x, names_u, ubounds, tol, checks, wide_scale)
    if len(t) < 2 or np.any(np.diff(t) <= 0):
        raise ValueError(f"phase {ph.name!r}: the rows' times must increase strictly (at least two rows)")
    funcs = PhaseFunctions(ph, params, ph.integrals)
    # between rows: the interpolant clipped to its box, projected onto what path constraints
    # affine in one control allow at the state (verify/admissible.py)
    uf = project(control_interpolant(traj, names_u, ubounds, interpolation), funcs, ubounds)
    breaks = breakpoints(traj, interpolation)
    breaks = np.unique(np.clip(np.concatenate([[t[0], t[-1]], breaks]), t[0], t[-1]))
    scale_x = state_scale(X)
    nq = len(funcs.integral_symbols)
    if nq:
        scale_q = integral_scales(funcs, t, X, controls_at(uf, t, X), scale_x, ubounds)
    else:
        scale_q = np.zeros(0)
    scale = np.concatenate([scale_x, scale_q])
    glob, local = reintegrate(funcs, uf, t, X, breaks, settings.rtol, scale, settings.per_interval,
                              settings.open_loop)
    at_rows = np.searchsorted(glob.t, t)
    pname = ph.name
    if funcs.n:
        miss_g = np.abs(glob.Y[at_rows, :funcs.n] - X)
        miss_l = np.abs(local.Y[at_rows, :funcs.n] - X)
        if np.max(np.nan_to_num(np.maximum(miss_g, miss_l) / scale_x, nan=np.inf), initial=0.0) > tol:
            scale_x = _travel_floor(ph, funcs, uf, t, X, scale_x)
        eg, el = miss_g / scale_x, miss_l / scale_x
        v, where = worst(el, names_x, t)
        checks.append(row("dynamics per piece", pname, v, tol, where,
                          f"{len(breaks) - 1} pieces, {', '.join(sorted(local.methods))}",
                          **_constant_state_note(el, X, scale_x, names_x, v, tol)))
        if settings.open_loop:
            v_local = v
            v, where = worst(eg, names_x, t)
            global_row = row("dynamics from x(t0)", pname, v, tol, where,
                             f"{', '.join(sorted(glob.methods))}, {glob.steps} steps",
                             **_constant_state_note(eg, X, scale_x, names_x, v, tol))
            sensitive, leaves = _too_sensitive(funcs, uf, t, X, breaks, settings, scale, glob, v, v_local)
            if sensitive:
                global_row.update(passed=None, not_judged=sensitive)
                v = 0.0       # nothing stuck: the flight is not the judge
            checks.append(global_row)
            # a flight that never leaves a state's start value (rate exactly 0 there) while the
            # rows leave it: y' = sqrt(y) sin(theta) from y = 0 has y = 0 as a solution too, and
            # the integrator takes it (unseen21 FA5: a brachistochrone from rest at y = 0)
            stuck = [(n, float(X[0, j])) for j, n in enumerate(names_x)
                     if np.all(glob.Y[:, j] == glob.Y[0, j]) and np.max(np.abs(X[:, j] - X[0, j])) > tol * scale_x[j]
                     ] if v > tol else []
            if stuck:
                held = ", ".join(f"{n} at {x0:.6g}" for n, x0 in stuck)
                stuck_note = (f"the flight from x(t0) keeps {held} over the whole phase while the rows leave "
                              "them: their rates there are 0, and where the dynamics are not Lipschitz (a square "
                              "root at 0) another solution leaves; start a little off (e.g. "
                              f"{stuck[-1][0]}(t0) == {stuck[-1][1] + 1e-9 * max(1.0, abs(stuck[-1][1])):.9g})")
        table = {"t": glob.t}
        for j, n in enumerate(names_x):
            table[n] = glob.Y[:, j]
            table[f"err_{n}"] = np.interp(glob.t, t, eg[:, j])
        tables[f"reintegration_{pname}"] = table
    # bounds and path constraints on the dense grid, with the piece-by-piece states, and
    # between its points (an obstacle smaller than the grid's spacing sat between them)
    grid, Yl = local.t, local.Y
    if funcs.n and len(grid) >= 2:
        fine_t, fine_X = between_points(funcs, uf, grid, Yl[:, :funcs.n], settings.between)
        order = np.argsort(np.concatenate([grid, fine_t]), kind="stable")
        grid = np.concatenate([grid, fine_t])[order]
        Yl = np.concatenate([Yl[:, :funcs.n], fine_X])[order]
    Ug = controls_at(uf, grid, Yl[:, :funcs.n])
    sbounds = bounds_of(ph, names_x, "states")
    if any(math.isfinite(b) for lo_hi in sbounds for b in lo_hi):
        err = np.column_stack([relative_violation(Yl[:, j], lo, hi, scale_x[j])
                               for j, (lo, hi) in enumerate(sbounds)])
        v, where = worst(err, names_x, grid)
        checks.append(row("state bounds", pname, v, tol, where, f"{len(grid)} points"))
    _control_bounds_check(ph, traj, names_u, ubounds, tol, checks)
    if funcs.g is not None:
        G = funcs.g(grid, Yl[:, :funcs.n], Ug)
        gscale = path_scales(funcs, t, X, controls_at(uf, t, X), scale_x, ubounds, G)
        err = path_violations(funcs, grid, Yl[:, :funcs.n], Ug, G, scale_x, ubounds, gscale)
        t_err, detail = grid, f"{len(grid)} points"
        # a projected constraint holds between the rows by construction: at the rows it is
        # held with the exported controls and states, as the NLP held it
        tr, Gr, cols = row_values(funcs, uf, traj, names_u, t, X)
        if cols:
            er = np.zeros(Gr.shape)
            for k in cols:
                c = funcs.path[k]
                er[:, k] = relative_violation(Gr[:, k], c.lower, c.upper, gscale[k])
            err, t_err = np.vstack([err, er]), np.concatenate([grid, tr])
            detail += f" and {len(tr)} exported rows"
        v, where = worst(err, [c.text or str(c.expr) for c in funcs.path], t_err)
        flat = np.nan_to_num(err, nan=np.inf)
        at = float(t_err[np.unravel_index(np.argmax(flat), flat.shape)[0]]) if flat.size else math.nan
        checks.append(row("path constraints", pname, v, tol, where, detail,
                          at_start=bool(at <= t[0] + 1e-12 * max(1.0, abs(t[-1] - t[0])))))
    end_rate = funcs.augmented_point(float(t[-1]), local.Y[-1],
                                     controls_at(uf, t[-1:], local.Y[-1:, :funcs.n])[0])
    run = _PhaseRun(t, X, scale_x, scale_q, glob.Y[-1], local.Y[-1], uf, end_rate, flight_not_judged=sensitive)
    if stuck_note or leaves:
        run.notes.append(stuck_note or leaves)
    return run


def _control_bounds_check(ph, traj, names_u, ubounds, tol, checks) -> None:
    """The exported controls, row by row, against their bounds."""
    if not names_u or not any(math.isfinite(b) for lo_hi in ubounds for b in lo_hi):
        return
    tr, Ur = control_rows(traj, names_u)
    scale_u = np.array([hi - lo if math.isfinite(hi - lo) and hi > lo else
                        max(float(np.ptp(Ur[:, j])) if len(Ur) else 0.0, 1e-12)
                        for j, (lo, hi) in enumerate(ubounds)])
    err = np.column_stack([relative_violation(Ur[:, j], lo, hi, scale_u[j])
                           for j, (lo, hi) in enumerate(ubounds)])
    v, where = worst(err, names_u, tr)
    checks.append(row("control bounds", ph.name, v, tol, where, f"{len(tr)} exported rows"))


def _zero_duration_phase(ph, traj, t, X, names_x, names_u, ubounds, tol, checks,
                         wide_scale: dict[str, float] | None = None) -> _PhaseRun:
    """A phase that takes no time (e.g. a wait of length 0): nothing to integrate; its rows
    must all hold one state, its integrals are zero and its ends are that state. Each state is
    measured against its scale over the whole problem (``wide_scale``): over no time, its own
    rows' range is the NLP's noise (v 1e-9 +- 9e-10 failed against 1e-7, unseen34 F3)."""
    scale_x = state_scale(X)
    if wide_scale:
        scale_x = np.maximum(scale_x, [wide_scale.get(n, 0.0) for n in names_x])
    if names_x:
        v, where = worst(np.abs(X - X[0]) / scale_x, names_x, t)
        checks.append(row("dynamics per piece", ph.name, v, tol, where,
                          "zero duration: every row must hold the same state"))
    _control_bounds_check(ph, traj, names_u, ubounds, tol, checks)
    tr, Ur = control_rows(traj, names_u)
    first = Ur[:1] if len(Ur) else np.zeros((1, len(names_u)))
    uf = _Tabulated(t[:1], first, ubounds, "previous")
    nq = len(ph.integrals)
    end = np.concatenate([X[0], np.zeros(nq)])
    return _PhaseRun(t, X, scale_x, np.full(nq, 1e-12), end, end, uf)


def _d_dtf(expr: sp.Expr, ph, run: _PhaseRun, problem, point) -> float:
    """d expr / d t_f of phase ``ph`` with everything else held: through x(t_f) (its rate
    f(x(t_f), u(t_f))), the phase's integrals (their integrands at t_f) and t_f itself."""
    n = len(ph.states)
    total = 0.0
    for s in expr.free_symbols:
        if s == ph.tf_symbol:
            rate = 1.0
        elif s in ph.integrals:
            rate = float(run.end_rate[n + list(ph.integrals).index(s)])
        elif s in problem.boundary_values and problem.boundary_values[s].phase == ph.name \
                and problem.boundary_values[s].which == "tf" and problem.boundary_values[s].var in ph.states:
            rate = float(run.end_rate[list(ph.states).index(problem.boundary_values[s].var)])
        else:
            continue
        total += evaluate(sp.diff(expr, s), point) * rate
    return total


# the objective's first-order size above this many times |J|: its check is that much looser
# than the tolerance of J, and the verdict says so
PRECISION_SHARE = 10.0
# a state smaller than this share of the NLP's resolution is noise about 0 (an identically zero
# state at 1e-26), not a quantity in units too large
RESOLUTION_FLOOR_SHARE = 1e-4


def _objective_precision(problem, runs, J: float, size: float, tol: float) -> dict:
    """``{"precision": ...}`` when the objective is checked against a first-order size (what
    J moves when the states, controls and integrals move by their scales) far above |J|: the
    checks then hold J only to tolerance x that size. A furnace in kelvin (T from 1199.9 to
    the cap 1199.97, cost (T - 1200)^2, J = 0.0204) was "verified" 5.6e-5 below its optimum
    with T 1.2e-6 K over its cap: T is measured against 1e-3 of its size, 1.2 K, and J
    against 1.48 (unseen32)."""
    if not (math.isfinite(J) and J != 0.0 and size > PRECISION_SHARE * abs(J)):
        return {}
    # a state measured against more than its range: against 1e-3 of its size (a rewrite as a
    # deviation resolves it), or against the NLP's resolution (its units are too large; a
    # deviation changes nothing: x2 from 0 to 1e-8 was told to write x2 = 5e-9 + dx2, unseen47 F5)
    flat, small = [], []
    for ph in problem.phases:
        run = runs.get(ph.name)
        for j, s in enumerate(ph.states if run is not None and len(run.X) else ()):
            spread, size_ = float(np.ptp(run.X[:, j])), float(np.max(np.abs(run.X[:, j])))
            if spread >= run.scale_x[j] or size_ == 0.0:
                continue
            if spread < 1e-3 * size_:
                flat.append((s.name, spread, size_, 0.5 * float(np.max(run.X[:, j]) + np.min(run.X[:, j]))))
            elif size_ >= RESOLUTION_FLOOR_SHARE * RESOLUTION:
                small.append((s.name, size_))
    text = (f"J is held to its first-order size {size:.3g} (what it moves when the states, controls and "
            f"integrals move by their scales), {size / abs(J):.3g} times |J|: verified to {tol * size:.2g} "
            f"in its units, {tol * size / abs(J):.1e} of J, not {tol:g} of J")
    if small:
        one = len(small) == 1
        text += (f"; {', '.join(f'{n} (size {z:.2g})' for n, z in small)} {'spans' if one else 'span'} less than "
                 f"the NLP resolves ({RESOLUTION:g}) and {'is' if one else 'are'} measured against that: "
                 f"write {'it' if one else 'them'} in smaller units (a factor of 1e3 or more) to resolve "
                 f"{'it' if one else 'them'}")
    if flat:
        one = len(flat) == 1
        name, _, _, mid = flat[0]
        text += (f"; {', '.join(f'{n} (range {r:.2g}, size {z:.3g})' for n, r, z, _ in flat)} "
                 f"{'varies' if one else 'vary'} little against {'its' if one else 'their'} size and "
                 f"{'is' if one else 'are'} measured against 1e-3 of it: write {'it' if one else 'each'} as a "
                 f"deviation from a reference ({name} = {mid:.4g} + d{name}) to resolve {'it' if one else 'them'}, "
                 "and J with it")
    return {"precision": text}


def _free_final_time_checks(problem, runs, point, scales, tol, checks) -> None:
    """First-order optimality in a free final time, where it needs no multiplier: when t_f
    is strictly inside its bounds and no active constraint moves with it, the objective
    must be stationary in t_f (d J / d t_f = 0: ending a little earlier or later is feasible
    and, were the derivative not zero, better). A solution stopped at the guess of t_f
    (tumour, LG 12 x 4: 3.2e-3 late, the end of the dose on a segment boundary) is
    feasible, flies exactly, and is caught only here."""
    obj = problem.objective
    j_scale = max(sensitivity_scale(obj.expr, point, scales), 1e-12)
    for ph in problem.phases:
        run = runs[ph.name]
        if ph.tf is not None or run.end_rate is None or not np.all(np.isfinite(run.end_rate)):
            continue
        T, duration = float(run.t[-1]), max(float(run.t[-1] - run.t[0]), 1e-12)
        lo, hi = ph.tf_bounds
        if min(T - lo, hi - T) <= tol * duration:
            continue                              # at a bound: its multiplier is unknown
        moving = False
        pinned = _controls_on_bounds_at_end(ph, run, tol)   # none left to correct a miss at t_f
        resting = []        # final equalities met with their states at rest
        for c in problem.boundary:
            v = evaluate(c.expr, point)
            sc = sensitivity_scale(c.expr, point, scales)
            active = c.lower == c.upper or min(abs(v - c.lower), abs(c.upper - v)) <= tol * sc
            if active and abs(_d_dtf(c.expr, ph, run, problem, point)) * duration > tol * sc:
                moving = True
                break
            if c.lower == c.upper and any(problem.boundary_values[s].phase == ph.name
                                          and problem.boundary_values[s].which == "tf"
                                          for s in c.expr.free_symbols if s in problem.boundary_values):
                resting.append(c.text or str(c.expr))      # an equality at t_f that t_f does not move
            if pinned and c.lower == c.upper and _arrives_with_zero_rate(c.expr, ph, run, problem, tol):
                # met at second order (h' = -sqrt(h) + u reaches h = 0 with rate 0): ending
                # earlier misses it all the same, so the first-order test does not apply
                # (unseen21 FA4: Torricelli's tank, tf exact, "stopped short of the optimum")
                moving = True
                break
        if moving or _held_at_the_end(ph, run, tol):
            continue
        g = _d_dtf(obj.expr, ph, run, problem, point)
        if g == 0.0 and not (obj.expr.free_symbols & ({ph.tf_symbol} | set(ph.integrals))):
            continue                              # the objective does not depend on this t_f
        more = {}
        earlier = (g > 0) == (obj.sense != "maximize")      # J improves by ending earlier
        if resting and earlier:
            # a target met with its states at rest: reached only as t -> infinity (x' = -x + u,
            # u <= 1, x(tf) = 1), or held for any later t_f; "the solver stopped short ... start
            # from another tf" moved the answer to another arbitrary t_f (unseen47 F3)
            more["hint"] = (f"`{resting[0]}` is met with its states at rest at t_f (they no longer move it): a "
                            "target approached only as t_f grows (then no finite t_f reaches it, and Ipopt "
                            "stopped where the miss fell below its tolerance), or one that every later t_f "
                            "meets as well; check that it is reachable in finite time before refining")
        checks.append(row("free final time", ph.name, abs(g) * duration / j_scale, tol,
                          f"dJ/dtf = {g:.6g} at tf = {T:.10g}",
                          "objective stationary in tf (no active constraint moves with it)", **more))


def _controls_on_bounds_at_end(ph, run, tol: float) -> bool:
    """Every control of the phase on one of its bounds at t_f (within ``tol`` of the bound's
    size): none is left to correct the second-order miss of a condition reached with rate 0
    (``_arrives_with_zero_rate``). With an interior control that miss costs second order only,
    and J must still be stationary in t_f."""
    T = float(run.t[-1])
    u_end = controls_at(run.uf, np.array([T]), run.X[-1:])[0] if len(ph.controls) else []
    for (lo, hi), u in zip(bounds_of(ph, [c.name for c in ph.controls], "controls"), u_end):
        size = tol * max(1.0, abs(lo) if math.isfinite(lo) else 0.0, abs(hi) if math.isfinite(hi) else 0.0)
        if not (abs(u - lo) <= size or abs(hi - u) <= size):
            return False
    return True


def _arrives_with_zero_rate(expr, ph, run, problem, tol: float) -> bool:
    """A condition on this phase's x(t_f) whose states were still moving over the last
    twentieth of the phase (beyond ``tol`` of their scale): reached at t_f, not rested on (a
    state that rests on its value, Goddard's m = 0.6 while coasting, keeps the check)."""
    duration = float(run.t[-1] - run.t[0])
    tail = run.t >= run.t[-1] - 0.05 * duration
    for s in expr.free_symbols:
        bv = problem.boundary_values.get(s)
        if bv is None or bv.phase != ph.name or bv.which != "tf" or bv.var not in ph.states:
            continue
        j = list(ph.states).index(bv.var)
        if np.max(np.abs(run.X[tail, j] - run.X[-1, j])) > tol * run.scale_x[j]:
            return True
    return False


def _held_at_the_end(ph, run, tol: float) -> bool:
    """A state bound or path constraint active at t_f: ending later is then not free (x <= 0.3
    reached at t_f stops x(t_f) from growing), J is not differentiable in t_f there and its
    one-sided dJ/dt_f need not vanish (unseen #29: exact optimum, dJ/dtf = -0.7). A state
    that rests on its bound at t_f (rate 0: Goddard's m = 0.6 once the thrust is off) holds
    nothing: ending a little later or earlier keeps it there."""
    x_end = run.X[-1]
    duration = max(float(run.t[-1] - run.t[0]), 1e-12)
    for j, s in enumerate(ph.states):
        lo, hi = ph.state_bounds.get(s, (-INF, INF))
        size = tol * max(run.scale_x[j], abs(x_end[j]))
        arriving = abs(float(run.end_rate[j])) * duration > size
        if arriving and min(abs(x_end[j] - lo), abs(hi - x_end[j])) <= size:
            return True
    if not ph.path:
        return False
    T = float(run.t[-1])
    at_end = {TIME: T} | dict(zip(ph.states, map(float, x_end))) \
        | dict(zip(ph.controls, map(float, controls_at(run.uf, np.array([T]), run.X[-1:])[0])))
    for c in ph.path:
        v = evaluate(ph.substitute(c.expr), at_end)
        size = max(abs(v), *(abs(b) for b in (c.lower, c.upper) if math.isfinite(b)), 1e-12)
        if min(abs(v - c.lower), abs(c.upper - v)) <= tol * size:
            return True
    return False


def _points(problem, result, runs, params, which: str):
    """Symbol -> value of every boundary quantity, with the re-integrated ends (``which`` =
    "global" or "local"), the phases' times, the integrals, free parameters and constants."""
    point: dict[sp.Symbol, float] = {sp.Symbol(k, real=True): v for k, v in params.items()}
    scales: dict[sp.Symbol, float] = {}
    span = max((float(np.max(np.abs(runs[ph.name].t))) for ph in problem.phases if len(runs[ph.name].t)),
               default=1.0)
    for ph in problem.phases:
        run = runs[ph.name]
        end = run.glob_end if which == "global" else run.local_end
        n = len(ph.states)
        point[ph.t0_symbol], point[ph.tf_symbol] = float(run.t[0]), float(run.t[-1])
        duration = max(float(run.t[-1] - run.t[0]), 1e-12)
        if duration <= RESOLUTION * max(1.0, span):
            # a collapsed phase's times are measured on the problem's clock: tf 1e-9 before t0
            # failed `tf >= t0` by 500 times the tolerance against its own length (unseen34 F3)
            duration = max(span, 1e-12)
        scales[ph.t0_symbol] = scales[ph.tf_symbol] = duration
        for k, s in enumerate(ph.integrals):
            point[s], scales[s] = float(end[n + k]), float(run.scale_q[k])
    for s, bv in problem.boundary_values.items():
        run = runs[bv.phase]
        ph = problem.phase(bv.phase)
        states = [x for x in ph.states]
        if bv.var in states:
            j = states.index(bv.var)
            end = run.glob_end if which == "global" else run.local_end
            point[s] = float(run.X[0, j] if bv.which == "t0" else end[j])
            scales[s] = float(run.scale_x[j])
        else:       # a control at a boundary: the interpolated control there
            j = list(ph.controls).index(bv.var)
            i = 0 if bv.which == "t0" else -1
            point[s] = float(controls_at(run.uf, run.t[i:][:1], run.X[i:][:1])[0, j])
            scales[s] = max(abs(point[s]), 1e-6)
    for s in problem.free_parameters:
        if s.name in params:
            point[s] = params[s.name]
            scales[s] = max(abs(params[s.name]), 1e-6)
    return point, scales


def _boundary_checks(problem, result, runs, params, tol, checks, open_loop: bool = True) -> None:
    declared = _numbers(result.extra.get("terminal_tolerances", {}) or {})
    integral_symbols = set(problem.integrals)
    passes = (("global", "from x(t0)"), ("local", "per piece")) if open_loop else (("local", "per piece"),)
    # the ends of a phase whose flight from x(t0) judges nothing judge nothing either
    unjudged = "; ".join(f"phase {name}: {run.flight_not_judged}" if len(runs) > 1 else run.flight_not_judged
                         for name, run in runs.items() if run.flight_not_judged)
    for which, label in passes:
        point, scales = _points(problem, result, runs, params, which)
        first = len(checks)
        groups: dict[str, list] = {"boundary conditions": [], "integral constraints": []}
        for c in problem.boundary:
            v = evaluate(c.expr, point)
            sc = sensitivity_scale(c.expr, point, scales)
            viol = float(relative_violation(np.array([v]), c.lower, c.upper, 1.0)[0])
            text = c.text or str(c.expr)
            kind = "integral constraints" if c.expr.free_symbols & integral_symbols else "boundary conditions"
            if text in declared:
                groups[kind].append((viol / declared[text], f"{text} (declared tolerance {declared[text]:g})",
                                     1.0))
            else:
                groups[kind].append((viol / sc, text, tol))
        for kind, items in groups.items():
            if not items:
                continue
            ratio = [v / lim for v, _, lim in items]
            k = int(np.nanargmax(np.where(np.isfinite(ratio), ratio, np.inf)))
            value, where, limit = items[k]
            checks.append(row(f"{kind}", None, value, limit, where, f"{len(items)} conditions, {label}",
                              trajectory=which))
        if which == "local":
            _free_final_time_checks(problem, runs, point, scales, tol, checks)
        obj = problem.objective
        if result.objective is not None and math.isfinite(float(result.objective)):
            J = evaluate(obj.expr, point)
            sc = max(sensitivity_scale(obj.expr, point, scales), 1e-12)
            checks.append(row("objective", None, abs(J - float(result.objective)) / sc, tol,
                              f"recomputed {J:.10g}, solver {float(result.objective):.10g}", label,
                              trajectory=which, **(_objective_precision(problem, runs, float(result.objective), sc, tol)
                                                   if which == "local" else {})))
        if which == "global" and unjudged:
            for c in checks[first:]:
                c.update(passed=None, not_judged=unjudged)
