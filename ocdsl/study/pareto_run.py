"""Run the ``pareto:`` block of a problem file; the two-burn relative-motion solver of seed 4.

:func:`run_pareto` is what the CLI calls: it validates the block
(:mod:`ocdsl.spec.pareto`), builds the per-point callable, runs the chosen method of
:mod:`ocdsl.study.pareto` through a ``map`` (serial, or the studies executor), writes the
study folder (one run folder per point plus the table) and returns the Results and the
table.

Two kinds of point solvers:

* ``solver: closed_form`` on the two-burn programme wait/burn/coast/burn of the
  ``relative_motion_secular`` model (digest ../shared/seeds/seed_004.md §2.7-2.10): the
  burn durations come in closed form from the secular conditions, (t0, tp) are roots of
  the two periodic conditions found by multistart (SciPy ``root``) over cells of the
  window; :class:`TwoBurnTask` is one cell of one sign pattern.
* ``solver: nlp``: the collocation NLP of the problem file (:mod:`ocdsl.study.pareto_nlp`):
  ``enumerate`` solves a multi-phase file with fixed controls and free durations from
  starts (:func:`ocdsl.study.pareto_nlp.nlp_tasks`), ``epsilon`` re-solves the file with
  the parameter ``epsilon.parameter`` set to each eps (:class:`~ocdsl.study.pareto_nlp.EpsilonSolver`);
  ``solve_point`` replaces the default callable (``weighted`` needs one).
"""
from __future__ import annotations

import builtins
import functools
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ocdsl import run_folder
from ocdsl.result import PhaseTrajectory, Result
from ocdsl.spec.pareto import ParetoSpec, ParetoSpecError, constant, load_pareto, parse_pareto
from ocdsl.study import pareto as P
from ocdsl.symbolic import relative_motion as rm

__all__ = ["TwoBurnTask", "solve_two_burn_task", "two_burn_tasks", "two_burn_point",
           "two_burn_pareto", "two_burn_trajectory", "two_burn_problem", "run_pareto", "FAMILY_PREFIX"]

PHASES = ("wait", "burn1", "coast", "burn2")
FAMILY_PREFIX = {"same": "1", "opposite": "2"}   # the paper's rows 1.x and 2.x
OBJECTIVES = ("t_mot", "t_sum")
STATE_NAMES = ("r_av", "L_av", "l_x", "l_y")


# ---------------------------------------------------------------------------------------
# The two-burn point solver
# ---------------------------------------------------------------------------------------
def two_burn_trajectory(y0, t0, t1, tp, t2, d1, d2, nodes: int = 41) -> list[PhaseTrajectory]:
    """Closed-form trajectories of the four phases (dimensionless time from 0)."""
    out, y, start = [], np.asarray(y0, float), 0.0
    for name, delta, dur in zip(PHASES, (0, d1, 0, d2), (t0, t1, tp, t2)):
        s = np.linspace(0.0, dur, nodes)
        Y = np.array([rm.segment(y, delta, float(v)) for v in s])
        out.append(PhaseTrajectory(
            name, start + s, states={n: Y[:, i] for i, n in enumerate(STATE_NAMES)},
            controls={"delta": np.full(nodes, float(delta))}, control_interpolation={"kind": "linear"},
            extra={"l": np.hypot(Y[:, 2], Y[:, 3])}))
        y, start = Y[-1], start + dur
    return out


def two_burn_point(y0, t0, tp, d1, d2, family, final=(0.0, 0.0, 0.0, 0.0),
                   trajectory: bool = False) -> P.ParetoPoint | None:
    """The point of a (t0, tp) pair: closed-form durations, criteria, final-state residual."""
    t1, t2 = rm.burn_durations(y0, t0, tp, d1, d2, final[:2])
    if math.isnan(t1):
        return None
    yT = rm.two_burn_final_state(y0, t0, t1, tp, t2, d1, d2)
    t_mot, t_sum = rm.criteria(t0, t1, tp, t2)
    return P.ParetoPoint(
        objectives={"t_mot": t_mot, "t_sum": t_sum},
        variables={"t0": t0, "t1": t1, "tp": tp, "t2": t2, "d1": float(d1), "d2": float(d2)},
        family=family, residual=float(np.max(np.abs(yT - np.asarray(final, float)))),
        extra={"final_state": [float(v) for v in yT]},
        phases=two_burn_trajectory(y0, t0, t1, tp, t2, d1, d2) if trajectory else [])


_TWO_BURN_FILE = """\
name: two-burn programme {d1:+d}/{d2:+d} (what closed-form points are verified against)
model: {{use: relative_motion_secular}}
phases:
  wait:
    time: {{t0: 0, tf: free}}
    constraints: [delta == 0, r_av(t0) == {y0[0]!r}, L_av(t0) == {y0[1]!r}, l_x(t0) == {y0[2]!r}, l_y(t0) == {y0[3]!r}]
  burn1: {{time: {{t0: free, tf: free}}, constraints: [delta == {d1}]}}
  coast: {{time: {{t0: free, tf: free}}, constraints: [delta == 0]}}
  burn2:
    time: {{t0: free, tf: free}}
    constraints: [delta == {d2}, r_av(tf) == {yk[0]!r}, L_av(tf) == {yk[1]!r}, l_x(tf) == {yk[2]!r}, l_y(tf) == {yk[3]!r}]
links: ["continuous(wait, burn1, coast, burn2)"]
objective: minimize burn2.tf
"""


@functools.lru_cache(maxsize=16)     # one compile per sign pattern and start, not per point
def two_burn_problem(y0: tuple, d1: int, d2: int, final: tuple = (0.0, 0.0, 0.0, 0.0)):
    """The two-burn programme of one sign pattern as a compiled problem file, so that the
    closed-form points go through the same verification (ocdsl/verify) as every solve."""
    from ocdsl.api import compile_file

    text = _TWO_BURN_FILE.format(y0=[float(v) for v in y0], yk=[float(v) for v in final],
                                 d1=int(d1), d2=int(d2))
    return compile_file("<two-burn programme>", text=text).problem


def two_burn_verification(task: "TwoBurnTask", point: P.ParetoPoint) -> dict:
    """The verdict of ocdsl/verify on a closed-form point's trajectory (objective not
    checked: a Pareto point has two)."""
    from ocdsl.verify import verify_result

    problem = two_burn_problem(task.y0, task.d1, task.d2, task.final)
    res = Result("two-burn point", "optimal", phases=list(point.phases))
    return verify_result(problem, res)


@dataclass
class TwoBurnTask:
    """One cell of the (t0, tp) window for one sign pattern: a grid of starts, solved in turn.

    ``bounds`` are the whole window (roots outside are dropped: t0 in [lo, hi),
    tp in (lo, hi]); ``cell`` the part where the starts lie. Picklable, so an executor can
    run it.
    """

    y0: tuple[float, float, float, float]
    d1: int
    d2: int
    family: str
    cell: dict[str, tuple[float, float]]
    starts: dict[str, int]
    bounds: dict[str, tuple[float, float]]
    final: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    residual_tol: float = 1e-10
    xtol: float = 1e-13
    trajectory: bool = True


def solve_two_burn_task(task: TwoBurnTask) -> list[P.ParetoPoint]:
    """Roots of the periodic conditions from every start of the cell with t1, t2 >= 0."""
    from scipy.optimize import root

    def F(p):
        r = rm.periodic_residual(task.y0, p[0], p[1], task.d1, task.d2, task.final)
        return r if np.all(np.isfinite(r)) else np.array([1e3, 1e3])

    (t0lo, t0hi), (tplo, tphi) = task.bounds["t0"], task.bounds["tp"]
    found: list[P.ParetoPoint] = []
    for s in P.grid_starts({"t0": task.cell["t0"], "tp": task.cell["tp"]}, task.starts):
        sol = root(F, [s["t0"], s["tp"]], method="hybr", options={"xtol": task.xtol})
        t0, tp = (float(v) for v in sol.x)
        if not (t0lo <= t0 < t0hi and tplo < tp <= tphi):
            continue
        p = two_burn_point(task.y0, t0, tp, task.d1, task.d2, task.family, task.final)
        if p is None or p.variables["t1"] < 0 or p.variables["t2"] < 0 or p.residual > task.residual_tol:
            continue
        found.append(p)
    found = P.deduplicate(found, ("t0", "tp"), 1e-7)
    if task.trajectory:
        for p in found:
            v = p.variables
            p.phases = two_burn_trajectory(task.y0, v["t0"], v["t1"], v["tp"], v["t2"], task.d1, task.d2)
            p.extra["verification"] = two_burn_verification(task, p)
    return found


def two_burn_tasks(y0, families: dict[str, list[tuple[int, int]]],
                   window: dict[str, dict[str, Any]], final=(0.0, 0.0, 0.0, 0.0),
                   residual_tol: float = 1e-10, trajectory: bool = True) -> list[TwoBurnTask]:
    """Tasks: every sign pattern x every cell of the window.

    ``window`` = {"t0": {"range": (lo, hi), "split": None, "starts": n}, "tp": {...}}.
    """
    cells = {k: P.window_cells(*w["range"], w.get("split")) for k, w in window.items()}
    tasks = []
    for family, patterns in families.items():
        for d1, d2 in patterns:
            for c0 in cells["t0"]:
                for cp in cells["tp"]:
                    tasks.append(TwoBurnTask(
                        tuple(float(v) for v in y0), int(d1), int(d2), family,
                        {"t0": c0, "tp": cp},
                        {"t0": int(window["t0"].get("starts", 4)), "tp": int(window["tp"].get("starts", 4))},
                        {k: tuple(w["range"]) for k, w in window.items()},
                        tuple(float(v) for v in final), residual_tol, trajectory=trajectory))
    return tasks


DEFAULT_FAMILIES = {"same": [(1, 1), (-1, -1)], "opposite": [(1, -1), (-1, 1)]}
DEFAULT_WINDOW = {"t0": {"range": (0.0, 2 * math.pi), "starts": 12},
                  "tp": {"range": (0.0, 40.0), "split": 2 * math.pi, "starts": 6}}


def two_burn_pareto(y0, families=None, window=None, final=(0.0, 0.0, 0.0, 0.0), *,
                    map: Callable = builtins.map, residual_tol: float = 1e-10,
                    dedup_tol: float = 1e-6, trajectory: bool = True) -> P.ParetoSet:
    """The two-burn Pareto set of seed 4 (enumerate + filter); labels 1.x same, 2.x opposite."""
    tasks = two_burn_tasks(y0, families or DEFAULT_FAMILIES, window or DEFAULT_WINDOW, final,
                           residual_tol, trajectory)
    s = P.enumerate(solve_two_burn_task, tasks, OBJECTIVES, map=map,
                    dedup_keys=("t0", "tp", "d1"), dedup_tol=dedup_tol,
                    family_prefix=FAMILY_PREFIX)
    s.info.update({"solver": "closed_form", "tasks": len(tasks), "y0": list(map_float(y0))})
    return s


def map_float(v: Sequence[Any]) -> list[float]:
    return [float(x) for x in v]


# ---------------------------------------------------------------------------------------
# The runner used by the CLI
# ---------------------------------------------------------------------------------------
def _local_map(workers: int | None) -> tuple[Callable, Callable[[], None]]:
    """``map`` of the studies executor on local processes (``ocdsl.study.executor.Executor``)."""
    from ocdsl.study.executor import Executor

    ex = Executor(workers=workers)
    return ex.map, ex.close


def _two_burn_from_doc(doc: dict[str, Any], spec: ParetoSpec, parameters: dict[str, float],
                       file: str | None) -> tuple[tuple, dict, dict, tuple]:
    """Initial state, families, window and final state of a seed-4 problem file."""
    def par(name, default=None):
        if name in parameters:
            return float(parameters[name])
        v = (doc.get("parameters") or {}).get(name, default)
        if v is None:
            raise ParetoSpecError(f"parameter {name!r} is missing (the two-burn solver needs it)", file)
        return constant(v)

    y0 = tuple(par(n) for n in ("r0", "L0", "lx0", "ly0"))
    final = tuple(par(n, 0.0) for n in ("rk", "Lk", "lxk", "lyk"))
    alts = doc.get("alternatives") or {}
    families: dict[str, list[tuple[int, int]]] = {}
    for fam, pats in alts.items():
        pats = pats if isinstance(pats, list) else [pats]
        families[fam] = [(int(constant(p["s1"])), int(constant(p["s2"]))) for p in pats]
    if not families:
        families = DEFAULT_FAMILIES
    keys = {"wait.duration": "t0", "coast.duration": "tp"}
    window = {}
    for k, w in spec.window.items():
        if k not in keys:
            raise ParetoSpecError(f"pareto.window.{k}: the two-burn solver searches "
                                  f"wait.duration and coast.duration only", file)
        window[keys[k]] = {"range": w.range, "split": w.split, "starts": w.starts}
    if set(window) != {"t0", "tp"}:
        raise ParetoSpecError("pareto.window: give wait.duration and coast.duration", file)
    return y0, families, window, final


def run_pareto(problem: str | Path | dict[str, Any], out: str | Path | None = None, *,
               parameters: dict[str, float] | None = None, map: Callable | None = None,
               solve_point: Callable | None = None, trajectory: bool = True,
               return_set: bool = False, force: bool = False) -> tuple[list[Result], dict[str, list[Any]]]:
    """Run a problem file's ``pareto:`` block; return one Result per solution and the table.

    ``problem`` is a path or an already-loaded document; ``parameters`` override the
    file's constants (e.g. ``{"lx0": 1.0}`` for a variant); ``map`` runs the tasks (default:
    builtin map, or local processes when the block says ``executor: local``). When ``out``
    is given the study folder is written there: ``result.json`` + ``tables/pareto.csv`` +
    ``pareto.csv`` for the set, ``points/<label>/`` for every solution.
    The table has every solution, its family, the variables, the objectives and the
    Pareto flag; ``Result.extra['pareto']`` flags each point. ``return_set=True`` adds the
    :class:`~ocdsl.study.pareto.ParetoSet` as a third item (to combine studies in one table,
    :func:`ocdsl.study.pareto_nlp.combine_sets`).
    """
    t_start = time.perf_counter()
    if isinstance(problem, dict):
        doc, file = problem, None
        spec = parse_pareto(doc.get("pareto"))
    else:
        spec, doc = load_pareto(problem)
        file = str(problem)
    if out is not None:      # refused before any work (a folder ocdsl did not write)
        run_folder.check_destination(out, "pareto", force=force)
    parameters = dict(parameters or {})
    name = str(doc.get("name", "pareto study"))
    shutdown = lambda: None  # noqa: E731
    if map is None:
        map, shutdown = (builtins.map, shutdown) if spec.executor == "serial" else _local_map(spec.workers)
    try:
        if spec.solver == "closed_form":
            use = (doc.get("model") or {}).get("use")
            if use != "relative_motion_secular" or spec.method != "enumerate":
                raise ParetoSpecError("solver closed_form exists for the two-burn programme of model "
                                      "relative_motion_secular with method enumerate", file)
            y0, families, window, final = _two_burn_from_doc(doc, spec, parameters, file)
            pset = two_burn_pareto(y0, families, window, final, map=map,
                                   residual_tol=spec.residual_tol, dedup_tol=spec.dedup_tol,
                                   trajectory=trajectory)
        else:
            from ocdsl.study import pareto_nlp

            objs, senses = spec.objective_names, spec.senses
            if spec.method == "epsilon":
                if solve_point is None:
                    if file is None or not spec.epsilon.parameter:
                        raise ParetoSpecError("method epsilon with solver nlp needs the problem file's "
                                              "path and epsilon.parameter (the parameter that carries eps)",
                                              file)
                    seeds = []
                    if spec.epsilon.seed_study:
                        seed_path = Path(file).parent / spec.epsilon.seed_study
                        seed_pars = {k: v for k, v in parameters.items() if k != spec.epsilon.parameter}
                        _, _, seed_set = run_pareto(seed_path, parameters=seed_pars, return_set=True)
                        seeds = pareto_nlp.seeds_from(seed_set.points, spec.epsilon.objective, objs[0])
                    solve_point = pareto_nlp.EpsilonSolver(
                        file, spec.epsilon.parameter, {k: o.expr for k, o in spec.objectives.items()},
                        parameters, family=spec.family or "", trajectory=trajectory, seeds=seeds)
                pset = P.epsilon(solve_point, spec.epsilon.values, objs, senses, map=map,
                                 chains=spec.epsilon.chains, flag_tol=spec.dominance_tol,
                                 constrained=spec.epsilon.objective)
            elif spec.method == "weighted":
                if solve_point is None:
                    raise NotImplementedError("method weighted with solver nlp: pass solve_point=...")
                w = spec.weights.values if spec.weights.values is not None else spec.weights.num
                pset = P.weighted(solve_point, w, objs, senses, map=map, chains=spec.weights.chains)
            else:
                if file is None:
                    raise ParetoSpecError("method enumerate with solver nlp needs the problem file's path")
                tasks = pareto_nlp.nlp_tasks(file, spec, doc, parameters, trajectory=trajectory)
                prefix = FAMILY_PREFIX if set(spec.alternatives) <= set(FAMILY_PREFIX) else None
                pset = P.enumerate(solve_point or pareto_nlp.solve_nlp_task, tasks, objs, senses,
                                   map=map, dedup_tol=spec.dedup_tol, family_prefix=prefix,
                                   flag_tol=spec.dominance_tol)
                pset.info.update({"solver": "nlp", "tasks": len(tasks), "starts_from": spec.starts_from})
    finally:
        shutdown()
    wall = time.perf_counter() - t_start
    pset.info.update({"wall_time_s": wall, "parameters": parameters, "executor": spec.executor})
    method = {"pareto": spec.method, "solver": spec.solver}
    problem_desc = {"name": name, "description": str(doc.get("description", "")),
                    "phases": {ph: {"states": list(STATE_NAMES), "controls": ["delta"]} for ph in PHASES}
                    if spec.solver == "closed_form" else {},
                    "objective": {"sense": "minimize", "text": ", ".join(
                        f"{k} = {o.expr}" for k, o in spec.objectives.items())}}
    results = pset.results(name, method, problem_desc)
    for r in results:
        r.wall_time_s = {"total": wall / max(len(results), 1)}
    if out is not None:
        expect = spec.expect or (doc.get("expect") if spec.solver == "closed_form" else None)
        pset.write(out, name, method, problem_desc, wall_time_s=wall, expect=expect, force=force)
    table = pset.table()
    if return_set:
        return results, table, pset
    return results, table
