"""Tables of the problem: states and controls, parameters, method, phases."""
from __future__ import annotations

import numpy as np

from ocdsl.result import Result
from ocdsl.report.tables.cells import cell, finite_or_none, fmt, name_cell, table, unit_cell
from ocdsl.report.tables.details import _flatten


def variables_table(res: Result, kind: str) -> dict | None:
    """States or controls: name, unit, bounds, phases; one row per name and distinct bounds
    (unseen9 F7: a control bounded [1, 1], [0, 0] and [-1, -1] in three phases was shown with
    the first phase's bounds for all three)."""
    problem = res.problem or {}
    units = problem.get("units") or {}
    seen: dict[tuple, dict] = {}
    for pname, info in (problem.get("phases") or {}).items():
        for n in info.get(kind) or []:
            b = (info.get("bounds") or {}).get(n)
            e = seen.setdefault((n, None if b is None else tuple(b)), {"phases": [], "bounds": b})
            e["phases"].append(pname)
    if not seen:  # no description: fall back to the trajectory's columns
        for p in res.phases:
            for n in getattr(p, kind):
                seen.setdefault((n, None), {"phases": [], "bounds": None})["phases"].append(p.name)
    # a controller file's "phases" are its laws, on one plant: a column of them says nothing
    multi = len(problem.get("phases") or {}) > 1 and not (res.extra or {}).get("laws")
    rows = []
    for (n, _), e in seen.items():
        lo, hi = (e["bounds"] if isinstance(e["bounds"], (list, tuple)) and len(e["bounds"]) == 2
                  else (None, None))
        lo, hi = finite_or_none(lo), finite_or_none(hi)
        row = [name_cell(n), unit_cell(units.get(n, "")),
               cell(lo) if lo is not None else cell("−∞" if e["bounds"] else "—", "num"),
               cell(hi) if hi is not None else cell("∞" if e["bounds"] else "—", "num")]
        if multi:
            row.append(cell(", ".join(e["phases"]), ""))
        rows.append(row)
    cols = ["name", "unit", "lower bound", "upper bound"] + (["phases"] if multi else [])
    saturation = kind == "controls" and problem.get("bounds_are") == "saturation"
    return table(kind, f"{kind.capitalize()} of the problem"
                 + ("; the bounds are the controllers' saturation, to which every command is clipped." if saturation
                    else "."), cols, rows)


def parameters_table(res: Result) -> dict | None:
    problem_params = (res.problem or {}).get("parameters") or {}
    units = (res.problem or {}).get("units") or {}
    names = list(problem_params) + [n for n in res.parameters if n not in problem_params]
    rows = []
    for n in names:
        info = problem_params.get(n) or {}
        if not isinstance(info, dict):
            info = {"value": info}
        value = res.parameters.get(n, info.get("value"))
        free = bool(info.get("free", False))
        # "file" is recorded by the compiler only where --param or a study set the value: a
        # phase's own value (PHASE.b) is no override of the file's b
        overridden = (not free and "file" in info
                      and finite_or_none(info["file"]) != finite_or_none(value))
        note = "free (optimised)" if free else ("overridden (file: %s)" % fmt(info["file"]) if overridden
                                                else "")
        rows.append([name_cell(n), cell(value), unit_cell(units.get(n, "")), cell(note, "")])
    return table("parameters", "Parameters and the values used in this run.",
                 ["name", "value", "unit", "note"], rows)


def method_table(res: Result) -> dict | None:
    rows = [[cell(k, "name"), cell(v, "num" if isinstance(v, (int, float)) and not isinstance(v, bool) else "")]
            for k, v in _flatten(res.method)]
    return table("method", "Method, mesh and solver options.", ["setting", "value"], rows)


def phases_table(res: Result) -> dict | None:
    """Per-phase summary (only for several phases)."""
    if len(res.phases) < 2:
        return None
    tf = res.tf if isinstance(res.tf, dict) else {}
    rows = []
    for p in res.phases:
        t = np.asarray(p.time, float)
        t0 = float(t[0]) if t.size else None
        t1 = float(t[-1]) if t.size else tf.get(p.name)
        rows.append([cell(p.name, "name"), cell(int(t.size)), cell(t0), cell(t1),
                     cell(t1 - t0 if t0 is not None and t1 is not None else None),
                     cell(len(p.states)), cell(len(p.controls))])
    return table("phases", "Phases of the solution.",
                 ["phase", "nodes", "t₀", "t_f", "duration", "states", "controls"], rows)
