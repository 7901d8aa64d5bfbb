"""Core bench: time by stage and NLP size of the pseudospectral pipeline, in one process.

For each problem and segment count: parse, symbolic (compile to the SymPy Problem),
build (guess + Pyomo model), hand-over (PyNumero's NLP: NL writer + ASL), Ipopt (with and
without function evaluations, from Ipopt's own statistics), post (solution, costates).
Imports are measured once, first, and reported apart. Wall and CPU seconds are both
given, because on a shared machine wall time mostly measures the other processes.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

PROBLEMS = ["double_integrator", "brachistochrone"]
SEGMENTS = [1, 4, 16, 64]


def _clock():
    return time.perf_counter(), time.process_time()


def _since(t):
    w, c = _clock()
    return w - t[0], c - t[1]


def measure_imports() -> dict[str, float]:
    """Seconds to import what a solve needs, in order (each after the previous)."""
    out = {}
    for label, stmt in [("ocdsl.api (sympy, pydantic)", "import ocdsl.api"),
                        ("pyomo.core", "import pyomo.core"),
                        ("cyipopt + PyNumero (check_available)",
                         "from ocdsl.solve import ipopt; ipopt.check_available()"),
                        ("transcription modules", "import ocdsl.transcribe.pseudospectral, ocdsl.solve.costates")]:
        t = time.perf_counter()
        exec(stmt, {})
        out[label] = time.perf_counter() - t
    return out


def run_case(config: Path, segments: int, tmp: Path) -> dict:
    from ..api import Timer, compile_file
    from ..solve import ipopt
    from ..solve.costates import costates
    from ..transcribe.guess import make_guess
    from ..transcribe.mesh import Mesh
    from ..transcribe.pseudospectral import build
    from ..transcribe.solution import extract
    from . import ipopt_log

    row: dict = {"problem": config.stem, "segments": segments}
    t = _clock()
    timer = Timer()
    file = compile_file(config, None, timer)
    row["parse"], row["symbolic"] = timer.stages["parse"], timer.stages["symbolic"]
    problem, method = file.problem, file.method
    t = _clock()
    meshes = {ph.name: Mesh.uniform(method.transcription, segments, method.degree) for ph in problem.phases}
    guesses = {ph.name: make_guess(problem, ph) for ph in problem.phases}
    tr = build(problem, meshes, guesses)
    row["build"], row["build_cpu"] = _since(t)
    log = tmp / f"{config.stem}_{segments}.ipopt.txt"
    opts = {**file.spec.solver.options, **ipopt_log.options(log)}
    t = _clock()
    info = ipopt.solve(tr.model, opts, transcription=tr)
    row["solve"], row["solve_cpu"] = _since(t)
    t = _clock()
    phases = extract(tr)
    if info.status in ("optimal", "acceptable"):
        for traj, lam in zip(phases, costates(tr)):
            traj.costates = lam
    row["post"], row["post_cpu"] = _since(t)
    stats = ipopt_log.parse(log)
    row.update(status=info.status, objective=info.objective, iterations=info.iterations,
               variables=info.nlp.get("variables"), constraints=info.nlp.get("constraints"),
               nonzeros=info.nlp.get("nonzeros"),
               ipopt_wo_fe=stats.get("ipopt_wo_fe_s"), ipopt_fe=stats.get("ipopt_fe_s"))
    ip = (stats.get("ipopt_wo_fe_s") or 0.0) + (stats.get("ipopt_fe_s") or 0.0)
    row["handover"] = row["solve"] - ip
    row["outside_share"] = (row["parse"] + row["symbolic"] + row["build"] + row["handover"] + row["post"]) / \
        max(row["parse"] + row["symbolic"] + row["build"] + row["solve"] + row["post"], 1e-12)
    return row


def _f(v, nd=3):
    return "-" if v is None else f"{v:.{nd}f}"


def _g(v):
    return "-" if v is None else f"{v:.10g}"


def table(rows: list[dict], imports: dict[str, float]) -> str:
    lines = ["| problem | seg | vars | cons | nnz | iter | parse | symbolic | build | hand-over | "
             "Ipopt w/o f-eval | f-eval | post | outside Ipopt | build CPU | objective |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(
            f"| {r['problem']} | {r['segments']} | {r['variables']} | {r['constraints']} | {r['nonzeros']} | "
            f"{r['iterations']} | {_f(r['parse'])} | {_f(r['symbolic'])} | {_f(r['build'])} | "
            f"{_f(r['handover'])} | {_f(r['ipopt_wo_fe'])} | {_f(r['ipopt_fe'])} | {_f(r['post'])} | "
            f"{100 * r['outside_share']:.0f} % | {_f(r['build_cpu'])} | "
            f"{_g(r['objective'])} ({r['status']}) |")
    lines += ["", "Imports (seconds, once per process, in this order):", ""]
    lines += [f"- {k}: {v:.3f}" for k, v in imports.items()]
    return "\n".join(lines)


def machine() -> str:
    import platform

    try:
        load = os.getloadavg()
        load_s = f"load average {load[0]:.1f}"
    except OSError:
        load_s = ""
    return (f"{platform.node()}: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
            f"Python {platform.python_version()}, {load_s}")


def main_core(problems=None, segments=None, out: Path | None = Path("reports/bench/core.md")) -> str:
    imports = measure_imports()
    root = Path(__file__).resolve().parents[2] / "configs"
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in problems or PROBLEMS:
            for k in segments or SEGMENTS:
                cfg = Path(name) if name.endswith(".yaml") else root / f"{name}.yaml"
                rows.append(run_case(cfg, k, Path(tmp)))
                print(f"  {cfg.stem} {k} segments: build {rows[-1]['build']:.3f} s, "
                      f"solve {rows[-1]['solve']:.3f} s", file=sys.stderr)
    text = (f"# Core bench: time by stage (wall seconds) and NLP size\n\n"
            f"`python -m ocdsl.bench --sections core` on {machine()}, "
            f"{time.strftime('%Y-%m-%d %H:%M')}.\n"
            "hand-over = PyNumero's NLP (NL writer, ASL) and cyipopt set-up = solve call minus Ipopt's own "
            "total; outside Ipopt = share of the stages' wall time not in Ipopt.\n\n" + table(rows, imports) + "\n")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
    return text
