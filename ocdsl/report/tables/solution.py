"""Tables of the solution: the summary with its badges, times, wall time."""
from __future__ import annotations

from typing import Any

import numpy as np

from ocdsl.result import Result
from ocdsl.report.tables.cells import cell, finite_or_none, table


# ----------------------------------------------------------------------- solution
def badge_cell(b) -> dict[str, Any]:
    return {"text": b.text, "cls": {"pass": "pass", "fail": "fail", "warn": "warn"}.get(b.cls, "")}


def summary_table(res: Result) -> dict:
    from ocdsl.report.status import badges, what_is_drawn

    rows = []
    for b in badges(res):
        rows.append([cell(b.label, "name"), badge_cell(b)])
        if b.title:
            # a title that starts with the verdict itself ("verified: 7 checks ...") is not
            # prefixed with it again ("verified: verified: ...", unseen33 F11)
            said = b.title if str(b.title).lower().startswith(str(b.text).lower()) else f"{b.text}: {b.title}"
            rows[-1][1] = {**rows[-1][1], "text": said}
    sense = ((res.problem or {}).get("objective") or {}).get("sense")
    label = "objective" if res.has_solution else f"objective of the {what_is_drawn(res)}"
    if res.status == "mesh_not_converged":      # as the console says it (unseen43 F8: a plain result)
        label = "objective on the reported mesh (not converged)"
    front = res.extra.get("pareto_labels")
    if isinstance(front, list):     # a set has no one objective (unseen33 F9: its first point's)
        rows.append([cell("Pareto set", "name"),
                     cell(f"{res.extra.get('n_solutions', '?')} solutions, {len(front)} Pareto-optimal", "")])
    else:
        rows.append([cell(label + (f" ({sense})" if sense else ""), "name"), cell(res.objective, "num", 10)])
    # a failed run's times are its last iterate's or its guess's, said as for its objective
    # (unseen43 F6, F7: "final time t_f 5.05" unlabelled, the guess of a solve never started)
    whose = "" if res.has_solution else f" of the {what_is_drawn(res)}"
    for label, v in time_rows(res):
        rows.append([cell(label + whose, "name"), cell(v, "num", 10)])
    rows.append([cell("iterations", "name"), cell(res.iterations)])
    for k in ("variables", "constraints", "nonzeros"):
        if k in (res.nlp or {}):
            rows.append([cell(f"NLP {k}", "name"), cell(res.nlp[k])])
    for k, v in (res.nlp or {}).items():
        if k not in ("variables", "constraints", "nonzeros"):
            rows.append([cell(f"NLP {k}", "name"), cell(v)])
    if "total" in (res.wall_time_s or {}):
        rows.append([cell("wall time total [s]", "name"), cell(res.wall_time_s["total"], "num", 4)])
    return table("summary", "Solution summary: the solver's status, the independent verification, the "
                 "certificate and the expect checks; \"overall\" is the exit code of ocdsl run.",
                 ["quantity", "value"], rows)


def time_rows(res: Result) -> list[tuple[str, Any]]:
    """Final times in physical time: a run whose independent variable is not time (a
    Sundman-transformed problem) carries its physical time as the state or expression
    ``problem.time_variable`` names; its end is the flight time."""
    tvar = (res.problem or {}).get("time_variable")
    unit = ((res.problem or {}).get("units") or {}).get("t")
    u = f" [{unit}]" if unit else ""
    if tvar:
        ends = [(p.name, physical_time(p, tvar)) for p in res.phases]
        ends = [(n, float(a[np.isfinite(a)][-1])) for n, a in ends if a is not None and np.isfinite(a).any()]
        out = [(f"flight time ({tvar}(t_f)){u}" + (f" ({n})" if len(ends) > 1 else ""), v) for n, v in ends]
        if isinstance(res.tf, (int, float)):
            out.append(("final value of the independent variable", res.tf))
        return out
    if isinstance(res.tf, dict):
        return [(f"final time t_f ({k}){u}", v) for k, v in res.tf.items()]
    return [(f"final time t_f{u}", res.tf)]


def physical_time(p, tvar: str) -> np.ndarray | None:
    for group in (p.states, p.extra, p.controls):
        if tvar in group:
            return np.asarray(group[tvar], float)
    return None


def wall_time_table(res: Result) -> dict | None:
    wt = {k: v for k, v in (res.wall_time_s or {}).items() if finite_or_none(v) is not None}
    stages = [(k, float(v)) for k, v in wt.items() if k != "total"]
    if not stages:
        return None
    total = float(wt.get("total", sum(v for _, v in stages)))
    rows = [[cell(k, "name"), cell(v, "num", 4), cell(100 * v / total if total > 0 else None, "num", 3)]
            for k, v in stages]
    rows.append([cell("total", "name total"), cell(total, "num total", 4), cell(100.0 if total > 0 else None, "num total", 3)])
    return table("wall_time", "Wall-time breakdown by stage.", ["stage", "time [s]", "share [%]"], rows)
