"""``method: {transcription: parametric, ...}`` as a runner of the problem-file pipeline."""
from __future__ import annotations

from ..methods import register_runner
from ..result import Result


def integer_parameters(file) -> list[str]:
    """Names of the file's parameters declared ``integer: true`` (such as N_rev)."""
    from ..spec.schema import ParameterSpec

    return [n for n, p in file.spec.parameters.items() if isinstance(p, ParameterSpec) and p.integer]


def shooting_problem(file):
    """The paper-mode shooting problem (``search.run.ParametricProblem``) of a loaded
    parametric file, built as ``ocdsl run`` builds it."""
    from .run import build

    return build(file.problem, file.method, integer_parameters(file))


def run_parametric_file(file, timer, *, seed=None, warm_start=None, verbose=False, progress=False) -> Result:
    from ..run import check_expectations
    from .run import run

    result = run(file.problem, file.method, progress=progress, seed=seed, name=file.spec.name,
                 integer_parameters=integer_parameters(file))
    # the search's own stages (build: the kernel; solve: the swarm; polish, refine, post) are
    # disjoint; one "solve" around them all counted the kernel's build twice (unseen9 F12:
    # build 22.6 + solve 44.4 in a 44.6 s run)
    for stage, seconds in result.wall_time_s.items():
        if stage != "total":
            timer.add(stage, seconds)
    values = {}
    for s, bv in file.problem.boundary_values.items():
        traj = next((p for p in result.phases if p.name == bv.phase), None)
        if traj is not None and bv.var.name in traj.states:
            arr = traj.states[bv.var.name]
            values[s] = float(arr[0] if bv.which == "t0" else arr[-1])
    for ph in file.problem.phases:
        if isinstance(result.tf, (int, float)):
            values[ph.tf_symbol] = float(result.tf)
        values[ph.t0_symbol] = float(ph.t0 or 0.0)
    for s in file.problem.free_parameters:
        if s.name in result.parameters:
            values[s] = float(result.parameters[s.name])
    result.expect = check_expectations(file, values, result.objective)
    _control_bounds(file, result)
    result.wall_time_s = timer.breakdown()
    return result


def _control_bounds(file, result: Result) -> None:
    """The series are searched in their coefficients' box, not in the problem's control
    bounds, and nothing saturates them: a search result whose control leaves a bound the
    problem states (``-1 <= u <= 1``) is no feasible trajectory of the problem (unseen19 F2:
    `feasible`, u up to 5.14, the verification failing on the mesh). It becomes `infeasible`,
    saying which control and how far."""
    from .run import controls_outside_bounds

    if result.status != "feasible":
        return
    tol = float(file.spec.verify.tolerance)
    out = []
    for ph, traj in zip(file.problem.phases, result.phases):
        bounds = {c.name: ph.control_bounds.get(c) for c in ph.controls}
        for name, (a, b) in controls_outside_bounds(ph, traj.controls, tol).items():
            lo, hi = (float(v) for v in bounds[name])
            out.append(f"{name} reaches {a:.6g} .. {b:.6g} against {lo:g} <= {name} <= {hi:g}")
    if out:
        result.status = "infeasible"
        result.message = (f"{result.message}; but the series control leaves the problem's bounds ({'; '.join(out)}): "
                          "a series is searched in its coefficients' box and is not saturated, so the "
                          "terminal errors are met by a control the problem does not allow. Narrow the "
                          "series' `bounds` and `a0`, lower its order, or use a pseudospectral method")


register_runner("parametric", run_parametric_file)
