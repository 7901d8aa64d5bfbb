"""Tables from a run folder's columns: any ``tables/<name>.csv`` and the re-integration."""
from __future__ import annotations

from typing import Any

import numpy as np

from ocdsl.result import Result
from ocdsl.report.status import unjudged_flight
from ocdsl.report.tables.cells import cell, fmt, status_cell, table, truthy


# -------------------------------------------------------------------- run tables
def _number(v: Any) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True


def _digits(column: str, digits: int) -> int:
    """An objective column shows ten digits: a mesh history's J converging in its seventh
    digit read 8.24621 three times (unseen33 F11)."""
    return max(digits, 10) if column in ("objective", "J") or column.startswith("objective") else digits


def column_table(key: str, caption: str, cols: dict[str, Any], max_rows: int = 40, digits: int = 6,
                 drop_constant: bool = False) -> dict | None:
    """A tables/<name>.csv (or study table) as rows; long tables are thinned evenly;
    ``drop_constant``: columns with one value in every row are named in the note instead."""
    if not cols:
        return None
    names = list(cols)
    constant = []
    if drop_constant and max((len(v) for v in cols.values()), default=0) > 1:
        for c in names:
            # equal values, not equal-looking ones: J 10.024880738 and 10.024937811 were "the same
            # in every row" at six digits (unseen33 F14)
            if len({repr(v) if isinstance(v, (str, bytes)) else repr(float(v)) if _number(v) else repr(v)
                    for v in cols[c]}) == 1:
                constant.append(f"{c} = {fmt(cols[c][0], _digits(c, digits))}")
        names = [c for c in names if not any(x.startswith(f"{c} = ") for x in constant)] or list(cols)
    n = max((len(v) for v in cols.values()), default=0)
    idx = list(range(n))
    note = ""
    if n > max_rows:
        idx = sorted(set(np.linspace(0, n - 1, max_rows).round().astype(int).tolist()))
        note = f"{len(idx)} of {n} rows shown (evenly spaced); the full table is in the run folder."
    rows = []
    for i in idx:
        row = []
        for c in names:
            v = cols[c][i] if i < len(cols[c]) else None
            if c == "status":
                row.append(status_cell(str(v)))
            elif c == "pareto":
                row.append({"text": "Pareto" if truthy(v) else "", "cls": "pass" if truthy(v) else ""})
            else:
                row.append(cell(v, None, _digits(c, digits)))
        rows.append(row)
    if constant:
        note = (note + " " if note else "") + "The same in every row: " + "; ".join(constant) + "."
    return table(key, caption, [c.replace("_", " ") for c in names], rows, note)


def reintegration_table(res: Result) -> dict | None:
    """Per state: the re-integrated trajectory (``tables/reintegration_<phase>.csv``, written
    by the run's verification) against the solution's rows: largest and final deviation,
    and the largest relative to the state's range (``err_<state>``, the verification's measure)."""
    rows = []
    for tname, tab in sorted(res.tables.items()):
        if not (tname == "reintegration" or tname.startswith("reintegration_")) or "t" not in tab:
            continue
        phase = tname[len("reintegration_"):] if tname != "reintegration" else None
        phases = [p for p in res.phases if phase is None or p.name == phase]
        label = phase if phase and len(res.phases) > 1 else None
        t_r = np.asarray(tab["t"], float)
        for n, y_r in tab.items():
            if n == "t" or n.startswith("err_"):
                continue
            ts, ys = [], []
            for p in phases:
                if n in p.states:
                    ts.append(np.asarray(p.time, float))
                    ys.append(np.asarray(p.states[n], float))
            if not ts or t_r.size < 2:
                continue
            t_c, y_c = np.concatenate(ts), np.concatenate(ys)
            ok = np.isfinite(t_c) & np.isfinite(y_c)
            t_c, y_c = t_c[ok], y_c[ok]
            order = np.argsort(t_r, kind="stable")
            y_r = np.asarray(y_r, float)[order]
            dev = np.abs(np.interp(t_c, t_r[order], y_r) - y_c)
            if f"err_{n}" in tab:
                rel = float(np.nanmax(np.asarray(tab[f"err_{n}"], float)))
            else:
                rng = float(np.nanmax(y_c) - np.nanmin(y_c)) if y_c.size else 0.0
                rel = float(np.nanmax(dev)) / max(rng, 1e-300)
            rows.append([cell(f"{label}: {n}" if label else n, "name"), cell(float(np.nanmax(dev)), "num", 3),
                         cell(rel, "num", 3), cell(float(abs(y_r[-1] - y_c[-1])), "num", 3)])
    return table("reintegration", "Re-integration: the dynamics integrated from the solution's initial "
                 "state with its controls (the verification's trajectory, from the run folder) against "
                 "the solution's rows." + unjudged_flight(res, None),
                 ["state", "max |deviation|", "relative to its range", "final deviation"], rows)
