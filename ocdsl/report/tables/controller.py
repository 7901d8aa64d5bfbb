"""Controller comparison (settling, overshoot, peak control, cost, time per update) and
the closed-loop runs."""
from __future__ import annotations

import numpy as np

from ocdsl.result import Result
from ocdsl.report.tables.cells import cell, finite_or_none, fmt, status_cell, table


def controller_metrics(extra: dict) -> dict[str, dict]:
    """Controller name -> its closed-loop metrics (``extra[<controller>]["metrics"]``, as the
    controller back end writes them), in the file's order."""
    return {k: v["metrics"] for k, v in (extra or {}).items()
            if isinstance(v, dict) and isinstance(v.get("metrics"), dict)}


def _threshold_label(key: str, unit: str) -> tuple[float, str]:
    thr = float(key.split("@", 1)[1])
    if unit == "rad":
        return thr, f"settling to {fmt(np.degrees(thr), 3)}° [s]"
    return thr, f"settling to {fmt(thr, 3)}{(' ' + unit) if unit else ''} [s]"


def _regulated(res: Result, metrics: dict) -> tuple[list[str], str]:
    """The states the metrics measure, and their common unit ("" where they differ)."""
    units = (res.problem or {}).get("units") or {}
    states = list((metrics.get("states") or {}))
    return states, (units.get(states[0], "") if states and len({units.get(x, "") for x in states}) == 1 else "")


def controller_table(res: Result) -> dict | None:
    """The controllers side by side: settling time (every regulated state within each
    threshold), largest overshoot, peak control, cost, and the controller's time per
    update, from the metrics in ``result.json``."""
    mets = controller_metrics(res.extra)
    if not mets:
        return None
    first = next(iter(mets.values()))
    states, unit = _regulated(res, first)
    settle = sorted((k for k in first if k.startswith("settling_time@")), key=lambda k: -float(k.split("@")[1]))
    heads = [_threshold_label(k, unit)[1] for k in settle]
    rows = []
    for name, m in mets.items():
        st = m.get("states") or {}
        status = (res.extra.get(name) or {}).get("status", "")
        # past zero is an overshoot only of a response that comes back to zero: a pendulum that
        # fell from 60 to 252 degrees never crossed it and was "0 %" (unseen33)
        over = [finite_or_none(v.get("overshoot_pct")) for v in st.values() if isinstance(v, dict)] \
            if status in ("stable", "") else []
        over = [x for x in over if x is not None]
        peak = m.get("peak_control")
        peak = max(abs(float(x)) for x in peak) if isinstance(peak, list) and peak else finite_or_none(peak)
        ct = m.get("controller_time_s") or {}
        rows.append([cell(name, "name"), status_cell(str(status)) if status else cell("—"),
                     *[cell(m.get(k), "num", 4) for k in settle],
                     cell(max(over) if over else None, "num", 3), cell(peak, "num", 4),
                     cell(m.get("cost"), "num", 6), cell(m.get("control_cost"), "num", 5),
                     cell(1e3 * ct["mean"] if finite_or_none(ct.get("mean")) is not None else None, "num", 3),
                     cell(1e3 * ct["p95"] if finite_or_none(ct.get("p95")) is not None else None, "num", 3)])
    over_of = ", ".join(states) if states else "the states"
    settling = (f"settling time (every one of {over_of} within the threshold from then on), " if heads else "")
    return table("controllers", f"Controller comparison: {settling}largest overshoot of {over_of} past zero "
                 "(— for a law that does not regulate the plant), peak control magnitude, the cost J "
                 "and its control part, and the controller's computation time per update.",
                 ["controller", "status", *heads, "overshoot [%]", "peak control", "cost J", "control cost",
                  "time/update mean [ms]", "95 % [ms]"], rows)


def closed_loop_table(tables: dict[str, dict[str, np.ndarray]], problem: dict,
                      extra: dict | None = None) -> dict | None:
    """Per closed-loop run: samples, final time, the final size of the regulated states
    (those the metrics name; all states otherwise) and the controller timing (the table's
    ``timing`` column, else the metrics' ``controller_time_s``)."""
    rows = []
    states = set()
    for info in (problem.get("phases") or {}).values():
        states |= set(info.get("states") or [])
    mets = controller_metrics(extra or {})
    for name, tab in sorted(tables.items()):
        if not name.startswith("closed_loop_") or "t" not in tab:
            continue
        cname = name[len("closed_loop_"):]
        m = mets.get(cname.rsplit(":", 1)[-1], {})
        t = np.asarray(tab["t"], float)
        regulated = [k for k in (m.get("states") or {}) if k in tab]
        sv = regulated or [k for k in tab if k in states] or [k for k in tab if k not in ("t", "timing")]
        final = np.array([np.asarray(tab[k], float)[-1] for k in sv]) if t.size else np.array([])
        timing = np.asarray(tab.get("timing", []), float) * 1e3
        timing = timing[np.isfinite(timing)]
        ct = m.get("controller_time_s") or {}
        mean = float(np.mean(timing)) if timing.size else (1e3 * ct["mean"] if "mean" in ct else None)
        p95 = float(np.percentile(timing, 95)) if timing.size else (1e3 * ct["p95"] if "p95" in ct else None)
        mx = float(np.max(timing)) if timing.size else (1e3 * ct["max"] if "max" in ct else None)
        rows.append([cell(cname, "name"), cell(int(t.size)), cell(float(t[-1]) if t.size else None),
                     cell(float(np.linalg.norm(final)) if final.size else None, "num", 4),
                     cell(mean, "num", 4), cell(p95, "num", 4), cell(mx, "num", 4)])
    return table("closed_loop", "Closed-loop runs: final size of the regulated states ("
                 + (", ".join(sorted({k for m in mets.values() for k in (m.get('states') or {})})) or "all states")
                 + ") and the controller's time per update.",
                 ["controller", "samples", "final t", "final ‖x‖", "mean [ms]", "95 % [ms]", "max [ms]"], rows)


def robustness_table(res: Result) -> dict | None:
    """The robustness sweep (``tables/robustness.csv``): each law, designed on the nominal
    plant, flown on plants whose parameters are scaled by each factor: whether it regulates,
    its cost, peak control and the metrics the file asked for (unseen33: the console said
    "every law regulates at 0.8 only", the report held a raw CSV)."""
    tab = res.tables.get("robustness")
    if not tab or "factor" not in tab:
        return None
    rob = (((res.method or {}).get("controller") or {}).get("robustness") or {})
    scaled = ", ".join(rob.get("parameters") or []) or "the parameters"
    laws = [c[:-len(".stable")] for c in tab if c.endswith(".stable")]
    extra_cols = sorted({c.split(".", 1)[1] for c in tab if "." in c}
                        - {"stable", "cost", "peak_control"})
    states, unit = _regulated(res, next(iter(controller_metrics(res.extra).values()), {}))
    norm = f"|{states[0]}|" if len(states) == 1 else "max over the states of |x|"
    heads = [_threshold_label(k, unit)[1] if k.startswith("settling_time@")
             else f"max {norm} after t = {k.split('@', 1)[1]}" + (f" [{unit}]" if unit else "") for k in extra_cols]
    def at(column: str, i: int):
        return tab[column][i] if column in tab else None

    rows = []
    for i, factor in enumerate(tab["factor"]):
        for law in laws:
            held = float(tab[f"{law}.stable"][i]) == 1.0
            rows.append([cell(f"{float(factor):g}"), cell(law, "name"), cell("yes" if held else "no", ""),
                         cell(at(f"{law}.cost", i), "num", 6), cell(at(f"{law}.peak_control", i), "num", 4),
                         *[cell(finite_or_none(at(f"{law}.{k}", i)), "num", 4) for k in extra_cols]])
    verdicts = "; ".join(
        f"{law} regulates at "
        + (", ".join(f"{float(f):g}" for f, v in zip(tab["factor"], tab[f"{law}.stable"]) if float(v) == 1.0)
           or "no factor") for law in laws)
    return table("robustness", f"Robustness: every law, designed on the nominal plant, flown on plants with "
                 f"{scaled} multiplied by the factor (— where it does not settle): {verdicts}.",
                 ["factor", "law", "regulates", "cost J", "peak control", *heads], rows)
