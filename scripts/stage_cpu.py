"""CPU seconds by stage of what `ocdsl run` does, in one process, with the certificate apart.

    .venv/bin/python scripts/stage_cpu.py SEGMENTS [PROBLEM.yaml]

Runs ``ocdsl.run.execute`` on the problem file at SEGMENTS uniform segments and prints one
JSON line: imports, parse + symbolic, build, hand-over (solve stage minus Ipopt's own CPU),
Ipopt without / with function evaluations (Ipopt's timing statistics), post and the
certificate inside it, total and peak RSS. CPU rather than wall time, because on a shared
machine wall time mostly measures the other processes (reports/bench/peers_scaling.md).
"""
import time

_C0 = time.process_time()

import json
import resource
import sys
import tempfile
from pathlib import Path

import yaml

from ocdsl import run as R  # first: ocdsl sets PYOMO_CONFIG_DIR before Pyomo loads
from ocdsl.api import Timer, compile_file
from ocdsl.bench import ipopt_log
from ocdsl.solve import ipopt
from ocdsl.transcribe import pseudospectral as P

ipopt.check_available()
IMPORTS = time.process_time() - _C0


def main(segments: int, problem: str) -> dict:
    cpu = {"imports": IMPORTS}
    data = yaml.safe_load(Path(problem).read_text())
    data.setdefault("method", {})["segments"] = segments
    tmp = Path(tempfile.mkdtemp(prefix="ocdsl-stage-cpu-"))
    log = tmp / "ipopt.txt"
    solver = data.setdefault("solver", {})
    solver["options"] = {**(solver.get("options") or {}), **ipopt_log.options(log)}
    yml = tmp / "problem.yaml"
    yml.write_text(yaml.safe_dump(data, sort_keys=False))
    c = time.process_time()
    file = compile_file(yml)
    cpu["parse+symbolic"] = time.process_time() - c

    def timed(name, fn):
        def wrapper(*a, **k):
            c = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                cpu[name] = cpu.get(name, 0.0) + time.process_time() - c
        return wrapper

    P.build = timed("build", P.build)
    ipopt.solve = timed("solve", ipopt.solve)
    R._certify = timed("certificate", R._certify)
    R._result = timed("post", R._result)
    res = R.execute(file, Timer())
    st = ipopt_log.parse(log)
    cpu["ipopt_wo_fe"] = st.get("ipopt_wo_fe_cpu_s")
    cpu["ipopt_fe"] = st.get("ipopt_fe_cpu_s")
    cpu["handover"] = cpu["solve"] - st.get("ipopt_cpu_s", 0.0)
    cpu["total"] = time.process_time()
    ip = st.get("ipopt_cpu_s", 0.0)
    cpu["outside_share"] = (cpu["total"] - ip) / cpu["total"]
    cpu["outside_share_wo_certificate"] = (cpu["total"] - ip - cpu.get("certificate", 0.0)) / \
        (cpu["total"] - cpu.get("certificate", 0.0))
    out = {"segments": segments, "variables": res.nlp.get("variables"), "iterations": res.iterations,
           "status": res.status, "objective": res.objective}
    out.update({k: round(v, 3) for k, v in cpu.items() if v is not None})
    out["peak_MB"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)
    return out


if __name__ == "__main__":
    print(json.dumps(main(int(sys.argv[1]), sys.argv[2] if len(sys.argv) > 2 else "configs/brachistochrone.yaml")))
