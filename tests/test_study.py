"""Studies: spec and points, one table on every executor, resume after kill -9, a lost
Dask worker, bad input. Uses the synthetic point function ``ocdsl.study.demo.point``
(signature of ``ocdsl.api.run_file``) so that the machinery is tested without a solver."""
from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from ocdsl.study.demo import point as demo_point
from ocdsl.study.executor import Executor
from ocdsl.study.run import run_study
from ocdsl.study.spec import StudyError, generate_points, load_study, parse_study

ROOT = Path(__file__).resolve().parents[1]


def write(tmp: Path, body: str, name: str = "demo.yaml") -> Path:
    p = tmp / name
    p.write_text(textwrap.dedent(body))
    return p


EQUIV = """\
    name: demo
    parameters: {a: 1.0, b: 2.0, work_s: 0.01, fail: 0, raise: 0}
    demo: {build_s: 0.05}
    study:
      seed: 11
      sweep:
        list:
          - {a: 0.0, b: 1.0}
          - {a: 0.5, b: 1.5}
          - {a: 1.0, b: 2.0, fail: 1}
          - {a: 1.5, b: 2.5}
          - {a: 2.0, b: 3.0, raise: 1}
          - {a: 2.5, b: 3.5}
      monte-carlo:
        n: 2
        parameters:
          b: {dist: normal, std: 0.1}
      continuation: true
"""


def table(out: Path) -> dict[str, tuple]:
    data = json.loads((out / "study.json").read_text())
    return {r["id"]: (r["status"], r["objective"], r["warm_start"]) for r in data["points"]}


def assert_same(t1: dict, t2: dict) -> None:
    assert t1.keys() == t2.keys()
    for k in t1:
        s1, o1, w1 = t1[k]
        s2, o2, w2 = t2[k]
        assert s1 == s2, k
        assert w1 == w2, k
        if o1 is None or o2 is None:
            assert o1 is o2 is None, k
        else:
            assert abs(o1 - o2) <= 1e-10, k


def folders(out: Path) -> set[str]:
    return {p.name for p in (out / "points").iterdir() if not p.name.startswith(".")}


# ---------------------------------------------------------------------------------------
# spec and points
# ---------------------------------------------------------------------------------------
def test_points_grid_zip_list_and_determinism():
    spec = parse_study({"seed": 1, "sweep": {"grid": {"a": [1, 2, 3], "b": {"start": 0, "stop": 1, "num": 2}}},
                        "continuation": True})
    pts = generate_points(spec, {"a": 1.0, "b": 0.0})
    assert [p.parameters for p in pts][:3] == [{"a": 1.0, "b": 0.0}, {"a": 1.0, "b": 1.0}, {"a": 2.0, "b": 0.0}]
    assert len(pts) == 6 and pts[0].parent is None
    # every parent differs from its child by one step along one axis
    by = {p.id: p for p in pts}
    for p in pts[1:]:
        q = by[p.parent]
        assert sum(p.parameters[k] != q.parameters[k] for k in "ab") == 1
    z = generate_points(parse_study({"sweep": {"zip": {"a": [1, 2], "b": [3, 4]}}}), {})
    assert [p.parameters for p in z] == [{"a": 1.0, "b": 3.0}, {"a": 2.0, "b": 4.0}]
    with pytest.raises(ValueError, match="equal length"):
        generate_points(parse_study({"sweep": {"zip": {"a": [1, 2], "b": [3]}}}), {})
    mc = {"seed": 5, "starts": 3, "monte-carlo": {"n": 4, "parameters": {
        "a": {"dist": "normal", "rel_std": 0.1}, "b": {"dist": "uniform", "low": 0, "high": 1}}}}
    p1 = generate_points(parse_study(mc), {"a": 2.0, "b": None})
    p2 = generate_points(parse_study(mc), {"a": 2.0, "b": None})
    assert [p.to_json() for p in p1] == [p.to_json() for p in p2] and len(p1) == 12
    assert len({p.parameters["a"] for p in p1}) == 4 and len({p.seed for p in p1}) == 3
    assert all(0 <= p.parameters["b"] <= 1 for p in p1)
    p3 = generate_points(parse_study({**mc, "seed": 6}), {"a": 2.0, "b": None})
    assert [p.parameters for p in p3] != [p.parameters for p in p1]


@pytest.mark.parametrize("block, match", [
    ("sweep: {grid: {c: [1, 2]}}", "unknown parameter 'c'"),
    ("sweep: {list: [{a: 1}, {zz: 2}]}", "unknown parameter 'zz'"),
    ("monte-carlo: {n: 3, parameters: {q: {dist: normal, std: 1}}}", "unknown parameter 'q'"),
    ("sweep: {grid: {a: []}}", "empty sweep"),
    ("sweep: {list: []}", "empty sweep"),
    ("sweep: {grid: {}}", "empty sweep"),
    ("sweep: {grid: {a: {start: 0, stop: 1, num: 0}}}", "sweep would be empty"),
    ("monte-carlo: {n: -5, parameters: {a: {dist: normal, std: 1}}}", "must not be negative"),
    ("starts: -2", "must not be negative"),
    ("sweep: {grid: {a: [1]}, list: [{a: 1}]}", "exactly one of"),
    ("sweep: {grdi: {a: [1]}}", "unknown key 'grdi'"),
    ("monte-carlo: {n: 3, parameters: {a: {dist: normal}}}", "std"),
    ("continuation: true\nstarts: 2", "needs a `sweep`"),
    ("sweep: {list: [{a: 1}]}\nreuse_model: maybe", "reuse_model"),
])
def test_bad_study_blocks(tmp_path, block, match):
    body = "name: demo\nparameters: {a: 1.0, b: 2.0}\nstudy:\n" + textwrap.indent(block, "  ") + "\n"
    f = tmp_path / "bad.yaml"
    f.write_text(body)
    out = tmp_path / "out"
    with pytest.raises(StudyError, match=match) as err:
        run_study(f, out, serial=True, quiet=True, point_fn=demo_point)
    assert str(f) in str(err.value)          # names the file (and the line where known)
    assert not out.exists()                  # nothing written, nothing looks complete


def test_error_names_the_line(tmp_path):
    f = write(tmp_path, """\
        name: demo
        parameters: {a: 1.0}
        study:
          sweep:
            grid:
              a: [1, 2]
              nope: [1, 2]
    """)
    with pytest.raises(StudyError) as err:
        load_study(f)
    assert err.value.line == 7 and "nope" in str(err.value)


def test_separate_study_file(tmp_path):
    write(tmp_path, "name: demo\nparameters: {a: 1.0, work_s: 0}\n", "problem.yaml")
    s = write(tmp_path, "problem_file: problem.yaml\nstudy:\n  sweep: {list: [{a: 2}, {a: 3}]}\n", "s.yaml")
    res = run_study(s, tmp_path / "out", serial=True, quiet=True, point_fn=demo_point)
    assert res.complete and [r["a"] for r in res.rows] == [2.0, 3.0]
    assert load_study(s).problem_path == (tmp_path / "problem.yaml").resolve()


# ---------------------------------------------------------------------------------------
# one table on every executor
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster
    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                     silence_logs=50)
    yield c
    c.close()


def test_same_table_serial_processes_dask(tmp_path, cluster):
    f = write(tmp_path, EQUIV)
    r_s = run_study(f, tmp_path / "serial", serial=True, quiet=True, point_fn=demo_point)
    r_p = run_study(f, tmp_path / "proc", workers=2, quiet=True, point_fn=demo_point)
    r_d = run_study(f, tmp_path / "dask", scheduler=cluster.scheduler_address, quiet=True,
                    point_fn=demo_point)
    t_s, t_p, t_d = table(tmp_path / "serial"), table(tmp_path / "proc"), table(tmp_path / "dask")
    assert_same(t_s, t_p)
    assert_same(t_s, t_d)
    statuses = [s for s, _, _ in t_s.values()]
    assert len(statuses) == 12 and statuses.count("infeasible") == 2 and statuses.count("error") == 2
    for r in (r_s, r_p, r_d):
        assert r.complete and r.counts["done"] == 12 and r.counts["failed"] == 4
    # the failure is diagnosed, in the table and in the point's run folder
    err = [r for r in r_p.rows if r["status"] == "error"][0]
    assert "RuntimeError: demo point raised" in err["message"]
    assert "demo point raised" in json.loads((r_p.run_dir(err["id"]) / "result.json").read_text())["message"]
    # continuation: a point after a failed neighbour warm-starts from the last success
    assert t_s["p0006"][2] == "p0002" and t_s["p0010"][2] == "p0006"
    # study.csv has the same rows
    csv_rows = (tmp_path / "proc" / "study.csv").read_text().splitlines()
    assert len(csv_rows) == 13 and csv_rows[0].startswith("id,a,b,fail,raise,sweep,sample,")
    # the built problem is cached per worker: each worker process built it once
    builds = {}
    for r in r_p.rows:
        extra = json.loads((r_p.run_dir(r["id"]) / "result.json").read_text())["extra"]
        if "pid" in extra:
            builds[extra["pid"]] = max(builds.get(extra["pid"], 0), extra["cache_builds"])
    assert builds and set(builds.values()) == {1}
    hosts = {r["host"] for r in r_d.rows}
    assert hosts == {socket.gethostname()}


def test_executor_map_for_swarms():
    with Executor(workers=2) as ex:
        assert ex.map(abs, [-3, 2, -1]) == [3, 2, 1]
    with Executor(serial=True) as ex:
        assert ex.map(abs, [-1]) == [1]


def test_local_worker_crash_is_a_failed_point(tmp_path):
    f = write(tmp_path, """\
        name: demo
        parameters: {a: 1.0, work_s: 0, crash: 0}
        study:
          sweep: {list: [{a: 1}, {a: 2, crash: 1}, {a: 3}, {a: 4}]}
    """)
    res = run_study(f, tmp_path / "out", workers=2, quiet=True, point_fn=demo_point)
    st = {r["id"]: r["status"] for r in res.rows}
    assert st == {"p0000": "optimal", "p0001": "error", "p0002": "optimal", "p0003": "optimal"}
    assert "WorkerLost" in res.row("p0001")["message"]


# ---------------------------------------------------------------------------------------
# resume after kill -9
# ---------------------------------------------------------------------------------------
KILL = """\
    name: demo
    parameters: {a: 1.0, work_s: 0.1}
    study:
      sweep: {grid: {a: {start: 0, stop: 1, num: 12}}}
"""

RUNNER = ("import sys; from ocdsl.study.run import run_study; from ocdsl.study.demo import point; "
          "run_study(sys.argv[1], sys.argv[2], workers=2, quiet=True, point_fn=point, "
          "resume=sys.argv[3] == '1')")


def run_sub(f: Path, out: Path, ledger: Path, resume: bool) -> subprocess.Popen:
    env = {**os.environ, "OCDSL_DEMO_LEDGER": str(ledger)}
    return subprocess.Popen([sys.executable, "-c", RUNNER, str(f), str(out), "1" if resume else "0"],
                            env=env, cwd=ROOT, start_new_session=True)


def ledger_keys(p: Path) -> list[float]:
    if not p.exists():
        return []
    return [json.loads(line)["parameters"]["a"] for line in p.read_text().splitlines()]


def test_resume_after_sigkill(tmp_path):
    f = write(tmp_path, KILL)
    out = tmp_path / "out"
    proc = run_sub(f, out, tmp_path / "ledger1", resume=False)
    deadline = time.time() + 60
    while time.time() < deadline:
        if (out / "points").exists() and len(folders(out)) >= 4:
            break
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    time.sleep(0.3)
    before = folders(out)
    assert 4 <= len(before) < 12
    state = {d: os.stat(out / "points" / d / "result.json") for d in before}
    killed = json.loads((out / "study.json").read_text())
    assert killed["state"] == "running"      # a killed study does not look complete

    # without --resume the folder is refused; with it, the study finishes
    with pytest.raises(StudyError, match="--resume"):
        run_study(f, out, serial=True, quiet=True, point_fn=demo_point)
    proc2 = run_sub(f, out, tmp_path / "ledger2", resume=True)
    assert proc2.wait(timeout=60) == 0

    pts = load_study(f).points
    ids = {p.id for p in pts}
    assert folders(out) == ids
    data = json.loads((out / "study.json").read_text())
    assert data["state"] == "complete" and data["resumed"] == len(before)
    assert sorted(r["id"] for r in data["points"]) == sorted(ids)
    assert all(r["status"] == "optimal" for r in data["points"])
    csv_ids = [line.split(",")[0] for line in (out / "study.csv").read_text().splitlines()[1:]]
    assert sorted(csv_ids) == sorted(ids)
    # finished points were kept as they were, and not solved again
    for d, st in state.items():
        now = os.stat(out / "points" / d / "result.json")
        assert (now.st_ino, now.st_mtime_ns) == (st.st_ino, st.st_mtime_ns)
    a_of = {p.id: p.parameters["a"] for p in pts}
    second = ledger_keys(tmp_path / "ledger2")
    assert sorted(second) == sorted(a_of[i] for i in ids - before)   # each unfinished once
    # every point folder holds its own point
    for i in ids:
        assert json.loads((out / "points" / i / "point.json").read_text())["point"]["id"] == i


def test_changed_study_refuses_resume(tmp_path):
    f = write(tmp_path, "name: demo\nparameters: {a: 1.0, work_s: 0}\nstudy:\n  sweep: {list: [{a: 2}]}\n")
    run_study(f, tmp_path / "out", serial=True, quiet=True, point_fn=demo_point)
    f.write_text(f.read_text().replace("{a: 2}", "{a: 3}"))
    with pytest.raises(StudyError, match="different study"):
        run_study(f, tmp_path / "out", serial=True, quiet=True, resume=True, point_fn=demo_point)


def test_a_changed_table_refuses_resume(tmp_path):
    """unseen42 F1: a study cut short, its table's CSV edited, then resumed: the finished points
    (old table) were kept and the rest solved with the new one, "complete", 16 of 40 rows
    2.5x off and ok. The fingerprint covers the files the problem reads."""
    (tmp_path / "kk.csv").write_text("x,k\n0,0\n1,1\n")
    f = write(tmp_path, "name: demo\nparameters: {a: 1.0, work_s: 0}\ntables: {kk: {csv: kk.csv, x: x, "
                        "values: k}}\nstudy:\n  sweep: {list: [{a: 2}]}\n")
    run_study(f, tmp_path / "out", serial=True, quiet=True, point_fn=demo_point)
    run_study(f, tmp_path / "out", serial=True, quiet=True, resume=True, point_fn=demo_point)   # unchanged: resumes
    (tmp_path / "kk.csv").write_text("x,k\n0,0\n1,2\n")
    with pytest.raises(StudyError, match="a file it reads"):
        run_study(f, tmp_path / "out", serial=True, quiet=True, resume=True, point_fn=demo_point)


def test_resume_solves_the_point_an_interrupt_stopped(tmp_path, monkeypatch):
    """unseen42 F2: the point in hand when Ctrl-C or SIGTERM stopped a study is written
    `interrupted`; --resume took it for finished, so the study stayed "complete" with one
    failure and exited 1 at every resume. It is solved again."""
    ledger = tmp_path / "ledger.jsonl"
    monkeypatch.setenv("OCDSL_DEMO_LEDGER", str(ledger))
    f = write(tmp_path, "name: demo\nparameters: {a: 1.0, work_s: 0, interrupt: 0}\nstudy:\n"
                        "  sweep: {list: [{a: 2}, {a: 3, interrupt: 1}]}\n")
    monkeypatch.setenv("OCDSL_DEMO_INTERRUPT", "1")
    run_study(f, tmp_path / "out", serial=True, quiet=True, point_fn=demo_point)
    assert sorted(s for s, _, _ in table(tmp_path / "out").values()) == ["interrupted", "optimal"]
    monkeypatch.delenv("OCDSL_DEMO_INTERRUPT")
    run_study(f, tmp_path / "out", serial=True, quiet=True, resume=True, point_fn=demo_point)
    assert [s for s, _, _ in table(tmp_path / "out").values()] == ["optimal", "optimal"]
    solved = [json.loads(line)["parameters"] for line in ledger.read_text().splitlines()]
    assert len(solved) == 3 and solved.count(solved[0]) == 1       # the finished one once


# ---------------------------------------------------------------------------------------
# Dask: a lost worker, an unreachable scheduler
# ---------------------------------------------------------------------------------------
def test_dask_worker_killed_mid_study(tmp_path, cluster):
    from distributed import Client
    f = write(tmp_path, """\
        name: demo
        parameters: {a: 1.0, work_s: 0.2}
        study:
          sweep: {grid: {a: {start: 0, stop: 1, num: 12}}}
    """)
    out = tmp_path / "out"
    killed: list[int] = []

    def killer():
        with Client(cluster.scheduler_address, set_as_default=False) as c:
            deadline = time.time() + 60
            while time.time() < deadline:
                if (out / "points").exists() and len(folders(out)) >= 3:
                    break
                time.sleep(0.02)
            pids = c.run(os.getpid)
            pid = sorted(pids.values())[0]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    th = threading.Thread(target=killer)
    th.start()
    res = run_study(f, out, scheduler=cluster.scheduler_address, quiet=True, point_fn=demo_point)
    th.join()
    assert killed
    assert res.complete and res.counts["done"] == 12
    assert sorted(r["id"] for r in res.rows) == sorted(folders(out))
    assert len(folders(out)) == 12
    assert all(r["status"] == "optimal" for r in res.rows)
    data = json.loads((out / "study.json").read_text())
    assert len({r["id"] for r in data["points"]}) == len(data["points"]) == 12


def test_unreachable_scheduler(tmp_path):
    f = write(tmp_path, "name: demo\nparameters: {a: 1.0}\nstudy:\n  sweep: {list: [{a: 2}]}\n")
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there
    out = tmp_path / "out"
    with pytest.raises(StudyError, match="cannot reach the Dask scheduler"):
        run_study(f, out, scheduler=f"tcp://127.0.0.1:{port}", quiet=True, point_fn=demo_point)
    assert not out.exists()
    with pytest.raises(StudyError, match="bad scheduler address"):
        run_study(f, out, scheduler="tcp://nohostport", quiet=True, point_fn=demo_point)
    assert not out.exists()


def test_workers_exit_when_the_study_process_is_killed(tmp_path):
    """A study killed with SIGKILL cannot shut its pool down; its workers (children of the
    fork server, not of the study) must still go, instead of idling for good."""
    code = ("import os, sys, time\n"
            "from ocdsl.study.executor import Executor\n"
            "ex = Executor(workers=2)\n"
            "hs = [ex.submit(os.getpid) for _ in range(8)]\n"
            "pending = set(hs)\n"
            "while pending:\n"
            "    _, pending = ex.wait(pending, timeout=5)\n"
            "print(' '.join(str(p) for p in sorted({h.result() for h in hs})), flush=True)\n"
            "time.sleep(120)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    workers = [int(p) for p in proc.stdout.readline().split()]
    assert workers and proc.pid not in workers
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()

    def alive(pid):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True

    deadline = time.time() + 20
    while time.time() < deadline and any(alive(p) for p in workers):
        time.sleep(0.1)
    assert not any(alive(p) for p in workers), workers


# a rest-to-rest transfer over a distance d; {method} and {sweep} (under `study: sweep:`) filled in
REST_TO_REST_SWEEP = """name: sweep
parameters: {{d: 1.0}}
model:
  states: [x, v]
  controls: [u]
  dynamics: {{x: v, v: u}}
problem:
  time: {{t0: 0, tf: 2}}
  constraints: [x(t0) == 0, v(t0) == 0, x(tf) == d, v(tf) == 0]
  objective: minimize integral(u**2)
method: {method}
study:
  sweep:
    {sweep}
"""


def test_continuation_with_a_flat_method_is_refused_at_check_time(tmp_path):
    """unseen22 s04: `check` said ok and every point after the first failed with "flat-bspline
    does not take a warm start yet"; without continuation the same sweep is right."""
    import pytest

    from ocdsl.study.spec import StudyError, load_study

    text = REST_TO_REST_SWEEP.format(
        method="{transcription: flat-bspline, flat_outputs: [x], degree: 5, control_points: 8, collocation_points: 8}",
        sweep="list: [{d: 0.5}, {d: 1.0}]\n  continuation: true")
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert "sweep.yaml:15" in str(err.value) and "flat-bspline" in str(err.value)
    path.write_text(text.replace("  continuation: true\n", ""))
    assert len(load_study(path).points) == 2


def test_run_refuses_a_study_block_that_check_refuses(tmp_path):
    """unseen22 b12: `check` refused a sweep over an unknown parameter; `run` solved the
    nominal problem and said nothing."""
    from click.testing import CliRunner

    from ocdsl.cli import main

    path = tmp_path / "sweep.yaml"
    path.write_text(REST_TO_REST_SWEEP.format(method="{transcription: LGR, segments: 2, degree: 3}",
                                              sweep="grid: {dd: [1, 2]}"))
    out = tmp_path / "run"
    res = CliRunner().invoke(main, ["run", str(path), "--out", str(out)])
    assert res.exit_code == 2 and "sweep.yaml:14" in res.output and "'dd'" in res.output, res.output
    assert not out.exists()


def test_a_studys_best_point_is_an_ok_one():
    """unseen33 F4: study.json's "best" named p0000, whose verification failed, with 0 of 3
    points ok: the best is among the points that are ok, and none when none is."""
    from ocdsl.study.table import _Table

    table = _Table.__new__(_Table)
    table.sense = "minimize"
    table.rows = {"p0000": {"id": "p0000", "status": "optimal", "objective": 2.0, "ok": False},
                  "p0001": {"id": "p0001", "status": "optimal", "objective": 3.0, "ok": True}}
    assert table.best()["id"] == "p0001"
    table.rows["p0001"]["ok"] = False
    assert table.best() is None


def test_a_long_point_message_is_cut_at_a_word_and_says_so():
    """unseen33 F12: study.csv's messages stopped mid-word ("not th")."""
    from ocdsl.study.points import _shortened

    text = "not verified: dynamics per piece 0.0127 > 1e-05 " * 10
    cut = _shortened(text)
    assert cut.endswith("... (the point's result.json has it all)")
    assert text.startswith(cut[: cut.index(" ...")]) and cut[: cut.index(" ...")].split()[-1] in text.split()
    assert _shortened("short") == "short"


def test_check_takes_a_study_file_of_its_own(tmp_path):
    """unseen42 F4: `ocdsl check` refused the separate study file docs/studies.md shows
    (`problem_file:` and `study:`) with "missing required key 'name'" and a did-you-mean to
    `problem`, while `ocdsl study` ran it. It checks the block and the problem it names."""
    from click.testing import CliRunner

    from ocdsl.cli import main

    problem = REST_TO_REST_SWEEP.format(method="{transcription: LGR, segments: 2, degree: 3}",
                                        sweep="list: [{d: 2}]")
    (tmp_path / "lq.yaml").write_text(problem.split("study:")[0])
    study = tmp_path / "st.yaml"
    study.write_text("problem_file: lq.yaml\nstudy:\n  sweep: {grid: {d: [0.5, 1.0, 1.5]}}\n")
    res = CliRunner().invoke(main, ["check", str(study)])
    assert res.exit_code == 0 and "ok (study of lq.yaml: 3 points)" in res.output, res.output
    study.write_text("problem_file: lq.yaml\nstudy:\n  sweep: {grid: {dd: [0.5, 1.0]}}\n")
    res = CliRunner().invoke(main, ["check", str(study)])
    assert res.exit_code == 2 and "st.yaml:3" in res.output and "'dd'" in res.output, res.output
    (tmp_path / "lq.yaml").write_text(problem.split("study:")[0].replace("v: u", "v: w"))
    study.write_text("problem_file: lq.yaml\nstudy:\n  sweep: {grid: {d: [0.5, 1.0]}}\n")
    res = CliRunner().invoke(main, ["check", str(study)])
    assert res.exit_code == 2 and "lq.yaml:6" in res.output and "unknown name 'w'" in res.output, res.output


def test_an_unsolved_points_objective_is_labelled_in_the_study_table():
    """unseen50 F6: an infeasible point's last iterate (25) stood in the objective column
    like a solved point's."""
    from ocdsl.study.table import _objective_cell

    assert _objective_cell({"status": "infeasible", "objective": 25.000000000000007}) == "25 (last iterate)"
    assert _objective_cell({"status": "feasible", "objective": 4.0}) == "4"
    assert _objective_cell({"status": "optimal", "objective": 1.5}) == "1.5"
    assert _objective_cell({"status": "error", "objective": None}) == ""


def test_a_worker_lost_under_a_script_names_the_main_guard(monkeypatch, tmp_path):
    """unseen52 F3: `run_study(..., workers=2)` at a script's top level without the
    `__main__` guard: every worker imported the script and started the study again, every
    point was "the worker process died", and nothing named the script."""
    import sys
    import types

    from ocdsl.study.executor import _unguarded_script_hint

    script = types.ModuleType("__main__")
    script.__file__ = str(tmp_path / "sweep.py")
    script.__spec__ = None
    monkeypatch.setitem(sys.modules, "__main__", script)
    assert "guard it with `if __name__ == \"__main__\":`" in _unguarded_script_hint()
    assert str(tmp_path / "sweep.py") in _unguarded_script_hint()
    script.__spec__ = types.SimpleNamespace(name="pkg.mod")        # `python -m`: no script to guard
    assert _unguarded_script_hint() == ""


def test_the_executor_example_of_the_docs_runs_as_written(tmp_path):
    """unseen52 F2: the docs' executor example stopped with NameError (undefined names) and,
    completed but unguarded, lost every worker. Run here as the docs print it, in a process
    of its own, with two workers."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    text = (Path(__file__).parents[1] / "docs" / "studies.md").read_text()
    block = re.search(r"## For other features: the executor.*?```python\n(.*?)```", text, re.S).group(1)
    script = tmp_path / "example.py"
    script.write_text(block)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[25, 49, 1]"


def test_an_unsolved_points_objective_is_labelled_in_the_study_files(tmp_path):
    """unseen54 F7: study.csv and study.json gave an infeasible point's last iterate as its
    objective, unmarked (the console table said "(last iterate)")."""
    import csv
    import json

    from ocdsl.study.spec import Point
    from ocdsl.study.table import _Table

    points = [Point(id="p0", parameters={"T": 1.4}), Point(id="p1", parameters={"T": 2.0})]
    table = _Table(tmp_path, points, {})
    table.set("p0", {"status": "infeasible", "ok": False, "objective": 1.34143}, {})
    table.set("p1", {"status": "optimal", "ok": True, "objective": 1.5}, {})
    table.write("complete", force=True)
    rows = {r["id"]: r for r in csv.DictReader((tmp_path / "study.csv").open())}
    assert rows["p0"]["objective_from"] == "last iterate" and rows["p1"]["objective_from"] == "solution"
    doc = json.loads((tmp_path / "study.json").read_text())
    assert [p["objective_from"] for p in doc["points"]] == ["last iterate", "solution"]
