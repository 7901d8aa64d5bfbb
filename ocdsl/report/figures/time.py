"""Time axes: physical time of a phase (a Sundman run's time state) and the phases' boundaries."""
from __future__ import annotations

import numpy as np

from ocdsl.result import PhaseTrajectory, Result
from ocdsl.report.status import what_is_drawn
from ocdsl.report.figures.base import Series


def time_variable(res: Result) -> str | None:
    """The state that is physical time when the independent variable is not (a Sundman
    run: ``problem.time_variable``); None when the independent variable is time."""
    tv = (res.problem or {}).get("time_variable")
    return tv if tv and any(tv in p.states for p in res.phases) else None


def phase_time(res: Result, p: PhaseTrajectory) -> np.ndarray:
    """Physical time of a phase's rows: what every time axis shows."""
    tv = time_variable(res)
    return np.asarray(p.states[tv] if tv and tv in p.states else p.time, float)


def _phase_series(res: Result, attr: str, prefix: str = "") -> list[tuple[str, Series]]:
    names: list[str] = []
    skip = time_variable(res) if attr == "states" else None    # time against time says nothing
    for p in res.phases:
        for n in getattr(p, attr):
            if n not in names and n != skip:
                names.append(n)
    multi = len(res.phases) > 1
    return [(prefix + n, [(p.name if multi else what_is_drawn(res), phase_time(res, p), getattr(p, attr)[n])
                          for p in res.phases if n in getattr(p, attr)]) for n in names]


def _sequential(res: Result) -> bool:
    """Phases one after another in time (not alternatives over the same interval, as the
    controllers of a controller file are)."""
    ends = [(float(np.nanmin(phase_time(res, p))), float(np.nanmax(phase_time(res, p)))) for p in res.phases
            if len(p.time)]
    return all(b[0] >= a[1] - 1e-9 * max(1.0, abs(a[1])) for a, b in zip(ends, ends[1:]))


def _phase_boundaries(res: Result) -> list[float]:
    if len(res.phases) < 2 or not _sequential(res):
        return []
    return [float(np.asarray(phase_time(res, p), float)[-1]) for p in res.phases[:-1] if len(p.time)]


def _phases_note(res: Result) -> str:
    if len(res.phases) < 2:
        return ""
    return " Phases in colour, phase boundaries dotted." if _sequential(res) else " One line per phase (run)."

def _time_units(res: Result) -> dict[str, str]:
    """Only the unit of time (panels of costates and Hamiltonian quantities have none)."""
    u = (res.problem.get("units") or {}).get("t")
    return {"t": u} if u else {}
