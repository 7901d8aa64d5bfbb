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
    result.wall_time_s = timer.breakdown()
    return result


register_runner("parametric", run_parametric_file)
