"""Time histories of a run: states and controls, costates, other columns, and the
re-integration over the collocated states."""
from __future__ import annotations

import numpy as np

from ocdsl.angles import unwrap_finite
from ocdsl.result import Result
from ocdsl.report.status import unjudged_flight, what_is_drawn
from ocdsl.report.figures.base import (
    FLAG_COLUMNS, HAMILTONIAN_KEYS, Fig, Series, MAX_PANELS, _bounds_of, _chunks, _grid_figures, _new_figure,
    _nonempty, _styled, axis_label, in_degrees, tex_name, time_label)
from ocdsl.report.figures.time import (
    _phase_boundaries, _phase_series, _phases_note, _time_units, phase_time, time_variable)


ANGLE_PERIODS = {"rad": 2 * np.pi, "deg": 360.0, "degree": 360.0, "degrees": 360.0}


def unwrapped(panels: list[tuple[str, Series]], units: dict) -> tuple[list[tuple[str, Series]], str]:
    """Angles (unit rad or deg) that jump by more than half a turn between rows, drawn
    unwrapped (a direction crossing +-pi is one continuous curve, not a 2 pi jump); the
    caption's note names them."""
    out, names = [], []
    for name, series in panels:
        period = ANGLE_PERIODS.get(str(units.get(name, "")).strip().lower())
        if period is not None and any(np.any(np.abs(np.diff(np.asarray(y, float))) > period / 2) for _, _, y in series):
            series = [(lab, t, unwrap_finite(y, period)) for lab, t, y in series]
            names.append(name)
        out.append((name, series))
    note = (f" Angles {', '.join(names)} unwrapped (no jumps of a full turn)." if names else "")
    return out, note


@_styled
def fig_states_controls(res: Result) -> list[Fig]:
    """States and controls against time; control (and state) bounds dashed."""
    units = res.problem.get("units") or {}
    out: list[Fig] = []
    note = _phases_note(res)
    drawn = what_is_drawn(res)
    if drawn != "solution":
        note = f" Not a solution: the run ended {res.status}; drawn is its {drawn}." + note
    st = _phase_series(res, "states")
    st, bounds, st_units = in_degrees(st, _bounds_of(res.problem, [n for n, _ in st]), units, res.problem)
    st, wrapped = unwrapped(st, st_units)
    if st:
        out += _grid_figures("states", "State histories." + note + " Dashed: bounds." + wrapped, st, st_units,
                             bounds, boundaries=_phase_boundaries(res))
    ct = _phase_series(res, "controls")
    ct, bounds, ct_units = in_degrees(ct, _bounds_of(res.problem, [n for n, _ in ct]), units, res.problem)
    ct, wrapped = unwrapped(ct, ct_units)
    if ct:
        out += _grid_figures("controls", "Control histories; dashed lines are the control bounds." + note + wrapped,
                             ct, ct_units, bounds,
                             boundaries=_phase_boundaries(res))
    return out


@_styled
def fig_costates(res: Result) -> list[Fig]:
    panels = _phase_series(res, "costates")
    if not panels:
        return []
    tex = {n: r"\lambda_{%s}" % tex_name(n) for n, _ in panels}
    units = _time_units(res)
    return _grid_figures("costates", "Costates (multipliers of the dynamics).", panels, units, tex=tex,
                         boundaries=_phase_boundaries(res))

@_styled
def fig_other_extra(res: Result) -> list[Fig]:
    """Time histories in the trajectory that are neither states, controls, costates nor
    Hamiltonian quantities (e.g. when the problem description is missing)."""
    multi = len(res.phases) > 1
    names: list[str] = []
    for p in res.phases:
        names += [k for k in p.extra if k not in names and k not in HAMILTONIAN_KEYS
                  and k not in FLAG_COLUMNS and not k.startswith(("dH_d", "switch_"))]
    panels = [(k, [(p.name if multi else "solution", phase_time(res, p), p.extra[k]) for p in res.phases
                   if k in p.extra])
              for k in names]
    return _grid_figures("other", "Other time histories in the trajectory.", panels,
                         res.problem.get("units") or {}, boundaries=_phase_boundaries(res))


@_styled
def fig_reintegration(res: Result) -> list[Fig]:
    """Collocated states (markers) against the re-integrated trajectory (line)."""
    out: list[Fig] = []
    units = res.problem.get("units") or {}
    for tname, table in sorted(res.tables.items()):
        if not (tname == "reintegration" or tname.startswith("reintegration_")) or "t" not in table:
            continue
        phase = tname[len("reintegration_"):] if tname != "reintegration" else None
        phases = [p for p in res.phases if phase is None or p.name == phase]
        tvar = time_variable(res)
        names = [k for k in table if k not in ("t", tvar) and not k.startswith("err_") and _nonempty(table[k])]
        if not names:
            continue
        chunks = _chunks(names, MAX_PANELS)
        for ci, chunk in enumerate(chunks):
            fig, axes = _new_figure(len(chunk))
            for ax, n in zip(axes, chunk):
                ax.plot(table.get(tvar, table["t"]) if tvar else table["t"], table[n], color="#c0392b",
                        linewidth=1.2, label="re-integrated")
                first = True
                for p in phases:
                    if n in p.states:
                        ax.plot(phase_time(res, p), p.states[n], linestyle="none", marker="o", markersize=2.6,
                                markerfacecolor="none", color="#1f4e9c",
                                label="collocated" if first else None)
                        first = False
                ax.set_ylabel(axis_label(n, units))
                ax.set_xlabel(time_label(units))
                ax.legend(fontsize=7, frameon=False, loc="best")
            where = f" of phase {phase}" if phase else ""
            suffix = f" ({ci + 1} of {len(chunks)})" if len(chunks) > 1 else ""
            out.append(Fig(f"reint-{tname}-{ci}",
                           f"Re-integrated trajectory{where} (line, from the optimal control) "
                           f"over the collocated states (markers).{suffix}{unjudged_flight(res, phase)}", fig))
    return out
