"""Seed 1 "class mode": the optimum of the paper's own control class, found by collocation.

Paper mode searches the Fourier class (thrust angles delta, phi as half-range Fourier
series in t/t_f, eq. 24) by single shooting: a swarm, then least squares and SLSQP on the
shooting map. Over 5-25 revolutions that map is badly conditioned, and those local stages
stop where their line searches fail. This module finds a local optimum of the *same*
class (same series, same orders, same boundary states and revolution class) by direct
collocation instead, and then checks it with the paper-mode fitness itself:

1. the control of an optimal-mode run (unrestricted direction, LGR, synodic Cartesian, in
   the Sundman variable) is written as the paper's angles (delta from the transverse
   toward the radial direction of the Earth-centred rotating frame, phi from +z) and the
   Fourier coefficients are fitted to it by ridge least squares (the half-range basis with
   both cosines and sines is nearly dependent, so an unregularised fit has huge
   cancelling coefficients);
2. a penalty homotopy: the collocation problem ``minimize T + w * integral(R^k (ed^2 +
   ep^2))`` with ``ed == delta - D(time/T)`` and ``ep == phi - P(time/T)`` at every node
   (D, P the series, T the physical final time, a free parameter with ``time(tf) == T``) is
   solved for increasing weights w, each from the previous solution. The deviations ed, ep
   are auxiliary controls so that each series appears once per node (with the series
   inside the integral instead, the first 10 N step was not done after 210 s; this form
   takes 45 s). Each step is
   a problem file written into the run folder (``stages/``) and solved by the ordinary
   pipeline, so every stage can be re-run with ``ocdsl run``;
3. the hard problem (``delta == D``, ``phi == P``) from the last step;
4. the coefficients and T are put into the paper-mode decision vector and the polar
   dynamics are integrated by the paper-mode fitness (DOP853 at the file's tolerance);
   if a terminal error is outside its zeta, least squares at fixed t_f brings it back.

Stages are kept in ``OUT_stages/``; a second call with the same arguments reuses every
stage whose problem file is unchanged (resume after an interruption).

Why not the hard problem straight from the fit: the fitted series differs from the
optimal control by 0.5-1.2 rad rms (order 5 cannot follow the per-revolution oscillation
of the in-plane angle), so the start is far from consistent; measured at 10 N: Ipopt
diverged into restoration within 35 iterations.

Start from a paper-mode run (``paper_run``, ``--from-paper``): its best particle is a class
member, so its trajectory (converted to the Sundman variable and the Cartesian frame as
optimal mode's warm start is) with ed = ep = 0 is a consistent start and only the hard
problem is solved. It stays in the basin the shooting stages found but reaches that basin's
minimum, where SLSQP on the shooting map stops early (measured, session 5: 2 N 7.24121 ->
7.16780 in 31 iterations, 10 N 1.94317 -> 1.93775, 5 N 3.08085 -> 3.07607). Any class
member can be written as such a start by :func:`member_run`; random members (10 at 10 N,
shot from uniform coefficients) all ended infeasible.

The terminal conditions are the paper's by default (``terminal="paper"``): its box
``|e_i| <= ratio * zeta_i`` on the polar terminal states, the ratio of its refine stage,
which is what paper mode's SLSQP solves; ``terminal="exact"`` keeps the optimal file's end
state.

Why warm-start options after the first step (``mu_strategy monotone``, ``mu_init 1e-6``,
bound pushes 1e-8): with Ipopt's defaults each re-solve starts by pushing the point away
from its bounds and raising the barrier, and at weights >= 80 (10 N) that start diverged.

Command line::

    python -m ocdsl.search.class_collocation configs/seed1_10N_paper.yaml --optimal RUN --out OUT
    python -m ocdsl.search.class_collocation configs/seed1_2N_paper.yaml \
        --optimal configs/seed1_2N_optimal.yaml --from-paper PAPER_RUN --out OUT --segments 300
"""
from __future__ import annotations

import argparse
import copy
import math
import sys
import time as _time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..angles import unwrap_finite
from ..result import PhaseTrajectory, Result, single_phase_result

DEFAULT_WEIGHTS = (0.01, 0.1, 1, 10, 20, 40, 60)
WARM_OPTIONS = {"mu_strategy": "monotone", "mu_init": 1e-6, "bound_push": 1e-8, "bound_frac": 1e-8,
                "slack_bound_push": 1e-8, "slack_bound_frac": 1e-8}
#: Ipopt options of the hard problem's attempts, in order, each from the last penalty step.
#: Measured at 10 N: from the same weight-60 point (parameters equal to 1e-8) the warm
#: options once converged in 52 iterations and once ended infeasible after 2475; the
#: defaults and adaptive mu from 1e-4 both went to restoration. The hard step is that
#: sensitive, so it is tried more than once and each attempt is recorded; each is capped at
#: 400 iterations (the converged attempt took 52, the failed ones ran into the thousands).
HARD_ATTEMPTS = ({**WARM_OPTIONS, "max_iter": 400}, {"max_iter": 400})
ANGLES = ("delta", "phi")
DEVIATIONS = {"delta": "ed", "phi": "ep"}


# ---------------------------------------------------------------------------------------
# the series, as the paper-mode decision vector names them
def coefficient_names(control: str, order: int) -> list[str]:
    """``control_a0, control_a1..aN, control_b1..bN``: the paper-mode decision vector's names."""
    return ([f"{control}_a0"] + [f"{control}_a{k}" for k in range(1, order + 1)]
            + [f"{control}_b{k}" for k in range(1, order + 1)])


def series_text(control: str, order: int, clock: str = "time", period: str = "T") -> str:
    """The half-range Fourier series of eq. 24 in the problem language, argument clock/period."""
    names = coefficient_names(control, order)
    terms = [f"{names[0]}/2"]
    terms += [f"{names[k]}*cos({k}*pi*{clock}/{period})" for k in range(1, order + 1)]
    terms += [f"{names[order + k]}*sin({k}*pi*{clock}/{period})" for k in range(1, order + 1)]
    return " + ".join(terms)


def basis(order: int, t: np.ndarray, T: float) -> np.ndarray:
    """Columns in the order of :func:`coefficient_names` (same as ocdsl.simulate's layout)."""
    k = np.arange(1, order + 1)
    w = np.pi * np.outer(t, k) / T
    return np.hstack([np.full((len(t), 1), 0.5), np.cos(w), np.sin(w)])


def fit_series(t: np.ndarray, values: np.ndarray, T: float, order: int, ridge: float = 1e-2,
               samples: int = 2000) -> np.ndarray:
    """Ridge least-squares coefficients of ``values(t)`` on [0, T], sampled uniformly in t."""
    tu = np.linspace(0.0, T, samples)
    vu = np.interp(tu, t, values)
    B = basis(order, tu, T)
    A = B.T @ B / samples + ridge * np.eye(B.shape[1])
    return np.linalg.solve(A, B.T @ vu / samples)


def ecrf_angles(x, y, ux, uy, uz, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """The paper's thrust angles of a synodic direction: delta (unwrapped), phi."""
    x, y, ux, uy, uz = (np.asarray(a, float) for a in (x, y, ux, uy, uz))
    rho = np.hypot(x + mu, y)
    radial = (ux * (x + mu) + uy * y) / rho
    transverse = (-ux * y + uy * (x + mu)) / rho
    return unwrap_finite(np.arctan2(radial, transverse)), np.arccos(np.clip(uz, -1.0, 1.0))


# ---------------------------------------------------------------------------------------
# the collocation problem file
def _cartesian_model(parameters: dict[str, float], sundman_k: float) -> dict[str, Any]:
    """Synodic CR3BP (eq. 8) in the Sundman variable, thrust along the ECRF angles."""
    return {
        "states": ["x", "y", "z", "vx", "vy", "vz", "m", "time"],
        "controls": ["delta", "phi", "ed", "ep"],
        "parameters": {k: float(v) for k, v in parameters.items()},
        "expressions": {
            "c": "Isp*g0*TU/(LU*1000)", "T_max": "thrust/m0*TU**2/(LU*1000)",
            "r1": "sqrt((x + mu)**2 + y**2 + z**2)", "r2": "sqrt((x + mu - 1)**2 + y**2 + z**2)",
            "rho": "sqrt((x + mu)**2 + y**2)", "rate": f"r1**{sundman_k}",
            "ar": "sin(delta)*sin(phi)", "ath": "cos(delta)*sin(phi)",
            "ux": "(ar*(x + mu) - ath*y)/rho", "uy": "(ar*y + ath*(x + mu))/rho", "uz": "cos(phi)"},
        "dynamics": {
            "x": "rate*vx", "y": "rate*vy", "z": "rate*vz",
            "vx": "rate*(2*vy + x - (1 - mu)*(x + mu)/r1**3 - mu*(x + mu - 1)/r2**3 + T_max/m*ux)",
            "vy": "rate*(-2*vx + y - (1 - mu)*y/r1**3 - mu*y/r2**3 + T_max/m*uy)",
            "vz": "rate*(-(1 - mu)*z/r1**3 - mu*z/r2**3 + T_max/m*uz)",
            "m": "-rate*T_max/c", "time": "rate"},
        "units": {"x": "LU", "y": "LU", "z": "LU", "vx": "LU/TU", "vy": "LU/TU", "vz": "LU/TU",
                  "m": "m0", "time": "TU", "delta": "rad", "phi": "rad"},
        "positions": ["x", "y", "z"],
    }


#: the paper's terminal states (ECRF polar, eq. 28) in the synodic Cartesian states at tf
POLAR_TERMINALS = ("r", "theta", "z", "rdot", "thetadot", "zdot")
CARTESIAN_TERMINALS = ("x", "y", "z", "vx", "vy", "vz")


def terminal_box(optimal_doc: dict, zeta: dict[str, float], ratio: float) -> tuple[list[str], list[str]]:
    """The paper's terminal conditions ``|e_i| <= ratio * zeta_i`` on its polar states, written
    in the Cartesian states at tf, in place of the optimal-mode file's exact equalities.

    Returns (relations, the Cartesian equalities they replace). The targets are the polar
    values of the file's Cartesian target (theta modulo 2 pi: the revolution class is held
    by the continuity of the trajectory)."""
    import sympy as sp

    from ..symbolic import frames

    mu = float(optimal_doc["model"]["parameters"]["mu"])
    targets, replaced = {}, []
    for c in optimal_doc["problem"]["constraints"]:
        lhs, _, rhs = c.partition("==")
        name = lhs.strip()[:-len("(tf)")] if lhs.strip().endswith("(tf)") else None
        if name in CARTESIAN_TERMINALS and rhs:
            targets[name] = float(rhs)
            replaced.append(c)
    if set(targets) != set(CARTESIAN_TERMINALS):
        raise ValueError(f"class mode needs the optimal file's terminal {CARTESIAN_TERMINALS} as "
                         f"'x(tf) == number'; found {sorted(targets)}")
    at_tf = [sp.Symbol(f"{n}(tf)") for n in CARTESIAN_TERMINALS]
    polar = frames.synodic_to_ecrf(*at_tf, sp.Symbol("mu"), lib=sp)
    goal = frames.synodic_to_ecrf(*(targets[n] for n in CARTESIAN_TERMINALS), mu, lib=np)
    relations = []
    for name, expr, value in zip(POLAR_TERMINALS, polar, goal):
        half = ratio * zeta[name]
        relations.append(f"{float(value) - half!r} <= {sp.sstr(expr)} <= {float(value) + half!r}")
    return relations, replaced


def with_terminal_box(constraints: list[str], optimal_doc: dict, zeta: dict[str, float],
                      ratio: float) -> list[str]:
    """``constraints`` with the optimal file's exact terminal state replaced by the paper's
    terminal box (:func:`terminal_box`)."""
    relations, replaced = terminal_box(optimal_doc, zeta, ratio)
    return [c for c in constraints if c not in replaced] + relations


def paper_tolerances(paper_loaded) -> tuple[dict[str, float], float]:
    """zeta of each polar terminal state and the refine stage's target ratio: read from the
    paper-mode problem's own terminal conditions, so they are the ones its fitness uses."""
    from .problem_file import shooting_problem

    pp = shooting_problem(paper_loaded)
    zeta = {t.state: float(t.zeta) for t in pp.terminals if t.state in POLAR_TERMINALS}
    missing = set(POLAR_TERMINALS) - set(zeta)
    if missing:
        raise ValueError(f"class mode needs terminal conditions on {sorted(missing)} in the paper file")
    return zeta, float(paper_loaded.method.refine.target_ratio)


def class_problem(optimal_doc: dict, orders: dict[str, int], values: dict[str, float],
                  weight: float | None, coefficient_bound: float,
                  terminal: tuple[dict[str, float], float] | None = None) -> dict[str, Any]:
    """The collocation problem of the class: penalty step (``weight``) or hard (None).

    ``terminal`` = (zeta, ratio): the paper's terminal box instead of the optimal file's
    exact terminal state (see :func:`terminal_box`)."""
    model = optimal_doc["model"]
    k = float(model.get("options", {}).get("sundman_k", 1.5))
    boundary = [c for c in optimal_doc["problem"]["constraints"]
                if not any(u in c for u in ("ux", "uy", "uz"))]
    if terminal is not None:
        boundary = with_terminal_box(boundary, optimal_doc, *terminal)
    params: dict[str, Any] = {"T": {"value": float(values["T"]), "free": True, "bounds": [0.1, 100.0]}}
    for control, order in orders.items():
        for name in coefficient_names(control, order):
            params[name] = {"value": float(values[name]), "free": True,
                            "bounds": [-coefficient_bound, coefficient_bound]}
    series = {c: series_text(c, n) for c, n in orders.items()}
    if weight is None:
        ties = [f"{c} == {series[c]}" for c in orders] + [f"{DEVIATIONS[c]} == 0" for c in orders]
        objective = "minimize T"
    else:
        params["w"] = float(weight)
        ties = [f"{DEVIATIONS[c]} == {c} - ({series[c]})" for c in orders]
        dev = " + ".join(f"{DEVIATIONS[c]}**2" for c in orders)
        objective = f"minimize T + w*integral(r1**{k}*({dev}))"
    solver = copy.deepcopy(optimal_doc.get("solver", {}))
    return {
        "name": f"{optimal_doc['name']} - paper's Fourier class"
                + ("" if weight is None else f", penalty weight {weight:g}"),
        "model": _cartesian_model(model.get("parameters", {}), k),
        "parameters": params,
        "problem": {"time": optimal_doc["problem"]["time"],
                    "constraints": boundary + ties + ["time(tf) == T"],
                    "objective": objective},
        "method": copy.deepcopy(optimal_doc["method"]),
        "solver": solver,
    }


def warm_folder(optimal: Result, mu: float, orders: dict[str, int], out: Path,
                ridge: float) -> tuple[dict[str, float], dict[str, float]]:
    """Write the optimal-mode run as a run folder of the class problem; return the fit
    (T and the coefficients) and its rms deviation from each angle (rad)."""
    tr = optimal.phase()
    st, u = tr.states, tr.controls
    t = np.asarray(st["time"], float)
    delta, phi = ecrf_angles(st["x"], st["y"], u["ux"], u["uy"], u["uz"], mu)
    T = float(t[-1])
    # LGR has no control at the phase start (exported empty, NaN): fitted on the nodes that
    # carry one
    keep = np.r_[True, np.diff(t) > 0] & np.isfinite(delta) & np.isfinite(phi)
    angle = {"delta": delta, "phi": phi}
    values: dict[str, float] = {"T": T}
    controls = {}
    for control, order in orders.items():
        coef = fit_series(t[keep], angle[control][keep], T, order, ridge)
        values.update(zip(coefficient_names(control, order), map(float, coef)))
        controls[control] = angle[control]
        controls[DEVIATIONS[control]] = angle[control] - basis(order, t, T) @ coef
    states = {n: np.asarray(v, float) for n, v in st.items()}
    single_phase_result(f"{optimal.name} as angles", "optimal",
                        PhaseTrajectory(tr.name, np.asarray(tr.time, float), states, controls),
                        tf=optimal.tf, parameters=values).write(out)
    rms = {c: float(np.sqrt(np.nanmean(controls[DEVIATIONS[c]] ** 2))) for c in orders}
    return values, rms


def paper_start(paper_run: str | Path, orders: dict[str, int]) -> tuple[Result, dict[str, float]]:
    """The paper-mode run ``paper_run`` and its class member (T and coefficients); a
    ValueError naming the folder if it is not a paper-mode run of these series."""
    if not (Path(paper_run) / "result.json").exists():
        raise ValueError(f"{paper_run}: not a paper-mode run folder (no result.json)")
    paper = Result.read(paper_run)
    vector = paper.extra.get("decision_vector")
    if not vector or "tf" not in vector:
        raise ValueError(f"{paper_run}: not a paper-mode run folder (no decision vector)")
    names = [n for control, order in orders.items() for n in coefficient_names(control, order)]
    missing = [n for n in names if n not in vector]
    if missing:
        raise ValueError(f"{paper_run}: its decision vector lacks {missing}")
    return paper, {"T": float(vector["tf"]), **{n: float(vector[n]) for n in names}}


def paper_warm_folder(paper_run: str | Path, paper: Result, values: dict[str, float], optimal_loaded,
                      orders: dict[str, int], out: Path) -> None:
    """Write the paper-mode run (:func:`paper_start`) as a run folder of the class problem.

    The paper trajectory is converted to the Sundman variable and the Cartesian frame as
    optimal mode's warm start is; the angles are the series themselves at the physical time
    (the start is a member of the class: ed = ep = 0)."""
    from .refine_optimal import paper_to_warm_start

    cartesian = paper_to_warm_start(paper_run, optimal_loaded, out.with_name(out.name + "_cartesian"))
    tr = cartesian.phase()
    states = {n: np.asarray(v, float) for n, v in tr.states.items()}
    controls = {}
    for control, order in orders.items():
        coef = np.array([values[n] for n in coefficient_names(control, order)])
        controls[control] = basis(order, states["time"], values["T"]) @ coef
        controls[DEVIATIONS[control]] = np.zeros_like(states["time"])
    single_phase_result(f"{paper.name} as a class member", "feasible",
                        PhaseTrajectory(tr.name, np.asarray(tr.time, float), states, controls),
                        tf=cartesian.tf, parameters=values).write(out)


# ---------------------------------------------------------------------------------------
# the verification by the paper-mode fitness
def _decision_vector(paper_loaded, values: dict[str, float]):
    """The paper-mode problem and the decision vector of a class member (T and coefficients)."""
    from .problem_file import shooting_problem

    pp = shooting_problem(paper_loaded)
    x = np.empty(len(pp.names()))
    for i, name in enumerate(pp.names()):
        if name == "tf":
            x[i] = values["T"]
        elif name in values:
            x[i] = values[name]
        else:  # a search parameter such as N_rev: its value in the file (held at the class)
            var = next(v for v in pp.variables if v.name == name)
            x[i] = var.lower if var.lower == var.upper else paper_loaded.spec.parameters[name].value
    return pp, x


def member_run(paper_loaded, values: dict[str, float], out: str | Path) -> Result:
    """Write a class member (T and coefficients), integrated by the paper-mode fitness, as a
    paper-mode run folder: a start for :func:`refine_class` (``paper_run``) from any
    coefficients, e.g. a stored solution or a random member."""
    from .local import inside_tolerances
    from .run import solution_record

    pp, x = _decision_vector(paper_loaded, values)
    det = pp.details(x)
    phase, record = solution_record(pp, x, det)
    res = single_phase_result(f"{paper_loaded.spec.name} - class member",
                              "feasible" if inside_tolerances(det) else "infeasible", phase,
                              objective=det["objective"], tf=float(det["tf"]), extra=record)
    res.write(out)
    return res


def shooting_check(paper_loaded, values: dict[str, float], polish_evaluations: int = 2000) -> dict[str, Any]:
    """The paper-mode decision vector of the class solution, integrated by the paper's
    fitness; least squares at fixed t_f if a terminal error is outside its zeta."""
    from .local import polish

    spec = paper_loaded.method
    pp, x = _decision_vector(paper_loaded, values)
    det = pp.details(x)
    record = {"tf": float(det["tf"]), "max_error_over_zeta": float(det["ratio"].max()),
              "errors": det["errors"].tolist(), "polished": False}
    if det["ratio"].max() > 1.0:
        margin = 10.0 * np.abs(x) + 1.0
        x, info = polish(pp, x, spec.polish, max_evaluations=polish_evaluations,
                         bounds=(x - margin, x + margin))
        det = pp.details(x)
        record.update({"polished": True, "polish": info,
                       "max_error_over_zeta_after_polish": float(det["ratio"].max())})
    return {"pp": pp, "x": x, "details": det, "record": record}


def _reuse(path: Path, text: str) -> Result | None:
    """The stage's earlier run, when its problem file is the same text (resume after a stop)."""
    folder = path.with_suffix("")
    if path.exists() and path.read_text() == text and (folder / "result.json").exists():
        return Result.read(folder)
    return None


# ---------------------------------------------------------------------------------------
def refine_class(paper_file: str | Path, optimal: str | Path, out: str | Path,
                 weights: tuple[float, ...] = DEFAULT_WEIGHTS, ridge: float = 1e-2,
                 coefficient_bound: float = 30.0, progress: bool = True, segments: int | None = None,
                 solver_options: dict[str, Any] | None = None, paper_run: str | Path | None = None,
                 terminal: str = "paper") -> Result:
    """Class mode of ``paper_file``; writes ``out``.

    ``optimal``: an optimal-mode run folder (start: its control, fitted by the series, then
    the penalty homotopy) or, with ``paper_run``, an optimal-mode run folder or problem file
    that only supplies the Cartesian problem: the start is then the paper-mode run itself,
    already a class member, and only the hard problem is solved. ``terminal``: ``paper``
    (the paper's box |e_i| <= ratio * zeta_i on its polar terminal states, ratio and zeta of
    the paper file, as paper mode's refine stage) or ``exact`` (the optimal file's terminal
    state). ``segments`` replaces the optimal-mode file's mesh; ``solver_options`` are added
    to its Ipopt options in every step."""
    import ocdsl
    from ..api import write_run
    from ..run import check_expectations
    from .local import inside_tolerances
    from .run import solution_record

    t_start = _time.perf_counter()
    out = Path(out)
    stages = out.with_name(out.name + "_stages")
    paper = ocdsl.load(paper_file).file
    orders = {c: s.order for c, s in paper.method.controls.items()}
    if set(orders) != set(ANGLES) or any(s.series != "fourier" for s in paper.method.controls.values()):
        raise ValueError(f"{paper_file}: class mode expects Fourier series of delta and phi, "
                         f"got {sorted(orders)}")
    if terminal not in ("paper", "exact"):
        raise ValueError(f"terminal must be 'paper' or 'exact', got {terminal!r}")
    optimal = Path(optimal)
    problem_path = optimal if optimal.is_file() else optimal / "problem.yaml"
    needed = [problem_path] + ([] if paper_run is not None else [optimal / "result.json"])
    for path in needed:
        if not path.exists():
            raise ValueError(f"{optimal}: not an optimal-mode run folder (no {path.name})")
    optimal_doc = yaml.safe_load(problem_path.read_text())
    box = paper_tolerances(paper) if terminal == "paper" else None
    if paper_run is not None:   # every check before anything is written
        start, values = paper_start(paper_run, orders)
        optimal_loaded = ocdsl.load(problem_path).file
    stages.mkdir(parents=True, exist_ok=True)
    mu = float(optimal_doc["model"]["parameters"]["mu"])
    warm_dir = stages / "fit"
    if paper_run is None:
        values, fit_rms = warm_folder(Result.read(optimal), mu, orders, warm_dir, ridge)
    else:
        paper_warm_folder(paper_run, start, values, optimal_loaded, orders, warm_dir)
        fit_rms = {c: 0.0 for c in orders}
        weights = ()
    # tables are numeric: the statuses go to extra, the table has solved = 1/0
    history: dict[str, list] = {"step": [], "weight": [], "solved": [], "T": [], "penalty": [],
                                "iterations": [], "wall_s": []}
    statuses: list[str] = []
    previous = warm_dir
    last_ok = None
    schedule = [(w, WARM_OPTIONS if i > 0 else {}) for i, w in enumerate(weights)]
    schedule += [(None, opts) for opts in HARD_ATTEMPTS]
    hard_from = None
    for i, (w, step_options) in enumerate(schedule):
        if w is None and hard_from is None:
            hard_from = (previous, dict(values))
        if w is None:          # every hard attempt starts from the last penalty step
            previous, values = hard_from[0], dict(hard_from[1])
        doc = class_problem(optimal_doc, orders, values, w, coefficient_bound, box)
        if segments is not None:
            doc["method"]["segments"] = int(segments)
        doc["solver"].setdefault("options", {}).update(solver_options or {})
        doc["solver"]["options"].update(step_options)
        hard_index = i - len(weights)
        path = stages / (f"step{i:02d}.yaml" if w is not None else f"hard{hard_index}.yaml")
        text = yaml.safe_dump(doc, sort_keys=False, width=100000)
        t0 = _time.perf_counter()
        res = _reuse(path, text)
        if res is None:
            path.write_text(text)
            res = ocdsl.load(path).solve(stages / path.stem, warm_start=previous)
        ok = res.status in ("optimal", "acceptable")
        statuses.append(res.status)
        T = float(res.parameters.get("T", math.nan))
        penalty = float(res.objective - T) if (ok and w is not None) else 0.0
        for key, v in zip(history, (i, w if w is not None else math.inf, int(ok), T, penalty,
                                    res.iterations, _time.perf_counter() - t0)):
            history[key].append(v)
        if progress:
            print(f"class mode step {i}: weight {'hard' if w is None else f'{w:g}'}, {res.status}, "
                  f"T {T:.6f}, penalty {penalty:.3e}, {res.iterations} iterations", flush=True)
        if not ok and w is not None:
            break
        if not ok:
            continue
        values.update({k: float(v) for k, v in res.parameters.items() if k in values})
        previous, last_ok = stages / path.stem, w
        if w is None:
            break
    hard_ok = history["weight"][-1] == math.inf and bool(history["solved"][-1])
    if not hard_ok and hard_from is not None:
        values = dict(hard_from[1])      # check the last penalty step's class member instead
    check = shooting_check(paper, values)
    pp, x, det = check["pp"], check["x"], check["details"]
    phase, solution = solution_record(pp, x, det)
    feasible = inside_tolerances(det)
    status = "feasible" if (feasible and hard_ok) else "infeasible"
    extra = {
        "class_mode": {"optimal": str(optimal), "start": str(paper_run or optimal), "terminal": terminal, "fit_rms_rad": fit_rms, "ridge": ridge,
                       "coefficient_bound": coefficient_bound, "hard_solved": hard_ok,
                       "last_weight": last_ok, "collocation_T": values["T"], "statuses": statuses,
                       "coefficients_at_bound": sum(abs(values[n]) >= 0.999 * coefficient_bound
                                                    for c, o in orders.items() for n in coefficient_names(c, o)),
                       "stages": str(stages)},
        "shooting": check["record"],
        **solution,
    }
    msg = (f"class mode: penalty homotopy over {sum(np.isfinite(history['weight']))} weights, "
           f"hard class problem {'solved' if hard_ok else 'NOT solved'} (T {values['T']:.6g}); "
           f"paper-mode fitness: tf {det['tf']:.6g}, terminal errors "
           f"{'inside' if feasible else 'NOT inside'} zeta (max |e|/zeta {det['ratio'].max():.3g})")
    params = {k: float(v) for k, v in pp.parameters.items()}
    params.update({k: float(v) for k, v in det["variables"].items()})
    result = Result(f"{paper.spec.name} - class mode", status, message=msg, objective=det["objective"],
                    tf=det["tf"], iterations=int(sum(history["iterations"])),
                    wall_time_s={"total": _time.perf_counter() - t_start},
                    method=paper.method.model_dump(mode="json"), parameters=params,
                    phases=[phase], problem=paper.problem.description, extra=extra, tables={"homotopy": history})
    values_at = {ph.tf_symbol: float(det["tf"]) for ph in paper.problem.phases}
    result.expect = check_expectations(paper, values_at, result.objective)
    write_run(result, out, Path(paper_file))
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ocdsl.search.class_collocation",
                                 description="Seed 1 class mode: the paper's Fourier class by collocation")
    ap.add_argument("paper", help="paper-mode problem file (method: parametric)")
    ap.add_argument("--optimal", required=True,
                    help="optimal-mode run folder to start from (with --from-paper: that folder or an optimal-mode problem file)")
    ap.add_argument("--from-paper", default=None, metavar="RUN",
                    help="start from this paper-mode run (a class member): the hard problem only")
    ap.add_argument("--terminal", choices=("paper", "exact"), default="paper",
                    help="the paper's terminal box (default) or the optimal file's exact terminal state")
    ap.add_argument("--out", required=True, help="run folder to write")
    ap.add_argument("--weights", default=None, help="comma-separated penalty weights")
    ap.add_argument("--coefficient-bound", type=float, default=30.0,
                    help="bound on every |Fourier coefficient| (the paper states none; default 30)")
    ap.add_argument("--segments", type=int, default=None, help="mesh of the class problem (default: the optimal run's)")
    ap.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                    help="an Ipopt option for every step (repeatable)")
    args = ap.parse_args(argv)
    weights = DEFAULT_WEIGHTS if args.weights is None else tuple(float(w) for w in args.weights.split(","))
    options = {}
    for item in args.option:
        name, _, value = item.partition("=")
        options[name] = yaml.safe_load(value)
    from ..spec.errors import SpecError

    try:
        res = refine_class(args.paper, args.optimal, args.out, weights, segments=args.segments,
                           coefficient_bound=args.coefficient_bound,
                           solver_options=options, paper_run=args.from_paper, terminal=args.terminal)
    except (SpecError, ValueError) as e:   # bad input: one message, nothing written
        print(f"Error: {e}", file=sys.stderr)
        return 2
    print(res.message)
    return 0 if res.ok else 1


if __name__ == "__main__":
    sys.exit(main())
