"""Every run ends and says why (issue 27): time limits, a guess that is not a number, an
infeasible or unbounded problem, Ctrl-C, and study workers that outlive a killed client."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import CONFIGS
from ocdsl.api import compile_file, run_file
from ocdsl.spec.errors import SpecError

ROOT = Path(__file__).resolve().parents[1]

BASE = """name: t
model:
  states: [x, v]
  controls: [u]
  dynamics:
    x: v
    v: u
problem:
  time: {t0: 0, tf: 1}
  constraints:
    - -1 <= u <= 1
    - x(t0) == 0
    - v(t0) == 0
    - x(tf) == 0.2
    - v(tf) == 0
  objective: minimize integral(u**2)
method: {transcription: LGR, segments: 4, degree: 3}
"""

UNBOUNDED = """name: unbounded
model:
  states: [x]
  controls: [u]
  dynamics: {x: u}
problem:
  time: {t0: 0, tf: 1}
  constraints:
    - x(t0) == 0
  objective: minimize x(tf)
method: {transcription: LGR, segments: 4, degree: 3}
"""


def write(tmp_path, text, name="problem.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def ocdsl(*args, **kw):
    env = {**os.environ, "PYOMO_CONFIG_DIR": str(ROOT / ".venv/share/pyomo")}
    return subprocess.run([sys.executable, "-m", "ocdsl.cli", *args], capture_output=True, text=True,
                          env=env, **kw)


def test_ipopt_max_wall_time_ends_time_limit_not_unknown_status(tmp_path):
    p = write(tmp_path, BASE + "solver: {options: {max_wall_time: 1.0e-9}}\n")
    res = run_file(p, tmp_path / "run")
    assert res.status == "time_limit" and "Unknown status" not in res.message.split("(Ipopt")[0]
    saved = json.loads((tmp_path / "run" / "result.json").read_text())
    assert saved["status"] == "time_limit" and (tmp_path / "run" / "trajectory.csv").exists()


def test_a_time_limit_on_the_pynumero_route_is_a_time_limit_with_its_iterate(tmp_path, monkeypatch):
    """Pyomo's cyipopt solver raised KeyError b'Unknown status' for Ipopt's -5 (wall time), so a
    flat B-spline level (always PyNumero) cut short by the run's time limit ended 'error'
    without its last iterate (unseen19 f4)."""
    from ocdsl.transcribe import pseudospectral

    monkeypatch.setitem(pseudospectral.FAST, "direct_nlp", False)
    p = write(tmp_path, BASE + "solver: {options: {max_wall_time: 1.0e-9}}\n")
    res = run_file(p, tmp_path / "run")
    assert res.nlp["evaluation"].startswith("PyNumero")
    assert res.status == "time_limit" and "Unknown status" not in res.message, res.message
    assert (tmp_path / "run" / "trajectory.csv").exists()


def test_the_run_time_limit_is_shared_by_its_solves_and_set_from_the_command_line(tmp_path):
    """--time-limit overrides the file's solver: time_limit; a limit already spent ends the
    next solve before it starts (a run of several starts here)."""
    p = write(tmp_path, BASE.replace("degree: 3}", "degree: 3, starts: 3}") + "solver: {time_limit: 3600}\n")
    assert compile_file(p).spec.solver.time_limit == 3600
    out = ocdsl("run", str(p), "--out", str(tmp_path / "run"), "--time-limit", "1e-9")
    assert out.returncode == 1, out.stderr
    saved = json.loads((tmp_path / "run" / "result.json").read_text())
    assert saved["status"] == "time_limit" and "time limit of 1e-09 s" in saved["message"]


def test_nan_at_the_guess_is_named_before_ipopt_starts(tmp_path):
    p = write(tmp_path, BASE.replace("    v: u\n", "    v: u + sqrt(x - 2)\n"))
    res = run_file(p, None)
    assert res.status == "error" and res.iterations == 0
    assert "Ipopt was not started" in res.message
    assert "the dynamics of v (phase main, segment 0, node 0) is nan" in res.message
    assert "has `sqrt(x - 2)`, which needs x - 2 >= 0, and the guess gives x - 2 = -2" in res.message


@pytest.mark.parametrize("change, named", [
    # the objective's integrand (was: a raw Pyomo "math domain error" and a ValueError)
    (("minimize integral(u**2)", "minimize integral(u**2 + log(x - 2.5))"),
     "the objective's integral has `log(x - 2.5)`, which needs x - 2.5 > 0"),
    (("minimize integral(u**2)", "minimize integral(u**2) + log(x(tf) - 2.5)"),
     "the objective has `log(x(tf) - 2.5)`, which needs x(tf) - 2.5 > 0"),
    # a path constraint only: its rows, not the dynamics' (once every row was blamed)
    (("    - -1 <= u <= 1\n", "    - -1 <= u <= 1\n    - sqrt(x - 2.5) <= 2\n"),
     "path constraint `sqrt(x - 2.5) <= 2` (line 12) has `sqrt(x - 2.5)`"),
])
def test_nan_at_the_guess_names_the_expression_the_phase_and_the_way_out(tmp_path, capfd, change, named):
    p = write(tmp_path, BASE.replace(*change))
    res = run_file(p, tmp_path / "run")
    assert res.status == "error" and "Ipopt was not started" in res.message, res.message
    assert named in res.message and "`guess:` of the phase" in res.message
    assert ("at t = " in res.message and "(phase main)" in res.message) == ("(tf)" not in named)
    assert "dynamics" not in res.message.split("Ipopt was not started")[0], res.message
    assert "math domain error" not in res.message + capfd.readouterr().err
    assert json.loads((tmp_path / "run" / "result.json").read_text())["status"] == "error"


def test_an_infeasible_problem_names_the_conditions_that_cannot_be_met(tmp_path):
    p = write(tmp_path, BASE.replace("x(tf) == 0.2", "x(tf) == 5"))
    res = run_file(p, None)
    assert res.status == "infeasible"
    assert "cannot all be met" in res.message and "`x(tf) == 5` (line 14)" in res.message, res.message


def test_contradictory_boundary_conditions_are_a_compile_error_naming_both(tmp_path):
    p = write(tmp_path, BASE.replace("    - v(tf) == 0\n", "    - v(tf) == 0\n    - x(tf) == 0.3\n"))
    with pytest.raises(SpecError) as e:
        compile_file(p)
    issue = e.value.issues[0]
    assert issue.line == 16 and "contradicts `x(tf) == 0.2` (line 14)" in issue.message, str(e.value)


def test_an_unbounded_problem_is_reported_as_probably_unbounded(tmp_path):
    p = write(tmp_path, UNBOUNDED + "solver: {options: {max_iter: 100}}\n")
    res = run_file(p, None)
    assert res.status != "optimal" and "probably unbounded" in res.message, res.message


@pytest.mark.parametrize("sense", ["minimize", "maximize"])
def test_probably_unbounded_prints_the_objective_with_the_files_sign(tmp_path, sense):
    """A maximisation's Ipopt history is the negated objective: the message once said "from -0
    to -6e17" for `maximize x(tf)` running to +6e17."""
    import re

    text = UNBOUNDED.replace("minimize x(tf)", f"{sense} x(tf)")
    res = run_file(write(tmp_path, text + "solver: {options: {max_iter: 100}}\n"), None)
    m = re.search(r"went from (\S+) to (\S+):", res.message)
    assert m, res.message
    first, last = m.group(1), float(m.group(2))
    assert first == "0" and (last > 1e3 if sense == "maximize" else last < -1e3), res.message


def test_the_summary_of_a_failed_run_shows_no_objective_as_a_result(tmp_path):
    p = write(tmp_path, BASE.replace("    v: u\n", "    v: u + sqrt(x - 2)\n"))
    out = ocdsl("run", str(p), "--out", str(tmp_path / "run"))
    assert out.returncode == 1
    rows = [line.split() for line in out.stdout.splitlines()]
    assert not any(r and r[0] == "objective" for r in rows), out.stdout


def _interrupted_run(tmp_path, sig):
    """A run of an unbounded problem (it would iterate for ever) sent ``sig`` once Ipopt's log
    table has started: (exit code, the run folder's result.json, the output)."""
    p = write(tmp_path, UNBOUNDED + "solver: {options: {max_iter: 100000000}}\n")
    env = {**os.environ, "PYOMO_CONFIG_DIR": str(ROOT / ".venv/share/pyomo")}
    proc = subprocess.Popen([sys.executable, "-m", "ocdsl.cli", "run", str(p), "--out", str(tmp_path / "run"),
                             "--verbose"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    seen = []
    for line in proc.stdout:             # Ipopt's log: its table has started
        seen.append(line)
        if line.lstrip().startswith("iter") and "objective" in line:
            break
    proc.send_signal(sig)
    rest, _ = proc.communicate(timeout=300)
    saved = (tmp_path / "run" / "result.json")
    return proc.returncode, json.loads(saved.read_text()) if saved.exists() else {}, "".join(seen) + rest


def test_ctrl_c_writes_the_last_iterate_marked_interrupted_and_exits_130(tmp_path):
    """SIGINT while Ipopt iterates (an unbounded problem that would run for ever): the solve
    stops at its next iteration, the run folder holds that iterate, status interrupted."""
    code, saved, out = _interrupted_run(tmp_path, signal.SIGINT)
    assert code == 130, out
    assert saved["status"] == "interrupted" and saved["iterations"] > 0
    assert (tmp_path / "run" / "trajectory.csv").exists()


def test_ctrl_c_keeps_a_complete_earlier_run_in_the_folder(tmp_path):
    """unseen24 G4: Ctrl-C over a complete earlier run replaced it with the interrupted
    iterate. The earlier run stays, and the output says the iterate was not written."""
    first = ocdsl("run", str(write(tmp_path, UNBOUNDED + "solver: {options: {max_iter: 3}}\n")),
                  "--out", str(tmp_path / "run"))
    before = json.loads((tmp_path / "run" / "result.json").read_text())
    marker = (tmp_path / "run" / ".ocdsl-run").read_text()
    assert first.returncode == 1 and before["status"] == "max_iter", first.stdout
    code, saved, out = _interrupted_run(tmp_path, signal.SIGINT)
    assert code == 130, out
    assert saved == before and (tmp_path / "run" / ".ocdsl-run").read_text() == marker
    assert "earlier complete run" in out and "was kept" in out, out


def test_sigterm_writes_the_last_iterate_marked_interrupted_and_exits_143(tmp_path):
    """unseen24: SIGTERM (what `timeout`, systemd and batch schedulers send) ended the process
    with no run folder at all. It is handled as Ctrl-C is: the folder holds the last iterate."""
    code, saved, out = _interrupted_run(tmp_path, signal.SIGTERM)
    assert code == 143, out
    assert saved["status"] == "interrupted" and "SIGTERM" in saved["message"]


def test_ctrl_c_stops_a_serial_study(tmp_path):
    """unseen24: Ctrl-C did not stop `ocdsl study --serial` (every point ran, exit 0). Now the
    point in hand stops, no other starts, study.json says interrupted, exit 130."""
    text = BASE.replace("x(tf) == 0.2", "x(tf) == d") + "parameters: {d: 0.2}\n" + \
        "study:\n  sweep:\n    grid:\n      d: {start: 0.1, stop: 0.3, num: 200}\n"
    p = write(tmp_path, text)
    env = {**os.environ, "PYOMO_CONFIG_DIR": str(ROOT / ".venv/share/pyomo")}
    proc = subprocess.Popen([sys.executable, "-m", "ocdsl.cli", "study", str(p), "--out", str(tmp_path / "st"),
                             "--serial", "-q"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    points = tmp_path / "st" / "points"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not (points.is_dir() and len(list(points.iterdir())) >= 2):
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=300)
    assert proc.returncode == 130, out
    study = json.loads((tmp_path / "st" / "study.json").read_text())
    assert study["state"] == "interrupted" and study["counts"]["pending"] > 100, study["counts"]


def _descendants(pid: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
            children.setdefault(ppid, []).append(int(d.name))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def _alive(pid: int) -> bool:
    from ocdsl.study.executor import owner_alive

    return owner_alive(pid)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_study_workers_die_with_a_killed_client_left_a_zombie(tmp_path):
    """kill -9 of `ocdsl study`, never reaped (a zombie: os.kill(pid, 0) still succeeds):
    its workers and fork server end, and the pipes they held close (reading them ends)."""
    from ocdsl.study.executor import owner_alive

    p = write(tmp_path, UNBOUNDED.replace("minimize x(tf)", "minimize x(tf) + k*integral(u**2)")
              .replace("  dynamics: {x: u}", "  parameters: {k: 1.0}\n  dynamics: {x: u}")
              + "solver: {options: {max_iter: 100000000}}\n"
              + "study:\n  sweep:\n    grid:\n      k: [1, 2, 3, 4]\n")
    env = {**os.environ, "PYOMO_CONFIG_DIR": str(ROOT / ".venv/share/pyomo")}
    proc = subprocess.Popen([sys.executable, "-m", "ocdsl.cli", "study", str(p), "--out", str(tmp_path / "s"),
                             "--workers", "2", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    workers: set[int] = set()
    for _ in range(600):                  # the fork server and both workers are up
        workers = _descendants(proc.pid)
        if len(workers) >= 3:
            break
        time.sleep(0.5)
    assert len(workers) >= 3, "the study's workers did not start"
    os.kill(proc.pid, signal.SIGKILL)
    for _ in range(600):                  # not reaped: a zombie
        if not owner_alive(proc.pid):
            break
        time.sleep(0.1)
    os.kill(proc.pid, 0)                  # what the old owner watch asked: it still succeeds
    for _ in range(600):
        if not any(_alive(w) for w in workers):
            break
        time.sleep(0.5)
    left = [w for w in workers if _alive(w)]
    assert not left, f"workers still alive: {left}"
    assert proc.stdout.read() is not None and proc.stderr.read() is not None   # EOF, not a deadlock
    proc.wait()


def test_a_time_limit_during_mesh_refinement_keeps_the_best_completed_mesh(tmp_path, monkeypatch, capsys):
    """The third mesh's solve hits the time limit: the result is the best mesh solved before it
    (its objective, not null), the message says which, and the status stays time_limit."""
    from ocdsl.solve import ipopt

    real, calls = ipopt.solve, []

    def solve(*args, **kw):
        calls.append(1)
        if len(calls) == 3:
            return ipopt.SolveInfo("time_limit", "the run's time limit of 1 s was reached before this solve", 0,
                                   None, 0.0)
        return real(*args, **kw)

    monkeypatch.setattr(ipopt, "solve", solve)
    text = BASE.replace("degree: 3}", "degree: 3, mesh: {tolerance: 1.0e-12, move_switches: false}}")
    res = run_file(write(tmp_path, text), tmp_path / "run")
    saved = json.loads((tmp_path / "run" / "result.json").read_text())
    assert saved["status"] == "time_limit" and saved["objective"] is not None
    hist = saved["extra"]["mesh_history"]
    assert [h["status"] for h in hist] == ["optimal", "optimal", "time_limit"], hist
    k = saved["extra"]["mesh"]["chosen_iteration"]
    assert k in (1, 2) and saved["objective"] == hist[k - 1]["objective"]
    assert f"the result is mesh iteration {k}'s solution" in res.message, res.message
    # that solution is a completed solve: it is verified like any other (a verdict, not 'skipped'),
    # and the summary names it as the best completed mesh, not as a last iterate
    assert saved["extra"]["mesh"]["chosen_status"] == "optimal"
    assert saved["verification"]["status"] in ("verified", "failed"), saved["verification"]
    from ocdsl.cli import _summary

    capsys.readouterr()
    _summary(res, tmp_path / "run")
    shown = capsys.readouterr().out
    assert "best completed mesh" in shown and f"mesh iteration {k}, Ipopt optimal" in shown, shown
    assert "last iterate" not in shown, shown


def test_a_time_limit_that_cuts_later_starts_is_a_time_limit(tmp_path, monkeypatch, capsys):
    """unseen42 F3: `--time-limit` ran out after two of six starts: two starts and the
    bisection check never ran, and the run said `optimal`, exit 0, where the docs say a run
    past its limit ends `time_limit`. The best start's solution is kept, verified and named
    as such; the status is time_limit (exit 1)."""
    import time

    from ocdsl.solve import ipopt

    real, calls = ipopt.solve, []

    def solve(*args, **kw):
        calls.append(1)
        if len(calls) == 2:        # the limit runs out after the first start
            deadline = ipopt._DEADLINE.get()
            ipopt._DEADLINE.set((time.monotonic() - 1.0, deadline[1]))
        return real(*args, **kw)

    monkeypatch.setattr(ipopt, "solve", solve)
    text = BASE.replace("degree: 3}", "degree: 3, starts: 3}") + "solver: {time_limit: 100}\n"
    res = run_file(write(tmp_path, text), tmp_path / "run")
    assert [s["status"] for s in res.extra["starts"]] == ["optimal", "time_limit", "time_limit"]
    assert res.status == "time_limit" and not res.ok
    cut = res.extra["cut_short"]
    assert cut["solution_status"] == "optimal" and cut["solves_cut"] >= 2      # the starts (and the bisection)
    assert f"the run's time limit cut {cut['solves_cut']} of its solves" in res.message
    assert res.verification["status"] in ("verified", "failed")       # a verdict on it, not skipped
    assert res.objective == res.extra["starts"][0]["objective"]
    from ocdsl.cli import _summary

    capsys.readouterr()
    _summary(res, tmp_path / "run")
    shown = capsys.readouterr().out
    assert "best solution before the time limit (Ipopt optimal" in shown and "last iterate" not in shown, shown


ZERMELO_SI = """name: Zermelo in SI units
model:
  states: [x, y]
  controls: [theta]
  parameters: {V: 5, h: 1000}
  dynamics: {x: V*cos(theta) - V*y/h, y: V*sin(theta)}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 3660, y(t0) == -1860, x(tf) == 0, y(tf) == 0, 1 <= tf <= 20000]
  objective: minimize tf
  guess: {tf: 1000, theta: 2}
method: {transcription: LGR, segments: 8, degree: 5}
"""


def test_a_failed_solve_of_a_badly_scaled_file_suggests_automatic_scaling(tmp_path):
    """Zermelo in metres and seconds (unseen #24): Ipopt fails (restoration failed) and the
    message says to try `scaling: {mode: auto}`, which solves it; a failure of a well-scaled
    file gets no such hint."""
    res = run_file(write(tmp_path, ZERMELO_SI), None)
    assert res.status in ("error", "max_iter"), res.status
    assert "try `scaling: {mode: auto}`" in res.message and "tf against theta" in res.message, res.message
    assert "nothing bounds" not in res.message       # theta enters through sin/cos: an angle
    scaled = run_file(write(tmp_path, ZERMELO_SI + "scaling: {mode: auto}\n", "scaled.yaml"), None)
    assert scaled.status == "optimal" and abs(scaled.tf - 1091.573053) < 1e-4, (scaled.status, scaled.tf)
    small = run_file(write(tmp_path, BASE + "solver: {options: {max_iter: 2}}\n", "small.yaml"), None)
    assert small.status == "max_iter" and "scaling" not in small.message, small.message


@pytest.mark.parametrize("change, hint", [
    # fuel as a state m' = abs(u) (unseen #17): the abs() hint, through mesh refinement too
    (("    v: u\n", "    v: u\n    m: abs(u)\n"), "abs() in the dynamics of m has no derivative at 0"),
    (("minimize integral(u**2)", "minimize abs(x(tf) - 0.1) + integral(0.01*u**2)"),
     "abs() in the objective has no derivative at 0"),
    # minimum time with the control bound forgotten (unseen #34)
    (("    - -1 <= u <= 1\n", ""), "whose control u nothing bounds"),
])
def test_a_failed_solve_names_a_cheaply_detected_cause(tmp_path, change, hint):
    text = BASE.replace("states: [x, v]", "states: [x, v, m]") if "m: abs" in change[1] else BASE
    if "nothing bounds" in hint:
        text = text.replace("time: {t0: 0, tf: 1}", "time: {t0: 0, tf: free}").replace(
            "minimize integral(u**2)", "minimize tf")
    text = text.replace(*change).replace("degree: 3}", "degree: 3, mesh: {tolerance: 1.0e-6}}") \
        + "solver: {options: {max_iter: 5}}\n"
    res = run_file(write(tmp_path, text), None)
    assert res.status == "max_iter" and hint in res.message, res.message
    assert "scaling" not in res.message


def test_a_root_of_zero_at_the_guess_is_a_diagnosed_failure_with_a_run_folder(tmp_path):
    """unseen2 #3: minimize sqrt(integral(u**2)) from the default guess u = 0 took the PyNumero
    route, whose ASL printed "can't evaluate sqrt'(0)" and ended the process: no run folder.
    Now Ipopt is not started, the message names the root in the file's words, the folder is
    written and the exit code is 1."""
    import subprocess
    import sys

    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(Path(__file__).parent / "data" /
                           "root_of_zero_objective.yaml"), "--out", str(out)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    saved = json.loads((out / "result.json").read_text())
    assert saved["status"] == "error"
    assert "`sqrt(integral(u**2))`" in saved["message"] and "Ipopt was not started" in saved["message"]


def test_every_attempt_of_a_solve_gets_the_time_left(monkeypatch):
    """unseen10 F1: a mesh's warm-started solve (given multipliers) was built from the options
    without the run's time left, and ran 75 s past a 100 s limit; and a retry without the
    multipliers gets what is left after the first attempt, not the whole again."""
    import time as _time

    import pyomo.core as pyo

    from ocdsl.solve import ipopt

    seen = []

    def attempt(model, opts, verbose, progress, on_iteration, multipliers, transcription=None, given=frozenset()):
        seen.append((multipliers is not None, opts.get("max_wall_time")))
        _time.sleep(0.2)
        return ipopt.SolveInfo("max_iter" if multipliers is not None else "optimal", "", 1, 0.0, 0.2)

    monkeypatch.setattr(ipopt, "_attempt", attempt)
    monkeypatch.setattr(ipopt, "check_available", lambda: None)
    m = pyo.ConcreteModel()
    m.x = pyo.Var(initialize=1.0)
    m.o = pyo.Objective(expr=m.x ** 2)
    with ipopt.time_limit(5.0):
        ipopt.solve(m, {}, multipliers=ipopt.Multipliers())
    (warm, w_left), (cold, c_left) = seen
    assert warm and not cold
    assert w_left is not None and 4.0 < w_left <= 5.0
    assert c_left is not None and c_left <= w_left - 0.19


def test_a_published_value_matched_by_a_failed_solves_last_iterate_is_no_pass(tmp_path):
    """unseen19 F3: Ipopt ended 'error' and the summary printed `... (last iterate, not a
    solution) pass` with result.json `passed: true`. Only a solution meets a published value."""
    import re

    text = (CONFIGS / "brachistochrone.yaml").read_text().split("expect:")[0]
    text = re.sub(r"(?m)^solver:.*\n", "", text)
    text += "solver: {options: {max_iter: 2}}\nexpect:\n  objective: {value: 1.8, atol: 1.0e+3}\n"
    res = run_file(write(tmp_path, text), tmp_path / "run")
    saved = json.loads((tmp_path / "run" / "result.json").read_text())
    assert saved["status"] == "max_iter" and abs(saved["objective"] - 1.8) < 1e3     # the value "matches"
    (check,) = saved["expect"]
    assert check["passed"] is False and check["not_a_solution"] is True
    assert not res.expect[0]["passed"]



LOOP = """name: minimum-time periodic loop
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: free}
  constraints: [-1 <= u <= 1, v(t0) == 1, x(tf) == x(t0), v(tf) == v(t0), 1 <= tf <= 10]
  objective: minimize tf
"""


def test_a_failed_solve_names_a_state_whose_level_nothing_fixes(tmp_path):
    """unseen21 FA8: x enters only through x(tf) == x(t0); every shift of it is a solution and
    Ipopt wandered to max_iter on 13 of 17 meshes with no hint. The hint names x and the fix;
    fixing one end (or any use of x elsewhere) removes it."""
    from ocdsl.api import compile_file
    from ocdsl.solve.failure_hints import failure_hints

    (tmp_path / "loop.yaml").write_text(LOOP)
    hint = failure_hints(compile_file(tmp_path / "loop.yaml"), None, "max_iter")
    assert "Nothing fixes the level of x" in hint and "x(t0) == 0" in hint and " v" not in hint.split(":")[0]
    for fixed in ("v(t0) == 1, x(t0) == 0", "v(t0) == 1, x >= -10"):
        (tmp_path / "anchored.yaml").write_text(LOOP.replace("v(t0) == 1", fixed))
        assert "Nothing fixes" not in failure_hints(compile_file(tmp_path / "anchored.yaml"), None, "max_iter")


def test_ipopts_output_file_keeps_the_first_solve_and_numbers_the_later_ones(tmp_path, monkeypatch):
    """Ipopt truncates its output_file per solve; a run's later solves (the bisection check)
    overwrote the first's log, and the bench read a bisected mesh's 2,560 variables as
    Goddard's 644. The first solve keeps the name, later ones are numbered."""
    from ocdsl.solve import ipopt

    monkeypatch.setattr(ipopt, "_SOLVES_WITH_OUTPUT_FILE", [0])
    log = str(tmp_path / "ipopt.txt")
    assert ipopt._numbered_output_file({"tol": 1e-8}) == {"tol": 1e-8}
    first = ipopt._numbered_output_file({"output_file": log})
    second = ipopt._numbered_output_file({"output_file": log})
    assert first["output_file"] == log and second["output_file"] == str(tmp_path / "ipopt.2.txt")


@pytest.mark.parametrize("objective", ["minimize 0", "minimize 0.0"])
def test_a_feasibility_problem_solves_and_its_certificate_is_skipped(tmp_path, objective):
    """unseen27: `minimize 0` (documented as a feasibility problem) ended `solver error` with a
    SyntaxError from the generated code (a function of no argument), and once solved its
    certificate judged the NLP's arbitrary multipliers ("failed"). Now it solves; the
    certificate says there is nothing to check."""
    res = run_file(write(tmp_path, BASE.replace("minimize integral(u**2)", objective)), tmp_path / "run")
    assert res.status == "optimal", res.message
    x_end = res.phases[0].states["x"][-1]
    assert x_end == pytest.approx(0.2, abs=1e-6)
    assert "feasibility problem" in res.certificate.get("skipped", ""), res.certificate


def test_scaling_auto_prints_no_pyomo_note_before_the_status(tmp_path):
    """unseen27: `scaling: auto` printed Pyomo's NL-writer WARNING (factors of variables it
    skips) before the run's status line."""
    # minimum time over 100 km at 10 m/s^2 (SI units)
    text = (BASE.replace("tf: 1}", "tf: free}").replace("-1 <= u <= 1", "-10 <= u <= 10")
            .replace("x(t0) == 0", "x(t0) == -1.0e5").replace("x(tf) == 0.2", "x(tf) == 0\n    - 1 <= tf <= 1000")
            .replace("integral(u**2)", "tf") + "scaling: {mode: auto}\n")
    out = ocdsl("run", str(write(tmp_path, text)), "--out", str(tmp_path / "run"))
    assert out.returncode == 0, out.stdout + out.stderr
    assert "WARNING" not in out.stdout + out.stderr, out.stdout + out.stderr
    assert out.stdout.startswith("t: solver optimal"), out.stdout


def test_an_objective_whose_names_cancel_is_refused_at_check(tmp_path):
    """unseen28: `minimize x(tf) - x(tf)` is the constant 0 once SymPy cancels it; the docs
    refuse an objective that names something yet is a constant, but it passed as a bare number."""
    p = write(tmp_path, BASE.replace("minimize integral(u**2)", "minimize x(tf) - x(tf)"))
    with pytest.raises(SpecError) as err:
        compile_file(p)
    assert "simplifies to the constant 0" in str(err.value) and ":16:" in str(err.value)


def test_a_control_guess_is_flown_from_x_t0_before_infeasibility_is_diagnosed():
    """unseen57 F1: the fed-batch ethanol fermenter (Chen & Hwang) with `guess: {u: 3}` alone:
    the states were guessed constant at x(t0) (the volume at 10 where u = 3 takes it to 193),
    Ipopt ended locally infeasible, and the relaxed solve named the correct `x1(t0) == 1` and
    `x4(t0) == 10` as unmet. The guessed control flown from x(t0) is feasible; the solve from
    those states is tried before the diagnosis, and solves."""
    from pathlib import Path

    from ocdsl.api import run_file

    res = run_file(Path(__file__).parent / "data" / "ethanol_control_guess.yaml", None)
    assert res.status != "infeasible" and res.objective > 1.9e4, (res.status, res.message[:300])
    assert "x1(t0) == 1" not in res.message
    assert any(r.get("flown_guess") for r in res.extra["starts"]), res.extra.get("starts")


def test_an_acceptable_end_from_large_variables_says_why(tmp_path):
    """unseen61 F1: Bryson-Denham's altitude floor in SI (h about 6.5e6 m) with `mesh:` ends
    `acceptable` on every mesh (the refinement's tol 1e-10 is below the rounding of h), exit 1
    on a J right to 8e-15, with no word why; the hint names the spread and the remedy."""
    from pathlib import Path

    from ocdsl.api import run_file

    res = run_file(Path(__file__).parent / "data" / "altitude_floor_si_mesh.yaml", None)
    assert res.status == "acceptable" and not res.ok
    assert res.objective == pytest.approx(94777.49666666667, rel=1e-9)
    assert "Ipopt met only its acceptable level" in res.message and "scaling: {mode: auto}" in res.message
