"""Measure model reuse across the points of a sweep (reports/bench/levers.md, "Model reuse").

    python -m ocdsl.study.reuse_bench [--problem FILE] [--param NAME --start A --stop B]
                                      [--points 16] [--segments K] [--reps 3]

One process plays one study worker: it loads the problem once and solves the sweep's
points one after the other, each variant on a new handle, variants alternating, ``--reps``
times; CPU time (``time.process_time``) by stage, medians over the repetitions, then
summed over the points. Variants: fresh build at every point and reused model, each from
the file's guess and with continuation (warm start from the previous point's run folder),
and the reused model started from the solution it already holds (``START = previous``).
"""
from __future__ import annotations

import argparse
import re
import statistics
import tempfile
import time
import types
from pathlib import Path

VARIANTS = ("fresh", "reuse", "fresh+cont", "reuse+cont", "reuse+prev")


def _cpu_timers():
    """The stage timer of ocdsl.api measures CPU instead of wall time."""
    import ocdsl.api as api

    api.time = types.SimpleNamespace(perf_counter=time.process_time)


HANDOVER = {"cpu": 0.0}


def _time_handover():
    """Accumulate the CPU of PyomoNLP construction (the NL writer and ASL: the hand-over)."""
    from pyomo.contrib.pynumero.interfaces.pyomo_nlp import PyomoNLP

    init = PyomoNLP.__init__
    if getattr(init, "_timed", False):
        return

    def timed(self, *a, **k):
        c = time.process_time()
        try:
            return init(self, *a, **k)
        finally:
            HANDOVER["cpu"] += time.process_time() - c

    timed._timed = True
    PyomoNLP.__init__ = timed


def run_variant(path: str, name: str, values: list[float], variant: str, tmp: Path) -> list[dict]:
    from ocdsl.api import load
    from ocdsl.solve import reuse as reuse_mod

    reuse_mod.START["from"] = "previous" if variant == "reuse+prev" else "guess"
    handle = load(path)
    rows, prev = [], None
    for k, v in enumerate(values):
        warm = prev if variant.endswith("+cont") else None
        HANDOVER["cpu"] = 0.0
        c0 = time.process_time()
        res = handle.solve(parameters={name: v}, reuse=variant.startswith("reuse"), warm_start=warm)
        cpu = time.process_time() - c0
        if variant.endswith("+cont"):
            prev = tmp / f"{variant}-{k}"
            res.write(prev)
        st = res.wall_time_s
        rows.append({"cpu": cpu, "symbolic": st.get("symbolic", 0.0), "build": st.get("build", 0.0),
                     "handover": HANDOVER["cpu"],
                     "ipopt": st.get("solve", 0.0) - HANDOVER["cpu"], "post": st.get("post", 0.0),
                     "iterations": res.iterations, "objective": res.objective, "status": res.status,
                     "how": res.extra.get("model_reuse", "fresh")})
    reuse_mod.START["from"] = "guess"
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--problem", default="configs/study_moon_landing_sweep.yaml")
    ap.add_argument("--param", default="E")
    ap.add_argument("--start", type=float, default=2.2)
    ap.add_argument("--stop", type=float, default=2.6)
    ap.add_argument("--points", type=int, default=16)
    ap.add_argument("--segments", type=int, default=None)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    a = ap.parse_args(argv)
    _cpu_timers()
    _time_handover()
    from ocdsl.solve import ipopt

    ipopt.check_available()
    tmp = Path(tempfile.mkdtemp(prefix="ocdsl-reuse-bench-"))
    path = a.problem
    if a.segments:
        text = Path(path).read_text()
        text = re.sub(r"segments:\s*\d+", f"segments: {a.segments}", text)
        path = str(tmp / Path(path).name)
        Path(path).write_text(text)
    n = a.points
    values = [a.start + (a.stop - a.start) * i / (n - 1) for i in range(n)]
    variants = a.variants.split(",")
    runs: dict[str, list[list[dict]]] = {v: [] for v in variants}
    run_variant(path, a.param, values[:2], "fresh", tmp)          # imports, caches
    for _ in range(a.reps):
        for v in variants:
            runs[v].append(run_variant(path, a.param, values, v, tmp))
    print(f"{a.problem} segments={a.segments or 'file'} {a.param} in [{a.start}, {a.stop}], "
          f"{n} points, {a.reps} reps, CPU s (medians over reps)")
    hdr = ("variant", "first pt", "per pt (rest)", "symbolic", "build", "hand-over", "Ipopt", "post",
           "iters (sum)", "max |dJ| vs fresh (same start)")
    print(" | ".join(hdr))
    for v in variants:
        base = "fresh+cont" if v.endswith("+cont") and "fresh+cont" in runs else variants[0]
        ref = [r["objective"] for r in runs[base][0]]
        reps = runs[v]

        def med(key, i):
            return statistics.median(r[i][key] for r in reps)

        first = med("cpu", 0)
        rest = [med("cpu", i) for i in range(1, n)]
        stage = {k: sum(med(k, i) for i in range(1, n)) / (n - 1)
                 for k in ("symbolic", "build", "handover", "ipopt", "post")}
        iters = sum(r["iterations"] for r in reps[0])
        dj = max(abs(r["objective"] - j) for r, j in zip(reps[0], ref))
        hows = {r["how"] for r in reps[0]}
        print(f"{v} | {first:.3f} | {statistics.mean(rest):.4f} | {stage['symbolic']:.4f} | "
              f"{stage['build']:.4f} | {stage['handover']:.4f} | {stage['ipopt']:.4f} | {stage['post']:.4f} | "
              f"{iters} | "
              f"{dj:.1e} | {sorted(hows)}")


if __name__ == "__main__":
    main()
