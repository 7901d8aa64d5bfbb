"""The adaptive-mesh table of docs/mesh.md over configs/mesh_*.yaml (issue 26).

Each file is run as a whole process (``ocdsl run``, a fresh run folder); from its result:
status, verification, mesh iterations, final NLP size, objective and its error against the
reference value below; then, each in a fresh process, one cold solve of the final mesh (the
wall time of the solve alone: build, Ipopt, post) and a uniform LGR mesh of degree 4 with about
as many variables (``nlp_size``'s count; its objective's error). Run niced, one file at a time:

    nice -n 10 python -m ocdsl.bench.mesh configs/mesh_*.yaml > table.md
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# the exact or closest-to-exact value of each file's objective (docs/mesh.md derives them)
REFERENCE = {
    "mesh_bang_off_bang": 3.0 - math.sqrt(5.0),
    "mesh_bryson_denham": 4.0,
    "mesh_double_integrator": 2.0,
    "mesh_goddard": 1.0125762700748699,
    "mesh_hang_glider": 1248.031026,
    "mesh_hanging_chain": 5.068480110993,
    "mesh_moon_landing": 1.4203125990,
    "mesh_rayleigh_mixed": 44.8044449110,
    "mesh_shuttle": 34.1412 * math.pi / 180.0,
    "mesh_shuttle_heating": 30.6255 * math.pi / 180.0,
    "mesh_tumour": 7571.6700383826,
}

_ONE_SOLVE = r"""
import json, sys, time
from ocdsl.api import Timer, compile_file
from ocdsl.run import solve_pseudospectral
from ocdsl.solve.mesh.coarsen import nlp_size
from ocdsl.transcribe.mesh import Mesh
import numpy as np
path, mode, arg = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
f = compile_file(path)
tol = f.method.mesh.tolerance    # the Ipopt settings of the adaptive run
f.spec.solver.options.setdefault("tol", min(1e-8, 1e-2 * tol))
f.spec.solver.options.setdefault("bound_relax_factor", min(1e-8, 1e-3 * tol))
if mode == "final":
    meshes = {k: Mesh(m["transcription"], np.asarray(m["breakpoints"]), tuple(m["degrees"])) for k, m in arg.items()}
else:
    n = 1
    while sum(nlp_size(Mesh.uniform("LGR", n, 4), len(p.states), len(p.controls)) for p in f.problem.phases) < arg:
        n += 1
    meshes = {p.name: Mesh.uniform("LGR", n, 4) for p in f.problem.phases}
f.spec.verify.bisection_check = False    # one solve of this mesh, as it is
t = time.perf_counter()
r = solve_pseudospectral(f, Timer(), meshes=meshes)
print(json.dumps({"status": r.status, "objective": r.objective, "variables": r.nlp.get("variables"),
                  "wall": time.perf_counter() - t}))
"""


def _python(*args: str) -> dict:
    out = subprocess.run([sys.executable, "-c", _ONE_SOLVE, *args], capture_output=True, text=True, check=False)
    try:
        return json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return {"status": "error", "objective": None, "variables": None, "wall": math.nan}


def row(path: Path) -> dict:
    ref = REFERENCE.get(path.stem)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(path), "--out", str(out), "-q"],
                       capture_output=True, text=True, check=False)
        process = time.perf_counter() - t
        r = json.loads((out / "result.json").read_text())
    J = r.get("objective")
    mesh = r.get("extra", {}).get("mesh", {})
    final = r["method"].get("meshes", {})
    one = _python(str(path), "final", json.dumps(final))
    uni = _python(str(path), "uniform", json.dumps(r["nlp"].get("variables", 0)))
    err = lambda j: abs(j - ref) / abs(ref) if (j is not None and ref) else math.nan  # noqa: E731
    return {"problem": path.stem, "status": r["status"], "verification": r.get("verification", {}).get("status"),
            "iterations": mesh.get("iterations"), "chosen": mesh.get("chosen_iteration"),
            "variables": r["nlp"].get("variables"), "objective": J, "error": err(J),
            "uniform_variables": uni["variables"], "uniform_error": err(uni["objective"]),
            "uniform_status": uni["status"], "wall": r["wall_time_s"].get("total", math.nan),
            "process": process, "one_solve": one["wall"]}


def main(argv: list[str] | None = None) -> None:
    paths = [Path(p) for p in (argv if argv is not None else sys.argv[1:])]
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print()
    print("| problem | status | verification | mesh it. (chosen) | final vars | J | error | "
          "uniform (vars): error | wall s | one solve s | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for p in paths:
        q = row(p)
        ue = f"({q['uniform_variables']}) {q['uniform_error']:.1e}" if q["uniform_status"] in ("optimal", "acceptable") \
            else f"({q['uniform_variables']}) {q['uniform_status']}"
        print(f"| {q['problem']} | {q['status']} | {q['verification']} | {q['iterations']} ({q['chosen']}) | "
              f"{q['variables']} | {q['objective']:.10g} | {q['error']:.1e} | {ue} | {q['wall']:.1f} | "
              f"{q['one_solve']:.1f} | {q['wall'] / q['one_solve']:.1f} |", flush=True)
    print()
    print(f"load average after: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
