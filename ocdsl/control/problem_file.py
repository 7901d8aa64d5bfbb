"""Run a problem file's ``controller:`` block: every law on the plant, one Result.

Each law becomes a phase named after it (``trajectory_<law>.csv``) and a table
``closed_loop_<law>``; a ``robustness:`` block adds the sweep's table. The run is
``stable`` when every law regulates the plant.
"""
from __future__ import annotations


from ..result import Result
from .run import robustness_sweep, run_controllers, summary_table


def run_controller_file(file, timer) -> Result:
    spec, model = file.controller, file.model
    params = {s: v for s, v in model.parameters.items() if v is not None}
    with timer.measure("solve"):
        results = run_controllers(model, [spec], parameters=params)
    combined = Result(name=file.spec.name, status="stable", method={"controller": spec.model_dump(mode="json")},
                      parameters={str(k): float(v) for k, v in params.items()})
    laws = []
    for r in results:
        law = r.extra.get("controller") or r.name.split(":")[-1]
        key = law.replace("-", "_")
        laws.append(key)
        if r.status != "stable":
            combined.status = r.status if combined.status == "stable" else combined.status
            combined.message += f"{law}: {r.status} {r.message}\n"
        for ph in r.phases:
            ph.name = key
            combined.phases.append(ph)
        for name, table in r.tables.items():
            combined.tables[f"{name}_{key}"] = table
        combined.extra[key] = {"status": r.status, "message": r.message, "cost": r.objective, **r.extra}
        if not combined.problem:
            combined.problem = dict(r.problem)
            combined.problem["name"] = file.spec.name
    if combined.problem:
        base = combined.problem.get("phases", {}).get("main", {})
        combined.problem["phases"] = {k: base for k in laws}
    combined.tables["controllers"] = summary_table(results)
    combined.extra["laws"] = laws
    if spec.robustness is not None:
        with timer.measure("solve"):
            rob = robustness_sweep(model, spec, parameters=params)
        combined.tables.update({"robustness": t for t in rob.tables.values()})
    combined.objective = None
    combined.wall_time_s = timer.breakdown()
    return combined
