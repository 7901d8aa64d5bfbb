"""Closed-loop responses of controllers and their computation time per update."""
from __future__ import annotations

import numpy as np

from ocdsl.report.figures.base import (
    Fig, MAX_LEGEND, _bounds_of, _grid_figures, _new_figure, _nonempty, _run_colors, _styled, in_degrees,
    time_label)


# ------------------------------------------------------------------- closed loop
def closed_loop_tables(tables: dict[str, dict[str, np.ndarray]]) -> dict[str, dict[str, np.ndarray]]:
    return {k[len("closed_loop_"):]: v for k, v in sorted(tables.items())
            if k.startswith("closed_loop_") and "t" in v}


@_styled
def fig_closed_loop(tables: dict[str, dict[str, np.ndarray]], problem: dict, label_prefix: str = "") -> list[Fig]:
    """Closed-loop responses of each controller (one line per controller) and the
    controller's computation time per update (``timing`` column)."""
    cl = closed_loop_tables(tables)
    if not cl:
        return []
    units = problem.get("units") or {}
    states: list[str] = []
    controls: list[str] = []
    known_states, known_controls = set(), set()
    for info in (problem.get("phases") or {}).values():
        known_states |= set(info.get("states") or [])
        known_controls |= set(info.get("controls") or [])
    for tab in cl.values():
        for k in tab:
            if k in ("t", "timing"):
                continue
            if k in known_controls:
                controls += [k] if k not in controls else []
            elif k in known_states or not known_states:
                states += [k] if k not in states else []
    out: list[Fig] = []
    names = [label_prefix + c for c in cl]
    st = [(n, [(label_prefix + c, tab["t"], tab[n]) for c, tab in cl.items() if n in tab]) for n in states]
    st, _, st_units = in_degrees(st, None, units, problem)
    out += _grid_figures("cl-states", "Closed-loop state responses, one line per controller.", st, st_units)
    ct = [(n, [(label_prefix + c, tab["t"], tab[n]) for c, tab in cl.items() if n in tab]) for n in controls]
    if ct:
        bounds = _bounds_of(problem, controls)
        drawn = any(b is not None for lohi in bounds.values() for b in lohi)
        what = "the saturation" if problem.get("bounds_are") == "saturation" else "the control bounds"
        out += _grid_figures("cl-controls", "Closed-loop control histories"
                             + (f" (dashed: {what})." if drawn else "."), ct, units, bounds, step=True)
    timing = [(nm, np.asarray(tab["timing"], float)) for nm, tab in zip(names, cl.values()) if "timing" in tab]
    timing = [(nm, a[np.isfinite(a)] * 1e3) for nm, a in timing if _nonempty(a)]
    if timing:
        fig, axes = _new_figure(2, height=2.6)
        ax = axes[0]
        ax.boxplot([a for _, a in timing], showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(timing) + 1), [nm for nm, _ in timing], rotation=20, fontsize=7)
        ax.set_ylabel("time per update [ms]")
        ax.set_yscale("log")
        ax = axes[1]
        for (nm, a), tab, c in zip(timing, [t for t in cl.values() if "timing" in t], _run_colors(len(timing))):
            t = np.asarray(tab["t"], float)
            a_full = np.asarray(tab["timing"], float) * 1e3
            ax.plot(t, a_full, color=c, linewidth=0.8, label=nm)
        ax.set_yscale("log")
        ax.set_xlabel(time_label(units))
        ax.set_ylabel("time per update [ms]")
        if len(timing) <= MAX_LEGEND:
            ax.legend(fontsize=7, frameon=False)
        out.append(Fig("cl-timing", "Controller computation time per update: distribution (left) "
                       "and along the closed-loop run (right).", fig))
    return out
