"""Studies: outputs against the swept parameter, distributions, runs overlaid."""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ocdsl.result import Result
from ocdsl.report.tables import finite_or_none, truthy
from ocdsl.report.figures.base import (
    Fig, _bounds_of, _grid_figures, _new_figure, _styled, axis_label, unit_tex)
from ocdsl.report.figures.time import phase_time


@_styled
def fig_sweep(rows: list[dict[str, Any]], param: str, outputs: Sequence[str], units: dict | None = None,
              objective_label: str = "objective") -> list[Fig]:
    """Outputs (objective, t_f per phase) against the swept parameter: the ok points joined,
    converged points that are not ok (verification or certificate failed) as open circles,
    points that did not converge as x (unseen33 F4: unverified points drawn as a clean line)."""
    outputs = [o for o in outputs if any(finite_or_none(r.get(o)) is not None for r in rows)]
    if not outputs:
        return []
    units = units or {}
    fig, axes = _new_figure(len(outputs))
    good = ("optimal", "acceptable", "feasible", "stable")
    for ax, o in zip(axes, outputs):
        pts = [(float(r[param]), float(r[o]), str(r.get("status", "optimal")) in good, truthy(r.get("ok", True)))
               for r in rows if finite_or_none(r.get(param)) is not None and finite_or_none(r.get(o)) is not None]
        ok = sorted((x, y) for x, y, g, k in pts if g and k)
        doubtful = [(x, y) for x, y, g, k in pts if g and not k]
        bad = [(x, y) for x, y, g, _ in pts if not g]
        if ok:
            ax.plot([p[0] for p in ok], [p[1] for p in ok], marker="o", markersize=3, label="ok")
        if doubtful:
            ax.plot([p[0] for p in doubtful], [p[1] for p in doubtful], "o", markerfacecolor="none",
                    color="#d35400", label="converged, not ok")
        if bad:
            ax.plot([p[0] for p in bad], [p[1] for p in bad], "x", color="#c0392b", label="not converged")
        if doubtful or bad:
            ax.legend(fontsize=7, frameon=False)
        ax.set_xlabel(axis_label(param, units))
        if o == "objective":
            ax.set_ylabel(objective_label)
        else:
            phase = o[len("tf ("):-1] if o.startswith("tf (") else ""
            unit = units.get("t")
            ax.set_ylabel("$t_f$" + (f" ({phase})" if phase else "") + (f" [{unit_tex(unit)}]" if unit else ""))
    return [Fig("sweep", f"Study outputs against the swept parameter {param}.", fig)]


@_styled
def fig_histograms(rows: list[dict[str, Any]], outputs: Sequence[str]) -> list[Fig]:
    data = [(o, np.array([finite_or_none(r.get(o)) for r in rows if finite_or_none(r.get(o)) is not None]))
            for o in outputs]
    data = [(o, a) for o, a in data if a.size >= 2]
    if not data:
        return []
    fig, axes = _new_figure(len(data))
    for ax, (o, a) in zip(axes, data):
        ax.hist(a, bins=min(30, max(5, a.size // 3)), color="#1f4e9c", alpha=0.8)
        ax.set_xlabel(o.replace("_", " "))
        ax.set_ylabel("runs")
    return [Fig("histograms", "Distribution of the study outputs over its runs.", fig)]


@_styled
def fig_compare_runs(results: list[Result]) -> list[Fig]:
    """States and controls of several runs overlaid (one line per run)."""
    if not results or not any(r.phases for r in results):
        return []
    # units and bounds are drawn only where every run declares the same (unseen43 F12: the first
    # run's units on every axis, its bounds over runs without them)
    declared = [(r.problem or {}).get("units") or {} for r in results]
    units = declared[0] if all(u == declared[0] for u in declared) else {}
    # the legend names a run without a solution (the comparison report's labels); the caption
    # counts them, for figures with too many runs for a legend (unseen43 F9)
    unsolved = sum(not r.has_solution for r in results)
    note = f" {unsolved} of {len(results)} did not end with a solution: they show last iterates or guesses." if unsolved else ""
    out: list[Fig] = []
    for attr, what in (("states", "State"), ("controls", "Control")):
        names: list[str] = []
        for r in results:
            for p in r.phases:
                names += [n for n in getattr(p, attr) if n not in names]
        panels = [(n, [(r.name, phase_time(r, p), getattr(p, attr)[n]) for r in results for p in r.phases
                       if n in getattr(p, attr)]) for n in names]
        if panels:
            bounds = [_bounds_of(r.problem or {}, names) for r in results] if attr == "controls" else [None]
            out += _grid_figures(f"cmp-{attr}", f"{what} histories of the compared runs, one colour per run.{note}",
                                 panels, units, bounds[0] if all(b == bounds[0] for b in bounds) else None)
    return out
