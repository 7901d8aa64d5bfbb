"""ocdsl against a CasADi script generated from the same symbolic Problem (``ocdsl bench``).

Each problem file runs as whole processes, alternating ``ocdsl run`` and the generated
CasADi script, several times; the table gives medians. Both get the same mesh, guess and
Ipopt options, plus ``print_timing_statistics`` into an output file, from which Ipopt's
own times, iterations and NLP size are read. Peak memory is the child's maximum RSS.
"""
from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from . import ipopt_log


def _ocdsl_cmd() -> list[str]:
    exe = Path(sys.executable).with_name("ocdsl")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "ocdsl.cli"]


def _run(cmd: list[str], cwd: Path, env: dict) -> dict:
    """Wall seconds, CPU seconds and peak RSS (MB) of one child process; its stdout."""
    out_path = cwd / f"stdout_{time.monotonic_ns()}.txt"
    with open(out_path, "w") as out:
        t = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=cwd, stdout=out, stderr=subprocess.STDOUT, env=env)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t
    p.returncode = os.waitstatus_to_exitcode(status)
    return {"wall": wall, "cpu": ru.ru_utime + ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024.0,
            "rc": p.returncode, "stdout": out_path.read_text()}


def prepare(problem_file: Path, work: Path, segments: int | None = None) -> tuple[Path, Path, Path, Path]:
    """The ocdsl problem file and the CasADi script of one case, with Ipopt statistics on."""
    from ..api import compile_file
    from .casadi_gen import write_script

    data = yaml.safe_load(problem_file.read_text())
    if segments is not None:
        data.setdefault("method", {})["segments"] = segments
    # the script solves the file's initial mesh once: so does ocdsl here (adaptive refinement
    # is compared with one solve in the mesh table, ocdsl.bench.mesh)
    phases = (data.get("phases") or {}).values()          # phases: {name: phase}
    for method in [data.get("method") or {}] + [(p or {}).get("method") or {} for p in phases]:
        method.pop("mesh", None)
    work.mkdir(parents=True, exist_ok=True)
    log_o, log_c = work / "ipopt_ocdsl.txt", work / "ipopt_casadi.txt"
    solver = data.setdefault("solver", {})
    solver["options"] = {**(solver.get("options") or {}), **ipopt_log.options(log_o)}
    yml = work / "problem.yaml"
    yml.write_text(yaml.safe_dump(data, sort_keys=False))
    file = compile_file(yml)
    script = write_script(work / "casadi_script.py", file, extra_options=ipopt_log.options(log_c))
    return yml, script, log_o, log_c


def bench_case(problem_file: Path, work: Path, runs: int = 3, segments: int | None = None,
               serve_dir: Path | None = None) -> dict:
    """``runs`` rounds of three whole processes, alternating their order: ``ocdsl run`` on a
    cold disk cache (emptied before each run), ``ocdsl run`` on a warm one (filled by one
    unmeasured run first; ocdsl/cache.py) and the CasADi script; with ``serve_dir`` (the
    folder of a running ``ocdsl serve``) a fourth, ``ocdsl run`` served on the warm cache,
    whose CPU is its own process's plus the worker's (``OCDSL_SERVE_LOG``)."""
    yml, script, log_o, log_c = prepare(problem_file, work, segments)
    cold, warm = work / "cache_cold", work / "cache_warm"
    # PYTHONDONTWRITEBYTECODE would have every ocdsl run compile ocdsl's own modules from
    # source (~0.1 s of CPU on a source checkout) while CasADi loads its installed bytecode:
    # both children run as an installed package would, with bytecode (written by the fill run)
    base = {**_child_env(), "OCDSL_NO_SERVE": "1"}     # cold and warm rows: processes of their own
    runs_of: dict[str, list] = {"cold": [], "warm": [], "casadi": [], "served": []}
    served_log = work / "served.jsonl"

    def ocdsl_run(cache_dir: Path, served: bool = False) -> dict:
        out = work / "run"
        shutil.rmtree(out, ignore_errors=True)
        env = {**base, "OCDSL_CACHE": str(cache_dir)}
        if served:     # the server's own environment, so that its fingerprint matches
            env = {**_serve_env(serve_dir), "OCDSL_CACHE": str(cache_dir), "OCDSL_SERVE_LOG": str(served_log)}
            n = len(served_log.read_text().splitlines()) if served_log.exists() else 0
        # ocdsl refuses to empty an existing absolute output_file: the last run's logs go first
        for log in [log_o, *log_o.parent.glob(f"{log_o.stem}.*{log_o.suffix}")]:
            log.unlink(missing_ok=True)
        r = _run(_ocdsl_cmd() + ["run", str(yml), "--out", str(out), "-q"], work, env)
        if served:
            lines = served_log.read_text().splitlines() if served_log.exists() else []
            if len(lines) != n + 1:
                raise RuntimeError(f"ocdsl serve did not serve {yml} (is the server running?): {r['stdout'][-2000:]}")
            worker = json.loads(lines[-1])
            r["cpu"] += worker["worker_cpu_s"]
            r["rss_mb"] = max(r["rss_mb"], worker["worker_rss_mb"])
        r["result"] = json.loads((out / "result.json").read_text()) if (out / "result.json").exists() else {}
        r["ipopt"] = ipopt_log.parse(log_o)
        return r

    ocdsl_run(warm)                                   # fills the warm cache, not measured
    order = ("cold", "casadi", "warm") + (("served",) if serve_dir else ())
    for i in range(runs):
        for who in (order if i % 2 == 0 else order[::-1]):
            if who == "served":
                runs_of["served"].append(ocdsl_run(warm, served=True))
            elif who == "cold":
                shutil.rmtree(cold, ignore_errors=True)
                runs_of["cold"].append(ocdsl_run(cold))
            elif who == "warm":
                runs_of["warm"].append(ocdsl_run(warm))
            else:
                r = _run([sys.executable, str(script)], work, base)
                line = next((ln for ln in r["stdout"].splitlines() if ln.startswith("CASADI_RESULT ")), None)
                r["result"] = json.loads(line.split(" ", 1)[1]) if line else {}
                r["ipopt"] = ipopt_log.parse(log_c)
                runs_of["casadi"].append(r)
    return {"name": problem_file.stem if segments is None else f"{problem_file.stem} K={segments}",
            "ocdsl": summarize(runs_of["cold"], "ocdsl"), "ocdsl_warm": summarize(runs_of["warm"], "ocdsl"),
            "ocdsl_served": summarize(runs_of["served"], "ocdsl") if serve_dir else None,
            "casadi": summarize(runs_of["casadi"], "casadi")}


def _med(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def summarize(runs: list[dict], who: str) -> dict:
    s = {"wall": _med([r["wall"] for r in runs]), "cpu": _med([r["cpu"] for r in runs]),
         "rss_mb": _med([r["rss_mb"] for r in runs]), "rc": [r["rc"] for r in runs]}
    for key in ("ipopt_wo_fe_s", "ipopt_fe_s", "ipopt_wo_fe_cpu_s", "iterations", "variables", "constraints"):
        s[key] = _med([r["ipopt"].get(key) for r in runs])
    ip = [(r["ipopt"].get("ipopt_wo_fe_s") or 0) + (r["ipopt"].get("ipopt_fe_s") or 0) for r in runs]
    if who == "ocdsl":
        st = [r["result"].get("wall_time_s", {}) for r in runs]
        for k in ("parse", "symbolic", "build", "solve", "post", "verify"):
            s[k] = _med([w.get(k) for w in st])
        s["handover"] = _med([w.get("solve", 0) - i for w, i in zip(st, ip)])
        s["lazy_imports"] = _med([w.get("total", 0) - sum(v for k, v in w.items() if k != "total") for w in st])
        s["startup"] = _med([r["wall"] - r["result"].get("wall_time_s", {}).get("total", 0) for r in runs])
        s["status"] = runs[-1]["result"].get("status")
        s["objective"] = runs[-1]["result"].get("objective")
    else:
        res = [r["result"] for r in runs]
        s["parse"] = s["symbolic"] = s["post"] = s["verify"] = s["solve"] = s["lazy_imports"] = 0.0
        s["build"] = _med([x.get("build") for x in res])
        s["handover"] = _med([x.get("handover", 0) + x.get("solve", 0) - i for x, i in zip(res, ip)])
        s["startup"] = _med([r["wall"] - sum(x.get(k, 0) for k in ("import", "build", "handover", "solve"))
                             + x.get("import", 0) for r, x in zip(runs, res)])
        s["status"] = res[-1].get("status")
        s["objective"] = res[-1].get("objective")
    s["outside"] = s["wall"] - ((s["ipopt_wo_fe_s"] or 0) + (s["ipopt_fe_s"] or 0)) if s["wall"] else None
    return s


def _f(v, nd=3):
    return "-" if v is None else (f"{v:.{nd}f}" if isinstance(v, float) else str(v))


def table(cases: list[dict]) -> str:
    head = ("| problem | tool | vars | cons | iter | Ipopt w/o f-eval | Ipopt CPU w/o f-eval | f-eval | start-up+imports | parse | "
            "symbolic | build | hand-over | post | verify / solve stage | peak MB | wall (median) | CPU | outside Ipopt | "
            "Ipopt CPU/iter | ratio wall | ratio CPU | ratio Ipopt CPU/iter | objective |")
    lines = [head, "|" + "---|" * head.count("|")[:-1] if False else "|" + "---|" * (head.count("|") - 1)]
    for c in cases:
        k = c["casadi"]
        tools = [("ocdsl cold", c["ocdsl"])] + ([("ocdsl warm", c["ocdsl_warm"])] if c.get("ocdsl_warm") else [])
        tools += [("ocdsl served", c["ocdsl_served"])] if c.get("ocdsl_served") else []
        for who, s in tools + [("CasADi", k)]:
            o = s
            ratio_w = f"{o['wall'] / k['wall']:.2f}" if who != "CasADi" and k["wall"] else ""
            ratio_c = f"{o['cpu'] / k['cpu']:.2f}" if who != "CasADi" and k["cpu"] else ""
            obj = "-" if s["objective"] is None else f"{s['objective']:.10g}"
            per_it = {w: (x["ipopt_wo_fe_cpu_s"] / x["iterations"] if x.get("ipopt_wo_fe_cpu_s") and x.get("iterations")
                          else None) for w, x in (("o", o), ("k", k))}
            ratio_it = (f"{per_it['o'] / per_it['k']:.2f}" if who != "CasADi" and per_it["o"] and per_it["k"] else "")
            me = per_it["o" if who != "CasADi" else "k"]
            share = f"{100 * s['outside'] / s['wall']:.0f} %" if s.get("outside") is not None and s["wall"] else "-"
            lines.append(
                f"| {c['name']} | {who} | {_f(s['variables'], 0)} | {_f(s['constraints'], 0)} | "
                f"{_f(s['iterations'], 0)} | {_f(s['ipopt_wo_fe_s'])} | {_f(s['ipopt_wo_fe_cpu_s'])} | {_f(s['ipopt_fe_s'])} | "
                f"{_f((s['startup'] or 0) + (s['lazy_imports'] or 0))} | {_f(s['parse'])} | {_f(s['symbolic'])} | "
                f"{_f(s['build'])} | {_f(s['handover'])} | {_f(s['post'])} | {_f(s.get('verify'))} / {_f(s.get('solve'))} | {_f(s['rss_mb'], 0)} | "
                f"{_f(s['wall'])} | {_f(s['cpu'])} | {share} | {_f(me, 4)} | {ratio_w} | {ratio_c} | {ratio_it} | "
                f"{obj} ({s['status']}) |")
    return "\n".join(lines)


def _scale_child(problem_file: str, K: int, repeat: int) -> dict:
    """In a fresh process: build + hand-over at K segments, ``repeat`` times.

    CPU seconds (``time.process_time``), medians over the repeats; as ``ocdsl run`` does
    (``ocdsl.run.solve_pseudospectral``, ``ocdsl.solve.ipopt.solve``): guess + ``build`` is the
    build; the hand-over, inside ``gc_frozen``, is the route the solve takes (``ocdsl.solve.ipopt.direct_nlp``): ``DirectNLP.of``
    (its first call in a process includes the SymPy compile), or ``PyomoNLP`` (NL writer +
    ASL) where it declines."""
    import gc

    from ..api import compile_file
    from ..solve import ipopt
    from ..transcribe.guess import make_guess
    from ..transcribe.mesh import Mesh
    from ..transcribe.direct_nlp import DirectNLP
    from ..transcribe.pseudospectral import build, gc_frozen

    ipopt.check_available()

    file = compile_file(Path(problem_file))
    problem, method = file.problem, file.method
    b, h, n = [], [], None
    for _ in range(max(1, repeat)):
        meshes = {ph.name: Mesh.uniform(method.transcription, K, method.degree) for ph in problem.phases}
        c = time.process_time()
        guesses = {ph.name: make_guess(problem, ph) for ph in problem.phases}
        tr = build(problem, meshes, guesses)
        b.append(time.process_time() - c)
        c = time.process_time()
        with gc_frozen():
            nlp, _ = ipopt.direct_nlp(tr)
            if nlp is None:
                nlp = ipopt.pynumero_nlp(tr.model)
        h.append(time.process_time() - c)
        n = int(nlp.n) if isinstance(nlp, DirectNLP) else int(nlp.n_primals())
        del nlp, tr
        gc.collect()
    return {"K": K, "vars": n, "build": statistics.median(b), "handover": statistics.median(h),
            "build_runs": b, "handover_runs": h}


def scaling(problem_file: Path, segments: list[int], work: Path, repeat: int = 3) -> tuple[str, dict]:
    """Build + hand-over CPU time and peak memory (no solve) of ocdsl and of the CasADi script.

    Each segment count runs in its own process per tool (so the peak RSS is that of one
    model at that size), ``repeat`` builds each, CPU medians; exponents fitted over >= 50."""
    import numpy as np

    from ..api import compile_file
    from .casadi_gen import write_script

    file = compile_file(problem_file)
    rows = []
    env = dict(os.environ)
    for K in segments:
        child = ["-m", "ocdsl.bench.peers", "--scale-child", str(Path(problem_file).resolve()), str(K), str(repeat)]
        r = _run([sys.executable, *child], work, env)
        line = next((ln for ln in r["stdout"].splitlines() if ln.startswith("SCALE_RESULT ")), "x {}")
        o = json.loads(line.split(" ", 1)[1])
        if not o:
            print(r["stdout"][-2000:], file=sys.stderr)
        script = write_script(work / f"scale_{K}.py", file, segments=K)
        rc = _run([sys.executable, str(script), "--no-solve", "--repeat", str(repeat)], work, env)
        line = next((ln for ln in rc["stdout"].splitlines() if ln.startswith("CASADI_RESULT ")), "x {}")
        cr = json.loads(line.split(" ", 1)[1])
        rows.append({"K": K, "vars": o.get("vars"), "build": o.get("build"), "handover": o.get("handover"),
                     "rss": r["rss_mb"], "c_build": cr.get("build_cpu"), "c_handover": cr.get("handover_cpu"),
                     "c_rss": rc["rss_mb"]})
        print(f"  scaling K={K}: ocdsl build {_f(o.get('build'))} + hand-over {_f(o.get('handover'))} CPU s, "
              f"{r['rss_mb']:.0f} MB; CasADi {_f(cr.get('build_cpu'))} + {_f(cr.get('handover_cpu'))}, "
              f"{rc['rss_mb']:.0f} MB", file=sys.stderr)
    Ks = np.array([r["K"] for r in rows], float)
    fit = {}
    for key in ("build", "handover", "c_build", "c_handover"):
        y = np.array([r[key] or np.nan for r in rows], float)
        ok = np.isfinite(y) & (Ks >= 50) & (y > 0)
        fit[key] = float(np.polyfit(np.log(Ks[ok]), np.log(y[ok]), 1)[0]) if ok.sum() >= 2 else None
    lines = [(f"CPU seconds (`time.process_time`), median of {repeat} builds in one process per segment count "
              "and tool; peak MB = that process's maximum RSS (imports + one model, its NLP and "
              "the solver interface, no solve)."), "",
             ("| segments | NLP variables | ocdsl build | ocdsl hand-over | ocdsl peak MB | CasADi build | "
              "CasADi nlpsol set-up | CasADi peak MB |"),
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['K']} | {r['vars']} | {_f(r['build'])} | {_f(r['handover'])} | {r['rss']:.0f} | "
                     f"{_f(r['c_build'])} | {_f(r['c_handover'])} | {r['c_rss']:.0f} |")
    lines.append("")
    lines.append("Fitted exponent of CPU time ~ segments^p over segments >= 50: " + ", ".join(
        f"{k} p = {_f(v, 2)}" for k, v in fit.items()))
    return "\n".join(lines), fit


def _child_env() -> dict:
    """This process's environment without the switches that would change what is measured."""
    return {k: v for k, v in os.environ.items()
            if k not in ("OCDSL_NO_CACHE", "PYTHONDONTWRITEBYTECODE", "OCDSL_NO_SERVE")}


def _serve_env(serve_dir: Path) -> dict:
    return {**_child_env(), "OCDSL_SERVE_DIR": str(serve_dir)}


def _start_server(serve_dir: Path) -> tuple[Path | None, dict | None]:
    """A server for the served rows (its start measured, as a whole process), or None where
    the console script is not installed."""
    cmd = _ocdsl_cmd()
    if len(cmd) != 1:
        return None, None
    r = _run(cmd + ["serve", "start", "--idle", "3600"], serve_dir, _serve_env(serve_dir))
    return (serve_dir if r["rc"] == 0 else None), r


def main_peers(files: list[Path], runs: int = 3, out: Path | None = Path("reports/bench/peers.md"),
               scaling_file: Path | None = None, scaling_segments: list[int] | None = None,
               series_solve: list[int] | None = None, scaling_repeat: int = 3) -> str:
    from .cli import HEADING
    from .core import machine

    cases = []
    with tempfile.TemporaryDirectory(prefix="ocdsl-bench-") as tmp, \
            tempfile.TemporaryDirectory(prefix="osb", dir="/tmp") as serve_dir:   # AF_UNIX: short
        tmp = Path(tmp)
        serve_dir, serve_start = _start_server(Path(serve_dir))
        try:
            for i, f in enumerate(files):
                print(f"  {f}", file=sys.stderr)
                cases.append(bench_case(Path(f), tmp / f"case{i}", runs, serve_dir=serve_dir))
            for K in series_solve or []:
                print(f"  {scaling_file} K={K}", file=sys.stderr)
                cases.append(bench_case(Path(scaling_file), tmp / f"series{K}", runs, segments=K,
                                        serve_dir=serve_dir))
        finally:
            if serve_dir is not None:
                _run(_ocdsl_cmd() + ["serve", "stop"], tmp, _serve_env(serve_dir))
        scale_text = ""
        if scaling_file is not None and scaling_segments:
            scale_text, _ = scaling(Path(scaling_file), scaling_segments, tmp, repeat=scaling_repeat)
    text = (f"{HEADING}\n\n{machine()}, {time.strftime('%Y-%m-%d %H:%M')}, "
            f"{runs} runs each, alternating, medians; seconds.\n\n"
            "Whole processes, with Python's bytecode cache (PYTHONDONTWRITEBYTECODE is not passed on). ocdsl: start-up+imports = process wall minus `ocdsl run`'s own total, plus the "
            "lazy imports inside it (Pyomo, cyipopt); hand-over = solve stage minus Ipopt's own total "
            "(the NLP set-up of the route the solve took, `result.json` nlp.evaluation: the direct NumPy "
            "route's SymPy compile and index assembly, or PyNumero's NL writer + ASL; cyipopt set-up); "
            "post includes costates, certificate and expect "
            "checks; verify = the independent verification (ocdsl/verify). ocdsl cold: its disk cache of generated "
            "NLP code (ocdsl/cache.py) emptied before each run; warm: filled by one unmeasured run first. CasADi: hand-over = `nlpsol` creation plus solver call minus Ipopt's own total. "
            "Ipopt CPU = user + sys seconds from Ipopt's timing statistics (the wall columns "
            "mostly measure the machine's other load); Ipopt CPU/iter = that without function evaluations "
            "over iterations; outside Ipopt = share of the process wall not in Ipopt (with or without "
            "function evaluations). Ratios are ocdsl/CasADi. Ipopt rewrites its output file per solve: "
            "ocdsl's first solve keeps it (its later solves, other starts and the bisection check, "
            "write numbered copies; before 2026-12-06 the last solve's overwrote it, so a bisected mesh's "
            "sizes and iterations were read as the run's), CasADi's last start's does; with "
            "`method.starts` > 1 both run every start and the other starts' Ipopt time falls into hand-over. "
            + ("ocdsl served: `ocdsl run` with an `ocdsl serve` running (ocdsl/serve; warm cache): "
               "CPU = the console script's process plus the forked worker that ran the command; "
               "peak MB = the worker's, which Linux counts with the server's pages; start-up+imports = "
               "the client's process and the fork. The server's own start, paid once and not in these "
               f"rows: {serve_start['wall']:.2f} s wall, {serve_start['cpu']:.2f} s CPU (`ocdsl serve start`)."
               if serve_dir is not None else "No `ocdsl serve` rows: the console script is not installed.")
            + "\n\n" + table(cases) + "\n")
    if scale_text:
        text += (f"\n## Scaling: build time and memory against segments ({Path(scaling_file).stem}, no solve)\n\n"
                 + scale_text + "\n")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
    return text


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--scale-child":
        print("SCALE_RESULT " + json.dumps(_scale_child(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))))
