"""Run closed-loop controller studies and package them as :class:`ocdsl.result.Result`.

``run_controllers(model, specs)`` builds the SDC factorisation (``sdc: auto|given``),
lambdifies it, designs each law (LQR, SDRE, Theta-D), simulates the closed loop and
returns one Result per law: status ``stable``/``unstable`` (``error`` with the diagnosis
when a law cannot be designed, e.g. an unstabilisable pair), objective = the cost
1/2 int (x^T Q x + u^T R u) dt, the closed-loop history as the ``main`` phase and as the
table ``closed_loop`` (with the unsaturated control and the controller time of each
update), and ``extra`` with metrics (overshoot, settling, max |x| after check times),
timing statistics and controller data (K, T0, closed-loop eigenvalues).

``robustness_sweep(model, spec)`` designs the laws on the nominal parameters and runs
them on plants whose parameters (``robustness.parameters``) are multiplied by each
factor; the result is one Result whose table ``robustness`` has one row per factor and
columns ``<law>.<quantity>``.
"""
from __future__ import annotations

import time
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ocdsl.result import PhaseTrajectory, Result
from ocdsl.spec.controller import ControllerSpec, degree_inputs, to_number
from ocdsl.symbolic import sdc as sdcmod
from ocdsl.symbolic.model import Model

from .lqr import ControlError, LQRController
from .sdre import SDREController
from .simulate import metrics, saturation_limits, simulate
from .theta_d import ThetaDController


def _as_spec(spec) -> ControllerSpec:
    return spec if isinstance(spec, ControllerSpec) else ControllerSpec.model_validate(spec)


def build_sdc(model: Model, spec: ControllerSpec) -> sdcmod.SDC:
    """The SDC factorisation the spec asks for (auto with its split, or given A/B)."""
    if spec.sdc == "auto":
        return sdcmod.factorise(model, auxiliary=spec.auxiliary, states=spec.states, split=spec.split)
    xs, _ = sdcmod._split_states(model, spec.auxiliary, spec.states)
    n, m = len(xs), len(model.controls)
    syms = model.symbols()
    A = spec.given_matrix("A", (n, n), syms)
    B = spec.given_matrix("B", (n, m), syms)
    return sdcmod.given(model, A, B, auxiliary=spec.auxiliary, states=spec.states)


def make_controller(kind: str, num: sdcmod.NumericSDC, spec: ControllerSpec):
    n, m = num.sdc.n, num.sdc.m
    Q, R = spec.matrix("Q", n), spec.matrix("R", m)
    if kind == "lqr":
        return LQRController(num, Q, R)
    if kind == "sdre":
        return SDREController(num, Q, R)
    if kind == "theta-d":
        td = spec.theta_d
        A0 = td.A0 if isinstance(td.A0, str) else np.asarray(td.A0, float)
        return ThetaDController(num, Q, R, terms=td.terms, k=td.k, a=td.a, A0=A0, lyapunov=td.lyapunov)
    raise ValueError(f"unknown controller type {kind!r}")


def _problem(model: Model, sdc: sdcmod.SDC, saturation=None) -> dict:
    """The run's problem description; a ``saturation`` is written as the controls' bounds
    (``bounds_are: saturation``), which the closed loop clips every command to: the report
    tabulates and draws them (unseen33: bounds "—" beside a command held at -10 N m)."""
    f = model.rhs()
    controls = [str(u) for u in model.controls]
    try:
        lo, hi = saturation_limits(saturation, len(controls))
    except ValueError:          # said by the simulation, which the run reports
        lo = hi = None
    bounds = {} if lo is None else {c: [float(a), float(b)] for c, a, b in zip(controls, lo, hi)}
    return {"name": model.name, "description": model.description,
            "phases": {"main": {"states": [str(s) for s in model.states],
                                "controls": controls,
                                "dynamics_latex": {str(s): sp.latex(f[i]) for i, s in enumerate(model.states)},
                                "bounds": bounds, "constraints": [], "constraints_latex": [],
                                "t0": 0.0, "tf": None}},
            **({"bounds_are": "saturation"} if bounds else {}),
            "parameters": {str(k): {"value": v, "free": False} for k, v in model.parameters.items()},
            "units": dict(model.units), "positions": list(model.positions),
            "sdc": {"method": sdc.method, "controlled_states": [str(s) for s in sdc.states],
                    "auxiliary_states": [str(s) for s in sdc.auxiliary],
                    "A_latex": sp.latex(sdc.A), "B_latex": sp.latex(sdc.B)}}


def _jsonable_info(d: dict) -> dict:
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in d.items()}


def run_one(model: Model, spec: ControllerSpec, kind: str, sdc: sdcmod.SDC,
            num: sdcmod.NumericSDC, parameters: Mapping | None = None,
            label: str | None = None, t_symbolic: float = 0.0) -> Result:
    """Design one law on ``num`` (its plant may be perturbed) and simulate it."""
    t0 = time.perf_counter()
    names = [str(s) for s in model.states]
    sim_spec = spec.simulate
    label = label or kind
    method = {"type": kind, "sdc": sdc.method, "integrator": sim_spec.integrator,
              "step": sim_spec.step, "update": sim_spec.update or sim_spec.step,
              "saturation": spec.saturation}
    if kind == "theta-d":
        method["theta_d"] = spec.theta_d.model_dump()
    params = {str(k): float(v) for k, v in model.default_parameters().items()}
    params.update({str(k): float(v) for k, v in (parameters or {}).items()})
    problem = _problem(model, sdc, spec.saturation)
    problem["phases"]["main"]["tf"] = sim_spec.horizon
    problem["display_units"] = {n: "deg" for n in degree_inputs(sim_spec.x0)}
    try:
        z0 = sim_spec.initial_state(names)
        n, m = sdc.n, sdc.m
        Q, R = spec.matrix("Q", n), spec.matrix("R", m)
        # pointwise checks at the origin and at the initial state
        zero = np.zeros(len(names))
        checks = sdcmod.check_pointwise(num, [zero, z0])
        where = "origin" if kind != "sdre" else "origin and x0"
        sdcmod.require_stabilisable(num, [zero] if kind != "sdre" else [zero, z0], f"{label} ({where})")
        ctrl = make_controller(kind, num, spec)
    except (ControlError, sdcmod.SDCError, ValueError) as exc:
        return Result(name=f"{model.name}:{label}", status="error", message=str(exc),
                      method=method, parameters=params, problem=problem,
                      wall_time_s={"total": time.perf_counter() - t0 + t_symbolic})
    t1 = time.perf_counter()
    bands = [to_number(b) for b in sim_spec.settle_bands]
    try:
        sim = simulate(num.f, ctrl, z0, num.index, Q, R, sim_spec.horizon, sim_spec.step,
                       sim_spec.update, sim_spec.integrator, spec.saturation, sim_spec.stable_ratio, names=names)
    except ControlError as exc:
        return Result(name=f"{model.name}:{label}", status="unstable", message=str(exc),
                      method=method, parameters=params, problem=problem,
                      wall_time_s={"total": time.perf_counter() - t0 + t_symbolic})
    t2 = time.perf_counter()
    if sim.status == "unstable" and "not regulated within the horizon" in sim.message:
        sim.message += _slow_loop_note(num, Q, R, sim_spec.horizon)
    met = metrics(sim, names, sim_spec.metric_states, bands, sim_spec.check_times, R)
    controls = [str(u) for u in model.controls]
    phase = PhaseTrajectory("main", sim.t, states={nm: sim.z[:, i] for i, nm in enumerate(names)},
                            controls={c: sim.u[:, j] for j, c in enumerate(controls)},
                            extra={"cost": sim.cost}, control_interpolation={"kind": "previous"})
    every = int(round((sim_spec.update or sim_spec.step) / sim_spec.step))
    ctime = np.full(len(sim.t), np.nan)
    ctime[::every][:len(sim.ctrl_time)] = sim.ctrl_time[:len(ctime[::every])]
    table = {"t": sim.t, **{nm: sim.z[:, i] for i, nm in enumerate(names)},
             **{c: sim.u[:, j] for j, c in enumerate(controls)},
             **{f"{c}_unsaturated": sim.u_raw[:, j] for j, c in enumerate(controls)},
             "cost": sim.cost, "controller_time_s": ctime}
    info = _jsonable_info(ctrl.info())
    extra = {"controller": label, "kind": kind, "metrics": met, "controller_info": info,
             "pointwise_checks": [{"at": "origin" if i == 0 else "x0", "controllability_rank": c.rank,
                                   "n": c.n, "stabilisable": c.stabilisable} for i, c in enumerate(checks)],
             "x0": z0.tolist(), "Q": Q.tolist(), "R": R.tolist()}
    return Result(name=f"{model.name}:{label}", status=sim.status, message=sim.message,
                  objective=sim.J, tf=float(sim.t[-1]), iterations=int(sim.ctrl_time.size),
                  wall_time_s={"total": time.perf_counter() - t0 + t_symbolic, "symbolic": t_symbolic,
                               "build": t1 - t0, "solve": t2 - t1, "post": time.perf_counter() - t2},
                  method=method, parameters=params, phases=[phase], problem=problem,
                  extra=extra, tables={"closed_loop": table})


def _slow_loop_note(num, Q, R, horizon: float) -> str:
    """What the loop's linearisation at the origin says of a run not regulated within its
    horizon: every law there is the LQR on (A(0), B(0)). A stable but slow loop reads as
    `unstable` (unseen37 F3, the TORA benchmark: eigenvalues -0.084 +- 1.0i, ratio 0.0144 at
    60 s, 1e-5 at 150 s); the note says how many of its time constants the horizon spans."""
    from .lqr import lqr

    try:
        z = np.zeros(len(num.sdc.model.states))
        _, _, eig = lqr(num.A(z), num.B(z), Q, R)
    except Exception:  # noqa: BLE001 - a note, never a failure
        return ""
    slowest = float(np.max(np.real(eig)))
    if not slowest < 0:
        return ""
    tau = -1.0 / slowest
    return (f" (its linearisation at the origin is stable, slowest eigenvalue real part {slowest:.3g}: a time "
            f"constant of {tau:.3g}, of which the horizon {horizon:g} spans {horizon / tau:.2g}; a longer "
            "`simulate.horizon` shows whether it regulates)")


def run_controllers(model: Model, spec_list: Sequence[ControllerSpec | dict],
                    parameters: Mapping | None = None,
                    plant_parameters: Mapping | None = None) -> list[Result]:
    """One Result per law of each spec (a spec with ``type: [lqr, sdre, theta-d]`` gives 3).

    ``parameters`` (name -> value) override the model defaults for controller and plant;
    ``plant_parameters`` override them for the plant only (model mismatch).
    """
    results = []
    for raw in spec_list:
        spec = _as_spec(raw)
        ts = time.perf_counter()
        try:
            sdc = build_sdc(model, spec)
            num = sdcmod.lambdify_sdc(sdc, parameters, plant_parameters)
        except (sdcmod.SDCError, ValueError, NotImplementedError) as exc:
            for one in spec.expand():
                results.append(Result(name=f"{model.name}:{one.name}", status="error",
                                      message=str(exc), method={"type": one.type}))
            continue
        t_sym = time.perf_counter() - ts
        for one in spec.expand():
            results.append(run_one(model, one, one.type, sdc, num, parameters, one.name, t_sym))
            results[-1].extra["plant_parameters"] = {str(k): float(v) for k, v in (plant_parameters or {}).items()}
    return results


def summary_table(results: Sequence[Result]) -> dict[str, np.ndarray]:
    """One row per law: its name, status, cost, max |metric states| after check times, timing."""
    cols: dict[str, list] = {"law": [], "status": [], "cost": [], "controller_time_mean_s": []}
    keys: list[str] = []
    for r in results:
        met = r.extra.get("metrics", {})
        for k in met:
            if (k.startswith("settling_time@") or k.startswith("max_abs_after@")) and k not in keys:
                keys.append(k)
    for k in keys:
        cols[k] = []
    for r in results:
        met = r.extra.get("metrics", {})
        cols["law"].append(r.extra.get("controller") or r.name.split(":")[-1])
        cols["status"].append(r.status)
        cols["cost"].append(r.objective if r.objective is not None else np.nan)
        cols["controller_time_mean_s"].append(met.get("controller_time_s", {}).get("mean", np.nan))
        for k in keys:
            cols[k].append(met.get(k, np.nan))
    return {k: np.asarray(v, str if k in ("law", "status") else float) for k, v in cols.items()}


def robustness_sweep(model: Model, spec: ControllerSpec | dict, factors: Sequence[float] | None = None,
                     scaled: Sequence[str] | None = None, parameters: Mapping | None = None) -> Result:
    """The spec's laws, designed on nominal parameters, on plants with scaled parameters.

    ``scaled`` (default ``spec.robustness.parameters``) are multiplied by each of
    ``factors`` (default ``spec.robustness.factors``) in the plant only. Returns one
    Result with the table ``robustness``: a row per factor, columns ``<law>.stable``,
    ``<law>.cost``, ``<law>.max_abs_after@T`` and ``<law>.settling_time@band`` and
    ``<law>.peak_control``.
    """
    spec = _as_spec(spec)
    if factors is None or scaled is None:
        if spec.robustness is None:
            raise ValueError("robustness_sweep needs factors and parameters (or a robustness: block)")
        factors = spec.robustness.factors if factors is None else factors
        scaled = spec.robustness.parameters if scaled is None else scaled
    t0 = time.perf_counter()
    nominal = {str(k): float(v) for k, v in model.default_parameters().items()}
    nominal.update({str(k): float(v) for k, v in (parameters or {}).items()})
    for p in scaled:
        if p not in nominal:
            raise ValueError(f"robustness: model {model.name!r} has no parameter {p!r} with a value")
    sdc = build_sdc(model, spec)
    laws = spec.types()
    table: dict[str, list] = {"factor": []}
    failures = []
    per_run = []
    for fac in factors:
        plant = {p: nominal[p] * fac for p in scaled}
        num = sdcmod.lambdify_sdc(sdc, parameters, plant)
        table["factor"].append(fac)
        for one in spec.expand():
            r = run_one(model, one, one.type, sdc, num, parameters, one.name)
            met = r.extra.get("metrics", {})
            row = {"stable": 1.0 if r.status == "stable" else 0.0,
                   "cost": r.objective if r.objective is not None else np.nan,
                   "peak_control": max(met.get("peak_control", [np.nan]))}
            for k, v in met.items():
                if k.startswith("settling_time@") or k.startswith("max_abs_after@"):
                    row[k] = v
            for k, v in row.items():
                table.setdefault(f"{one.type}.{k}", []).append(v)
            if r.status != "stable":
                failures.append(f"{one.type} at x{fac:g}: {r.status} ({r.message})")
            per_run.append({"law": one.type, "factor": fac, "status": r.status, "message": r.message,
                            "cost": r.objective})
    n = len(table["factor"])
    cols = {k: np.asarray(v + [np.nan] * (n - len(v)), float) for k, v in table.items()}
    return Result(name=f"{model.name}:robustness", status="unstable" if failures else "stable",
                  message="; ".join(failures) if failures else
                  f"all of {laws} stable for factors {list(factors)} on {list(scaled)}",
                  method={"type": "robustness", "laws": laws, "scaled": list(scaled), "factors": list(factors)},
                  parameters=nominal, wall_time_s={"total": time.perf_counter() - t0},
                  problem=_problem(model, sdc, spec.saturation), extra={"runs": per_run}, tables={"robustness": cols})
