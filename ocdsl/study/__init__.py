"""Studies: many solves of one problem (sweeps, multi-starts, Monte Carlo, Pareto points,
PSO swarms) on one executor, from one core to a Dask cluster. See docs/studies.md."""
from .spec import Point, StudyError, StudySpec, load_study  # noqa: F401


def run_study(*args, **kwargs):
    """See :func:`ocdsl.study.run.run_study` (imported lazily)."""
    from .run import run_study as _run_study
    return _run_study(*args, **kwargs)
