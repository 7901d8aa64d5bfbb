"""Pareto point solvers through the collocation NLP (``pareto: {solver: nlp}``).

Two callables that :func:`ocdsl.study.pareto_run.run_pareto` hands to the methods of
:mod:`ocdsl.study.pareto`, both picklable (module-level dataclasses) so that the studies
executor can run them in worker processes:

* :class:`NLPTask` + :func:`solve_nlp_task` (method ``enumerate``): a multi-phase problem
  file whose phases have fixed controls (bounds ``delta == s1``) and free durations (each
  phase runs from 0 to a free ``tf``), solved by pseudospectral collocation from several
  starts of the phase durations. With the controls fixed the NLP has as many equations as
  unknown durations, so each solve lands on an isolated root near its start (the seed-4
  two-burn programme, ``configs/seed4_two_burn_nlp.yaml``). Every root is then checked
  independently of the collocation: the phases are integrated (SciPy DOP853) with the found
  durations and the final-state conditions measured; that is the point's ``residual``.
* :class:`EpsilonSolver` (method ``epsilon``): any problem file whose objective is the
  first Pareto objective and whose parameter ``epsilon.parameter`` bounds the second one;
  each call solves the file with that parameter set to eps, warm-started from the previous
  point's trajectories (``configs/seed4_unrestricted.yaml``).

Starts of :func:`nlp_tasks`: a grid over the window cells (``starts_from: window``), or the
model's closed-form roots perturbed (``starts_from: closed_form``; for the two-burn
programme of ``relative_motion_secular``: the roots of
:func:`ocdsl.study.pareto_run.two_burn_pareto`, each duration moved by a seeded random
amount up to ``perturbation`` (dimensionless time, never below half the duration)), one
task per root.
"""
from __future__ import annotations

import ast
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from ocdsl.result import PhaseTrajectory, Result
from ocdsl.study import pareto as P

__all__ = ["NLPTask", "solve_nlp_task", "solve_durations", "integrated_residual", "nlp_tasks",
           "EpsilonSolver", "seeds_from", "evaluate", "compiled", "combine_sets", "write_comparison"]

GOOD = ("optimal", "acceptable")


# ---------------------------------------------------------------------------------------
# Objective expressions in phase durations / final times
# ---------------------------------------------------------------------------------------
_BIN = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
        ast.Div: lambda a, b: a / b}


def evaluate(text: str, values: dict[str, float]) -> float:
    """Value of an objective such as ``burn1.duration + burn2.duration`` or ``tf``.

    ``values`` maps names (``tf``, ``<phase>.duration``, ``<phase>.tf``, ``objective``) to
    numbers; only + - * /, numbers and ``pi`` are allowed (nothing is eval-ed).
    """
    def walk(n: ast.AST) -> float:
        if isinstance(n, ast.Expression):
            return walk(n.body)
        if isinstance(n, ast.Constant) and isinstance(n.value, (int, float)):
            return float(n.value)
        if isinstance(n, ast.Name):
            if n.id in values:
                return float(values[n.id])
            if n.id == "pi":
                return math.pi
        if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name):
            key = f"{n.value.id}.{n.attr}"
            if key in values:
                return float(values[key])
        if isinstance(n, ast.BinOp) and type(n.op) in _BIN:
            return _BIN[type(n.op)](walk(n.left), walk(n.right))
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.USub):
            return -walk(n.operand)
        raise ValueError(f"objective {text!r}: cannot evaluate {ast.unparse(n)!r} from "
                         f"{sorted(values)}")

    return walk(ast.parse(text.strip(), mode="eval"))


# ---------------------------------------------------------------------------------------
# Compile once per process
# ---------------------------------------------------------------------------------------
def compiled(path: str, parameters: dict[str, float]):
    """The compiled problem file (``ocdsl.api.compile_file``), cached in this process."""
    from ocdsl.api import compile_file
    from ocdsl.study.executor import worker_cache

    st = Path(path).stat()
    key = ("pareto_nlp", str(Path(path).resolve()), st.st_mtime_ns, st.st_size,
           tuple(sorted((k, float(v)) for k, v in parameters.items())))
    return worker_cache(key, lambda: compile_file(path, parameters), max_items=16)


def verification(file, phases, status: str, objective: float | None, free: dict[str, float]) -> dict:
    """The independent verification (ocdsl/verify) of one point's trajectory, with the
    file's settings; ``objective`` None when the point's objective is not the file's."""
    from ocdsl.verify import VerifySettings, verify_result

    res = Result(file.spec.name, status, objective=objective, phases=list(phases),
                 parameters={**file.parameters, **free})
    return verify_result(file.problem, res, VerifySettings.of(file.spec.verify))


def _meshes(file):
    from ocdsl.transcribe.mesh import Mesh

    m = file.method
    return {ph.name: Mesh.uniform(m.transcription, m.segments, m.degree) for ph in file.problem.phases}


def _solve(file, guesses):
    from ocdsl.solve import ipopt
    from ocdsl.transcribe.pseudospectral import build

    tr = build(file.problem, _meshes(file), guesses)
    info = ipopt.solve(tr.model, file.spec.solver.options, transcription=tr)
    return tr, info


# ---------------------------------------------------------------------------------------
# Fixed-control phases with free durations (enumerate)
# ---------------------------------------------------------------------------------------
def _fixed_controls(ph) -> np.ndarray:
    out = []
    for c in ph.controls:
        lo, hi = ph.bounds_of(c)
        if lo != hi:
            raise ValueError(f"phase {ph.name!r}: control {c} is not fixed (write e.g. `{c} == 1`); "
                             "solver nlp with method enumerate needs fixed controls")
        out.append(lo)
    return np.array(out, float)


def _boundary_equalities(problem) -> dict[tuple[str, str, str], float]:
    """(phase, state, t0|tf) -> value of every boundary value fixed by an equality."""
    out = {}
    for c in problem.boundary:
        if isinstance(c.expr, sp.Symbol) and c.expr in problem.boundary_values and c.is_equality:
            bv = problem.boundary_values[c.expr]
            out[(bv.phase, bv.var.name, bv.which)] = float(c.lower)
    return out


def integrated_residual(problem, durations: dict[str, float], nodes: int = 41, common_clock: bool = True
                        ) -> tuple[float, list[PhaseTrajectory], np.ndarray]:
    """Integrate the phases in order (states continuous, controls fixed) with ``durations``.

    The initial state is the first phase's fixed ``x(t0)``; the residual is the largest
    violation of the fixed boundary values along the way (in practice the final state),
    measured on the DOP853 solution (rtol 1e-12, atol 1e-13), independent of the
    collocation. Returns (residual, trajectories, final state); the trajectories run on a
    common clock, or each from 0 (``common_clock=False``, as an NLP guess).
    """
    from scipy.integrate import solve_ivp

    fixed = _boundary_equalities(problem)
    first = problem.phases[0]
    y = np.array([fixed[(first.name, s.name, "t0")] for s in first.states], float)
    res, start, out = 0.0, 0.0, []
    for ph in problem.phases:
        u = _fixed_controls(ph)
        f = sp.lambdify([sp.Matrix(ph.states), sp.Matrix(ph.controls)], ph.rhs(), "numpy")
        for j, s in enumerate(ph.states):
            if (ph.name, s.name, "t0") in fixed:
                res = max(res, abs(y[j] - fixed[(ph.name, s.name, "t0")]))
        d = float(durations[ph.name])
        ts = np.linspace(0.0, d, nodes)
        if d > 0:
            sol = solve_ivp(lambda t, x: np.asarray(f(x, u), float).ravel(), (0.0, d), y,
                            method="DOP853", rtol=1e-12, atol=1e-13, t_eval=ts)
            Y = sol.y.T
        else:
            Y = np.repeat(y[None, :], nodes, axis=0)
        y = Y[-1].copy()
        for j, s in enumerate(ph.states):
            if (ph.name, s.name, "tf") in fixed:
                res = max(res, abs(y[j] - fixed[(ph.name, s.name, "tf")]))
        out.append(PhaseTrajectory(ph.name, (start if common_clock else 0.0) + ts, states={s.name: Y[:, j] for j, s in enumerate(ph.states)},
                                   controls={c.name: np.full(nodes, u[j]) for j, c in enumerate(ph.controls)}))
        start += d
    return float(res), out, y


def solve_durations(file, start: dict[str, float]):
    """Solve the NLP from phase durations ``start``; return (durations, SolveInfo, seconds).

    The states of the guess are the phases integrated with the start durations (a shooting
    guess), so that the NLP starts on the dynamics and only the durations are off.
    """
    import pyomo.core as pyo

    from ocdsl.transcribe.guess import make_guess

    problem = file.problem
    _, sim, _ = integrated_residual(problem, start, nodes=101, common_clock=False)
    sim = {p.name: p for p in sim}
    guesses = {}
    for ph in problem.phases:
        ph.guess = {**ph.guess, "tf": float(ph.t0 or 0.0) + float(start[ph.name])}
        guesses[ph.name] = make_guess(problem, ph, sim[ph.name])
    t = time.perf_counter()
    tr, info = _solve(file, guesses)
    durations = {pb.phase.name: float(pyo.value(pb.block.tf)) - float(pyo.value(pb.block.t0))
                 for pb in tr.phases}
    return durations, info, time.perf_counter() - t


@dataclass
class NLPTask:
    """Starts of one family member (a parameter set) of a multi-phase problem file."""

    path: str
    parameters: dict[str, float]
    family: str
    starts: list[dict[str, float]]          # phase name -> duration
    objectives: dict[str, str]              # name -> expression in <phase>.duration
    residual_tol: float = 1e-6
    trajectory: bool = True
    tag: dict[str, Any] = field(default_factory=dict)   # e.g. the closed-form root it came from


def solve_nlp_task(task: NLPTask) -> list[P.ParetoPoint]:
    """Solve from every start; keep converged roots whose integrated residual is small."""
    file = compiled(task.path, task.parameters)
    out = []
    for start in task.starts:
        durations, info, secs = solve_durations(file, start)
        if info.status not in GOOD:
            continue
        res, traj, yT = integrated_residual(file.problem, durations)
        if not res <= task.residual_tol:
            continue
        names = {f"{k}.duration": v for k, v in durations.items()}
        names.update({f"{k}.tf": v for k, v in durations.items()})
        variables = {f"{k}.duration": v for k, v in durations.items()}
        variables.update({k: float(v) for k, v in task.parameters.items()})
        out.append(P.ParetoPoint(
            objectives={o: evaluate(e, names) for o, e in task.objectives.items()},
            variables=variables, family=task.family, status=info.status, residual=res,
            extra={"final_state": [float(v) for v in yT], "iterations": info.iterations,
                   "solve_time_s": secs, "start": dict(start), "nlp": info.nlp, **task.tag,
                   "verification": verification(file, traj, info.status, None, {})},
            phases=traj if task.trajectory else []))
    return out


def nlp_tasks(path: str | Path, spec, doc: dict[str, Any], parameters: dict[str, float] | None = None,
              seed: int = 0, trajectory: bool = True) -> list[NLPTask]:
    """The tasks of an ``enumerate`` study with ``solver: nlp`` (see the module docstring)."""
    parameters = dict(parameters or {})
    objectives = {k: o.expr for k, o in spec.objectives.items()}
    families = spec.alternatives or {"": [{}]}
    tasks: list[NLPTask] = []
    if spec.starts_from == "closed_form":
        from ocdsl.study.pareto_run import _two_burn_from_doc, two_burn_pareto

        if (doc.get("model") or {}).get("use") != "relative_motion_secular":
            raise ValueError("starts_from closed_form exists for the two-burn programme of "
                             "relative_motion_secular")
        phase_names = list(doc.get("phases") or {})
        if len(phase_names) != 4:
            raise ValueError("starts_from closed_form: the two-burn programme has four phases "
                             "(wait, burn1, coast, burn2 in order)")
        rng = np.random.default_rng(seed)
        for fam, sets in families.items():
            for ps in sets:
                pars = {**parameters, **{k: float(v) for k, v in ps.items()}}
                d = dict(doc, alternatives={fam: [{"s1": pars["s1"], "s2": pars["s2"]}]})
                y0, fams, window, final = _two_burn_from_doc(d, spec, pars, str(path))
                roots = two_burn_pareto(y0, fams, window, final, dedup_tol=spec.dedup_tol,
                                        trajectory=False)
                for p in roots.points:
                    v = p.variables
                    exact = (v["t0"], v["t1"], v["tp"], v["t2"])
                    moved = [max(x + spec.perturbation * rng.uniform(-1, 1), 0.5 * x) for x in exact]
                    tasks.append(NLPTask(str(path), pars, fam, [dict(zip(phase_names, moved))],
                                         objectives, spec.residual_tol, trajectory,
                                         tag={"closed_form_root": dict(zip(phase_names, exact))}))
        return tasks
    # window grid: the window's durations on a grid of every cell, other phases at their guess
    cells = {k: P.window_cells(*w.range, w.split) for k, w in spec.window.items()}
    counts = {k: w.starts for k, w in spec.window.items()}
    defaults = {}
    for name, ph in (doc.get("phases") or {}).items():
        g = ((ph.get("guess") or {}).get("tf"))
        defaults[name] = float(g) if g is not None else 1.0
    import itertools

    for fam, sets in families.items():
        for ps in sets:
            pars = {**parameters, **{k: float(v) for k, v in ps.items()}}
            for combo in itertools.product(*cells.values()):
                cell = dict(zip(cells, combo))
                starts = []
                for s in P.grid_starts(cell, counts):
                    st = dict(defaults)
                    st.update({k.rsplit(".", 1)[0]: v for k, v in s.items()})
                    starts.append(st)
                tasks.append(NLPTask(str(path), pars, fam, starts, objectives, spec.residual_tol, trajectory))
    return tasks


# ---------------------------------------------------------------------------------------
# Epsilon-constraint point solver
# ---------------------------------------------------------------------------------------
@dataclass
class EpsilonSolver:
    """``solve(eps, warm) -> ParetoPoint``: minimise the file's objective with ``parameter = eps``.

    The file's objective is the first Pareto objective (its value is the NLP's objective);
    the other objectives are evaluated from the phases' final times (``tf``,
    ``<phase>.tf``, ``<phase>.duration``). ``warm`` is the previous point's trajectories.
    """

    path: str
    parameter: str
    objectives: dict[str, str]
    parameters: dict[str, float] = field(default_factory=dict)
    family: str = ""
    trajectory: bool = True
    # (constrained objective, first objective, label, trajectories) of solutions of another
    # study (e.g. the two-burn roots); for each eps the seed with the best first objective
    # within the bound is a second start, and the better of the two solves is kept
    seeds: list[tuple[float, float, str, list[PhaseTrajectory]]] = field(default_factory=list)

    def __call__(self, eps: float, warm: Any = None) -> P.ParetoPoint | None:
        import pyomo.core as pyo

        from ocdsl.transcribe.guess import make_guess
        from ocdsl.transcribe.solution import extract

        file = compiled(self.path, {**self.parameters, self.parameter: float(eps)})
        problem = file.problem
        starts = [("warm" if isinstance(warm, list) else "default", warm if isinstance(warm, list) else None)]
        fit = [sd for sd in self.seeds if sd[0] <= eps]
        if fit:
            best = min(fit, key=lambda sd: sd[1])
            starts.append((f"seed {best[2]}", best[3]))
        tr = info = None
        t = time.perf_counter()
        tried = []
        for tag, traj in starts:
            previous = {p.name: p for p in traj} if traj else {}
            guesses = {ph.name: make_guess(problem, ph, previous.get(ph.name)) for ph in problem.phases}
            tr_i, info_i = _solve(file, guesses)
            tried.append({"start": tag, "status": info_i.status, "objective": info_i.objective,
                          "iterations": info_i.iterations})
            if info_i.status in GOOD and (info is None or info_i.objective < info.objective):
                tr, info, start_tag = tr_i, info_i, tag
        secs = time.perf_counter() - t
        if info is None:
            return None
        phases = extract(tr)
        names = {"objective": info.objective}
        for pb in tr.phases:
            t0, tf = float(pyo.value(pb.block.t0)), float(pyo.value(pb.block.tf))
            names.update({f"{pb.phase.name}.tf": tf, f"{pb.phase.name}.duration": tf - t0})
            if len(tr.phases) == 1:
                names.update({"tf": tf, "duration": tf - t0})
        objs = {}
        for i, (k, e) in enumerate(self.objectives.items()):
            objs[k] = float(info.objective) if i == 0 else evaluate(e, names)
        return P.ParetoPoint(
            objectives=objs, variables={**{k: v for k, v in names.items() if k != "objective"},
                                        self.parameter: float(eps)},
            family=self.family, status=info.status,
            extra={"iterations": info.iterations, "solve_time_s": secs, "nlp": info.nlp,
                   "start": start_tag, "starts": tried,
                   "verification": verification(file, phases, info.status, float(info.objective),
                                                {s.name: float(pyo.value(v)) for s, v in tr.scalars.items()
                                                 if s in problem.free_parameters})},
            phases=phases if self.trajectory else [], warm=phases)


def seeds_from(points: list[P.ParetoPoint], constrained: str, first: str,
               phase: str = "main") -> list[tuple[float, float, str, list[PhaseTrajectory]]]:
    """Seeds for :class:`EpsilonSolver` from the points of another study (with trajectories).

    The phases of each point are joined into one phase ``phase`` on their common clock; a
    control ``delta`` is also given as its positive and negative parts ``dp``, ``dm`` (the
    smooth |delta| = dp + dm of ``configs/seed4_unrestricted.yaml``).
    """
    out = []
    for p in points:
        if not p.phases:
            continue
        t = np.concatenate([q.time for q in p.phases])
        states = {k: np.concatenate([q.states[k] for q in p.phases]) for k in p.phases[0].states}
        controls = {k: np.concatenate([q.controls[k] for q in p.phases]) for k in p.phases[0].controls}
        if "delta" in controls:
            controls["dp"] = np.maximum(controls["delta"], 0.0)
            controls["dm"] = np.maximum(-controls["delta"], 0.0)
        out.append((float(p.objectives[constrained]), float(p.objectives[first]), p.label or p.family,
                    [PhaseTrajectory(phase, t, states=states, controls=controls)]))
    return out


# ---------------------------------------------------------------------------------------
# Several studies in one table (one figure)
# ---------------------------------------------------------------------------------------
def combine_sets(sets: list[P.ParetoSet], method: str = "compare") -> P.ParetoSet:
    """One set holding the points of several studies (same objectives), families kept.

    Each point keeps its own study's Pareto flag (``pareto``); ``extra['pareto_overall']``
    says whether it is also non-dominated in the union, i.e. what the comparison costs.
    """
    objectives, senses = sets[0].objectives, sets[0].senses
    points = [p for s in sets for p in s.points]
    mask = P.nondominated([[p.objectives[o] for o in objectives] for p in points], senses)
    for p, m in zip(points, mask):
        p.extra["pareto_overall"] = bool(m)
    return P.ParetoSet(points, list(objectives), list(senses), method,
                       info={"studies": [s.method for s in sets]})


def write_comparison(out: str | Path, sets: list[P.ParetoSet], name: str,
                     wall_time_s: float | None = None) -> Path:
    """Write the combined study folder of :func:`combine_sets` (``pareto.csv`` with a family
    column: e.g. ``same``/``opposite`` two-burn roots and the ``unrestricted`` front), the
    table the report's Pareto figure reads."""
    s = combine_sets(sets)
    for p in s.points:
        if not p.label:
            p.label = f"{p.family}.{id(p)}"
    return s.write(out, name, {"pareto": "compare"}, wall_time_s=wall_time_s)
