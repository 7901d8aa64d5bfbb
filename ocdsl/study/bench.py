"""Study executor benchmark: speedup of a 32-point study at 1 and 2 workers against
serial, and where the overhead goes.

    python -m ocdsl.study.bench                  # synthetic problem, ~1 s per point
    python -m ocdsl.study.bench --work 0.5 --points 16
    python -m ocdsl.study.bench --problem FILE   # a real problem file with a study: block
    python -m ocdsl.study.bench --dask           # also a 2-worker Dask LocalCluster

The synthetic problem (``ocdsl.study.demo.point``) burns ``--work`` CPU seconds per
point (a stand-in for Ipopt) and ``--build`` CPU seconds once per worker process (a
stand-in for parse + symbolic + model build, cached per worker). Printed:

- wall time and speedup against serial for each executor;
- worker start-up: process start + imports, measured by starting a fresh pool;
- model build paid per worker (the first point on each worker) and how many builds;
- per-point overhead: (workers x wall - sum of the point functions' own wall) / points,
  i.e. shipping, writing run folders and tables, and idle slots, averaged per point.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

DEMO = """\
name: bench
parameters: {{a: 1.0, work_s: {work}}}
demo: {{build_s: {build}}}
study:
  sweep:
    grid:
      a: {{start: 0, stop: 2, num: {points}}}
"""


def _point_walls(out: Path) -> tuple[list[float], dict[int, float], int]:
    walls, first_build, builds = [], {}, 0
    for d in sorted((out / "points").iterdir()):
        if d.name.startswith("."):
            continue
        data = json.loads((d / "result.json").read_text())
        w = data.get("wall_time_s") or {}
        walls.append(float(w.get("total", 0.0)))
        extra = data.get("extra") or {}
        if "pid" in extra:
            b = float(w.get("build", 0.0))
            if b > 1e-3:
                first_build[extra["pid"]] = b
                builds += 1
    return walls, first_build, builds


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ocdsl.study.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=32)
    ap.add_argument("--work", type=float, default=1.0, help="CPU seconds per point (synthetic)")
    ap.add_argument("--build", type=float, default=0.5, help="CPU seconds of model build per worker (synthetic)")
    ap.add_argument("--problem", help="a real problem file with a study: block (default point function)")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    ap.add_argument("--dask", action="store_true", help="also run on a 2-worker Dask LocalCluster")
    ap.add_argument("--keep", action="store_true", help="keep the study folders")
    args = ap.parse_args(argv)

    from ocdsl.study.demo import point as demo_point
    from ocdsl.study.executor import Executor
    from ocdsl.study.run import run_study

    tmp = Path(tempfile.mkdtemp(prefix="ocdsl-study-bench-"))
    if args.problem:
        problem, point_fn = Path(args.problem).resolve(), None
        label = str(problem)
    else:
        problem = tmp / "bench.yaml"
        problem.write_text(DEMO.format(work=args.work, build=args.build, points=args.points))
        point_fn = demo_point
        label = (f"synthetic: {args.points} points, {args.work:g} CPU s each, "
                 f"{args.build:g} CPU s model build per worker")
    try:
        load = os.getloadavg()
    except OSError:  # pragma: no cover
        load = (float("nan"),) * 3
    print(f"study bench: {label}")
    print(f"host: {os.cpu_count()} cores, load average {load[0]:.2f} (other jobs slow every run down)")

    # worker start-up: process start and imports, once per worker
    ex = Executor(workers=2)
    t_start = ex.warm_up()
    ex.close()
    print(f"worker start-up (fork server + 2 worker processes + imports): {t_start:.3f} s, once per study")

    runs: list[tuple[str, dict]] = [("serial", {"serial": True})]
    for w in [int(x) for x in args.workers.split(",") if x.strip()]:
        runs.append((f"{w} process{'es' if w > 1 else ''}", {"workers": w}))
    cluster = None
    if args.dask:
        from distributed import LocalCluster
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None,
                               silence_logs=40)
        runs.append(("dask 2 workers", {"scheduler": cluster.scheduler_address}))

    rows = []
    t_serial = None
    try:
        for name, kw in runs:
            out = tmp / name.replace(" ", "_")
            t0 = time.perf_counter()
            res = run_study(problem, out, quiet=True, point_fn=point_fn, **kw)
            wall = time.perf_counter() - t0
            slots = 1 if kw.get("serial") else kw.get("workers") or 2
            walls, first_build, builds = _point_walls(out)
            n = len(walls)
            over = (slots * wall - sum(walls)) / max(n, 1)
            if t_serial is None:
                t_serial = wall
            rows.append((name, wall, t_serial / wall, res.counts["ok"], n, over,
                         builds, max(first_build.values(), default=0.0)))
    finally:
        if cluster is not None:
            cluster.close()
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            print(f"study folders kept in {tmp}")

    print()
    print(f"{'executor':<16}{'wall s':>9}{'speedup':>9}{'ok':>6}{'per-point overhead s':>22}"
          f"{'model builds':>14}{'build s':>9}")
    for name, wall, sp, ok, n, over, builds, b in rows:
        print(f"{name:<16}{wall:9.2f}{sp:8.2f}x{ok:>4}/{n:<2}{over:21.3f} {builds:>13}{b:9.3f}")
    two = [r for r in rows if r[0] == "2 processes"]
    if two:
        verdict = "meets" if two[0][2] >= 1.8 else "misses"
        print(f"\n2 workers: {two[0][2]:.2f}x against serial ({verdict} the 1.8x target); "
              "model build paid once per worker, not per point")
    return 0


if __name__ == "__main__":
    sys.exit(main())
