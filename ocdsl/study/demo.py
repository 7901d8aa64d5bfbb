"""A synthetic point function with the signature of ``ocdsl.api.run_file``, for testing
and benchmarking the study machinery without a solver.

It reads ``parameters:`` of a YAML file, and a ``demo:`` block:
``{build_s: seconds of CPU to "build the model" (once per worker, cached)}``. Parameters
with a meaning: ``work_s`` (CPU seconds per solve), ``fail`` (> 0.5: status infeasible),
``raise`` (> 0.5: raise an exception), ``crash`` (> 0.5: kill the worker process),
``interrupt`` (> 0.5 while ``OCDSL_DEMO_INTERRUPT`` is set: status interrupted, as the point
in hand when Ctrl-C stops a study). The
objective is a smooth deterministic function of the other parameters and the seed. If the
environment variable ``OCDSL_DEMO_LEDGER`` names a file, each finished solve appends one
JSON line to it (parameters, seed, pid), so tests can count how often a point was solved.
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np
import yaml

from ocdsl.result import PhaseTrajectory, Result

from .executor import cache_stats, worker_cache

CONTROL = ("work_s", "fail", "raise", "crash", "interrupt")


def _burn(seconds: float) -> None:
    """Busy CPU for ``seconds`` of this process's CPU time (a stand-in for Ipopt)."""
    t0 = time.process_time()
    x = 0.0
    while time.process_time() - t0 < seconds:
        for i in range(2000):
            x += math.sin(i * 1e-3)


def _build(path: str) -> dict:
    data = yaml.safe_load(Path(path).read_text()) or {}
    params = {str(k): float(v) for k, v in (data.get("parameters") or {}).items()}
    _burn(float((data.get("demo") or {}).get("build_s", 0.0)))
    return {"name": data.get("name", Path(path).stem), "parameters": params}


def point(path, out_dir, parameters=None, seed=None, warm_start=None, quiet=True) -> Result:
    st = os.stat(path)
    t0 = time.perf_counter()
    model = worker_cache(("demo", str(path), st.st_mtime_ns, st.st_size), lambda: _build(str(path)))
    t_build = time.perf_counter() - t0
    p = {**model["parameters"], **{k: float(v) for k, v in (parameters or {}).items()}}
    _burn(p.get("work_s", 0.0))
    if p.get("crash", 0.0) > 0.5:
        os._exit(17)
    if p.get("raise", 0.0) > 0.5:
        raise RuntimeError(f"demo point raised for parameters {parameters}")
    x = [v for k, v in sorted(p.items()) if k not in CONTROL]
    objective = float(sum((v - 1.0) ** 2 for v in x) + 0.1 * math.sin(sum(x))
                      + (1e-3 * (seed % 997) if seed is not None else 0.0))
    warm_obj = None
    if warm_start:
        warm_obj = json.loads((Path(warm_start) / "result.json").read_text()).get("objective")
    status = "infeasible" if p.get("fail", 0.0) > 0.5 else "optimal"
    if p.get("interrupt", 0.0) > 0.5 and os.environ.get("OCDSL_DEMO_INTERRUPT"):
        status = "interrupted"
    tgrid = np.linspace(0.0, 1.0, 11)
    res = Result(
        name=model["name"], status=status,
        message="" if status == "optimal" else f"demo: {status} by request",
        objective=objective, tf=1.0 + 0.1 * len(x), iterations=4 if warm_start else 12,
        wall_time_s={"total": time.perf_counter() - t0, "build": t_build},
        method={"name": "demo"}, parameters=p,
        phases=[PhaseTrajectory("main", tgrid, states={"x": objective * tgrid})],
        problem={"name": model["name"], "phases": {"main": {"states": ["x"], "controls": []}},
                 "objective": {"sense": "minimize", "text": "demo", "latex": ""}},
        # a synthetic point has no dynamics to fly: nothing to verify (its ok is its status)
        verification={"status": "not_applicable", "summary": "synthetic demo point: nothing to verify"},
        extra={"warm_start_objective": warm_obj, "seed": seed, "pid": os.getpid(),
               "cache_builds": cache_stats()["builds"]})
    res.write(out_dir)
    ledger = os.environ.get("OCDSL_DEMO_LEDGER")
    if ledger:
        line = json.dumps({"parameters": parameters or {}, "seed": seed, "pid": os.getpid()})
        fd = os.open(ledger, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, (line + "\n").encode())
        finally:
            os.close(fd)
    return res
