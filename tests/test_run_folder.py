"""Output folders: ocdsl never removes what it did not write, and replaces its own folders
in one step (ocdsl/run_folder.py)."""
import json
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ocdsl import run_folder
from ocdsl.result import PhaseTrajectory, Result
from ocdsl.run_folder import MARKER, FolderError

ROOT = Path(__file__).resolve().parents[1]
PROBLEM = ROOT / "configs" / "double_integrator.yaml"


def _result(tag: str) -> Result:
    t = np.linspace(0.0, 1.0, 50)
    ph = PhaseTrajectory("main", t, states={"x": t ** 2}, controls={"u": 2 + 0 * t})
    return Result("t", "optimal", message=tag, phases=[ph], tables={"extra": {"a": t}},
                  problem={"phases": {"main": {"states": ["x"], "controls": ["u"]}}})


def _holds(folder: Path, tag: str) -> bool:
    """``folder`` is the complete run folder written with message ``tag``."""
    try:
        marker = json.loads((folder / MARKER).read_text())
        data = json.loads((folder / "result.json").read_text())
    except (OSError, ValueError):
        return False
    return (not marker["partial"] and data["message"] == tag
            and all((folder / e).exists() for e in marker["entries"])
            and len(Result.read(folder).phases[0].time) == 50)


def _ocdsl(*args, cwd=None):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", "ocdsl.cli", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def test_run_onto_a_users_folder_is_refused_and_nothing_touched(tmp_path):
    user = tmp_path / "mine"
    (user / "sub").mkdir(parents=True)
    (user / "keep.txt").write_text("mine")
    os.chmod(user, 0o750)
    p = _ocdsl("run", PROBLEM, "--out", user, "-q")
    assert p.returncode == 2
    assert "keep.txt" in p.stderr and "not written by ocdsl" in p.stderr
    assert "Traceback" not in p.stderr
    assert sorted(os.listdir(user)) == ["keep.txt", "sub"]
    assert (user / "keep.txt").read_text() == "mine"
    assert stat.S_IMODE(user.stat().st_mode) == 0o750
    with pytest.raises(FolderError):           # and the Python API refuses the same way
        _result("x").write(user, force=True)
    assert sorted(os.listdir(user)) == ["keep.txt", "sub"]


@pytest.mark.parametrize("out", [".", "..", "/", "./", "../here"])
def test_out_dot_dotdot_root_refused_cleanly(tmp_path, out):
    here = tmp_path / "here"
    here.mkdir()
    (here / "keep.txt").write_text("mine")
    p = _ocdsl("run", PROBLEM, "--out", out, "-q", cwd=here)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and p.stderr.startswith("Error: ")
    assert sorted(os.listdir(here)) == ["keep.txt"]
    assert sorted(os.listdir(tmp_path)) == ["here"]


def test_rerun_replaces_the_earlier_run_and_keeps_foreign_files(tmp_path):
    out = tmp_path / "run"
    _result("one").write(out)
    _result("two").write(out)
    assert _holds(out, "two")
    (out / "notes.txt").write_text("mine")
    with pytest.raises(FolderError, match="notes.txt"):
        _result("three").write(out, force=True)
    assert (out / "notes.txt").read_text() == "mine" and _holds(out, "two")


def test_another_kind_needs_force(tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    run_folder.write_marker(out, "study", ["plan.json"])
    (out / "plan.json").write_text("{}")
    with pytest.raises(FolderError, match="--force"):
        _result("a").write(out)
    _result("a").write(out, force=True)
    assert _holds(out, "a") and not (out / "plan.json").exists()


def test_nested_run_folders_are_ocdsl_s(tmp_path):
    """A study's points carry their own markers; a foreign file inside one is still found."""
    out = tmp_path / "s"
    (out / "points").mkdir(parents=True)
    run_folder.write_marker(out, "study", ["points", "plan.json"])
    (out / "plan.json").write_text("{}")
    _result("p").write(out / "points" / "p1")
    run_folder.check_destination(out, "study")
    (out / "points" / "p1" / "mine.txt").write_text("x")
    with pytest.raises(FolderError, match="points/p1/mine.txt"):
        run_folder.check_destination(out, "study", force=True)


def test_a_file_the_user_changed_in_a_run_is_the_users(tmp_path):
    """unseen24 G1: a user's edit of an ocdsl-written file was replaced by the next run."""
    out = tmp_path / "run"
    _result("one").write(out)
    with open(out / "trajectory.csv", "a") as fh:
        fh.write("# my edit\n")
    edited = (out / "trajectory.csv").read_text()
    with pytest.raises(FolderError, match=r"trajectory.csv \(changed since ocdsl wrote it\)"):
        _result("two").write(out, force=True)
    assert (out / "trajectory.csv").read_text() == edited


def test_a_link_put_in_place_of_an_ocdsl_entry_is_the_users(tmp_path):
    """unseen24 G2: a link the user put where ocdsl wrote a folder or a file was removed."""
    out = tmp_path / "run"
    precious = tmp_path / "precious"
    precious.mkdir()
    (precious / "mine.csv").write_text("mine")
    _result("one").write(out)
    import shutil
    shutil.rmtree(out / "tables")
    (out / "tables").symlink_to(precious)
    with pytest.raises(FolderError, match="tables \\(a link the user put there\\)"):
        _result("two").write(out)
    assert (out / "tables").is_symlink() and (precious / "mine.csv").read_text() == "mine"
    (out / "tables").unlink()
    (out / "trajectory.csv").unlink()
    (out / "trajectory.csv").symlink_to(precious / "mine.csv")
    with pytest.raises(FolderError, match="a link the user put there"):
        _result("two").write(out)
    assert (out / "trajectory.csv").is_symlink()


def test_another_run_inside_a_run_is_not_replaced_with_it(tmp_path):
    """unseen24 G3: ``run --out q/inner`` then ``run --out q`` deleted the separate run q/inner."""
    out = tmp_path / "q"
    _result("outer").write(out)
    _result("inner").write(out / "inner")
    with pytest.raises(FolderError, match=r"inner/ \(another ocdsl run\)"):
        _result("again").write(out, force=True)
    assert _holds(out / "inner", "inner") and _holds(out, "outer")


def test_a_report_s_files_rewritten_by_ocdsl_keep_the_run_replaceable(tmp_path):
    """Files ocdsl itself rewrites in a run folder (a report made twice) are not taken for
    the user's: their digests go when ocdsl claims them again."""
    out = tmp_path / "run"
    _result("one").write(out)
    marker = run_folder.read_marker(out)
    assert "result.json" in marker["digests"] and "trajectory.csv" in marker["digests"]
    for text in ("<p>first</p>", "<p>second</p>"):
        run_folder.claim(out, ["report.html"])
        (out / "report.html").write_text(text)
    _result("two").write(out)
    assert _holds(out, "two") and not (out / "report.html").exists()


@pytest.mark.parametrize("mask,dmode,fmode", [(0o022, 0o755, 0o644), (0o077, 0o700, 0o600),
                                               (0o002, 0o775, 0o664)])
def test_modes_follow_the_umask(tmp_path, mask, dmode, fmode):
    old = os.umask(mask)
    try:
        out = _result("m").write(tmp_path / "deep" / "run")
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == dmode
    assert stat.S_IMODE((out / "tables").stat().st_mode) == dmode
    for f in ("result.json", "trajectory.csv", MARKER, "tables/extra.csv"):
        assert stat.S_IMODE((out / f).stat().st_mode) == fmode, f


def _steps_of_a_write():
    """Every file-system call a write makes; the kill test stops the writer at each one."""
    return [(os, "replace"), (os, "rename"), (os, "rmdir"), (os, "unlink"), (os, "mkdir"),
            (os, "chmod"), (os, "fchmod"), (run_folder, "_exchange"), (Path, "write_text"),
            (Path, "mkdir"), (Path, "unlink")]


def _write_killed_at(dest: Path, k: int) -> bool:
    """In a child process, write ``new`` over ``dest``, SIGKILLed at the k-th step. True
    if the kill happened (False: the write has fewer than k steps)."""
    pid = os.fork()
    if pid == 0:
        try:
            count = [0]

            def hit():
                count[0] += 1
                if count[0] == k:
                    os.kill(os.getpid(), signal.SIGKILL)

            for owner, name in _steps_of_a_write():
                real = getattr(owner, name)

                def step(*a, _real=real, **kw):
                    hit()
                    out = _real(*a, **kw)
                    hit()
                    return out
                setattr(owner, name, step)
            _result("new").write(dest)
        finally:
            os._exit(0)
    _, status = os.waitpid(pid, 0)
    return os.WIFSIGNALED(status)


def test_a_kill_at_any_step_leaves_the_old_or_the_new_run(tmp_path):
    killed_at = 0
    for k in range(1, 200):
        dest = tmp_path / f"t{k}" / "run"
        _result("old").write(dest)
        if not _write_killed_at(dest, k):
            break
        killed_at += 1
        assert _holds(dest, "old") or _holds(dest, "new"), f"kill at step {k}: {os.listdir(dest.parent)}"
        _result("again").write(dest)             # the next write cleans what the kill left
        assert os.listdir(dest.parent) == ["run"], f"kill at step {k}"
        assert _holds(dest, "again")
    assert killed_at > 10       # the write really has steps to be killed at


def test_study_and_report_outputs_refuse_a_users_folder(tmp_path):
    from ocdsl.report.build import ReportError, make_comparison_report
    from ocdsl.study.run import StudyError, run_points

    user = tmp_path / "mine"
    user.mkdir()
    (user / "keep.txt").write_text("mine")
    with pytest.raises(StudyError, match="keep.txt"):
        run_points(PROBLEM, user, [{"id": "p0", "parameters": {}}], serial=True, quiet=True)
    run = _result("r").write(tmp_path / "run")
    with pytest.raises(ReportError, match="keep.txt"):
        make_comparison_report([run], user, formats=("html",))
    assert os.listdir(user) == ["keep.txt"]
    made = make_comparison_report([run], tmp_path / "cmp", formats=("html",))
    assert made and run_folder.read_marker(tmp_path / "cmp")["kind"] == "comparison"
    make_comparison_report([run], tmp_path / "cmp", formats=("html",))     # its own: rewritten
    assert run_folder.foreign_entries(tmp_path / "cmp") == []


def test_a_report_never_replaces_a_report_file_ocdsl_did_not_write(tmp_path):
    """unseen12 F1: `ocdsl report DIR` replaced a report.html the user had put in a run folder
    (and in a pre-marker-looking folder with a result.json), exit 0. Now refused, exit 2,
    the file untouched; the report the run folder's marker lists is rewritten as before."""
    run = _result("r").write(tmp_path / "run")
    (run / "report.html").write_text("<p>mine</p>")
    r = _ocdsl("report", run)
    assert r.returncode == 2 and "report.html" in r.stderr and "did not write" in r.stderr, r.stderr
    assert (run / "report.html").read_text() == "<p>mine</p>" and not (run / "report.pdf").exists()
    old = tmp_path / "old"
    old.mkdir()
    (old / "result.json").write_text((run / "result.json").read_text())
    (old / "report.html").write_text("<h1>my report</h1>")
    r = _ocdsl("report", old)
    assert r.returncode == 2 and (old / "report.html").read_text() == "<h1>my report</h1>", r.stderr
    (run / "report.html").unlink()
    for _ in range(2):      # ocdsl's own report: written, then replaced
        r = _ocdsl("report", run)
        assert r.returncode == 0, r.stderr
    assert "report.html" in run_folder.read_marker(run)["entries"]


def test_bench_refuses_an_out_file_it_did_not_write(tmp_path):
    """unseen12 F3: `ocdsl bench FILE --out notes.md` replaced the user's notes.md. Refused
    before any run (exit 2, the file untouched)."""
    notes = tmp_path / "notes.md"
    notes.write_text("mine\n")
    r = _ocdsl("bench", PROBLEM, "--runs", "1", "--out", notes, cwd=tmp_path)
    assert r.returncode == 2 and "not a table ocdsl bench wrote" in r.stderr, r.stderr
    assert notes.read_text() == "mine\n"


def test_a_warm_start_that_is_not_a_run_folder_is_a_usage_error(tmp_path):
    """unseen12 F7: `--warm-start` of the user's folder wrote a failed run folder, exit 1."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "a.txt").write_text("x")
    r = _ocdsl("run", PROBLEM, "--out", tmp_path / "r", "--warm-start", mine, cwd=tmp_path)
    assert r.returncode == 2 and "not a run folder" in r.stderr, r.stderr
    assert not (tmp_path / "r").exists()


def test_a_warm_start_whose_trajectory_is_not_numbers_is_a_usage_error(tmp_path):
    """unseen24: a run folder whose trajectory.csv holds text, or a single row, started a run
    that failed with a raw TypeError / IndexError. Both `--warm-start` and `guess: {from:}`
    now say what is wrong with it, exit 2, nothing written."""
    run = _result("r").write(tmp_path / "run")
    csv = (run / "trajectory.csv").read_text().splitlines()
    (run / "trajectory.csv").write_text("\n".join([csv[0], csv[1].replace(csv[1].split(",")[1], "abc", 1)]
                                                 + csv[2:]) + "\n")
    r = _ocdsl("run", PROBLEM, "--out", tmp_path / "a", "--warm-start", run, cwd=tmp_path)
    assert r.returncode == 2 and "hold text, not numbers" in r.stderr and "Traceback" not in r.stderr, r.stderr
    (run / "trajectory.csv").write_text("\n".join(csv[:2]) + "\n")
    r = _ocdsl("run", PROBLEM, "--out", tmp_path / "b", "--warm-start", run, cwd=tmp_path)
    assert r.returncode == 2 and "fewer than two rows" in r.stderr, r.stderr
    text = PROBLEM.read_text().replace("  objective: minimize tf\n", f"  objective: minimize tf\n  guess: {{from: {run}}}\n")
    (tmp_path / "g.yaml").write_text(text)
    r = _ocdsl("check", tmp_path / "g.yaml", cwd=tmp_path)
    assert r.returncode == 2 and "g.yaml:" in r.stderr and "fewer than two rows" in r.stderr, r.stderr
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    (run / "result.json").write_text('{"mine": 1}')      # a user's own result.json
    r = _ocdsl("run", PROBLEM, "--out", tmp_path / "c", "--warm-start", run, cwd=tmp_path)
    assert r.returncode == 2 and "not one ocdsl wrote" in r.stderr and "__init__" not in r.stderr, r.stderr


def test_a_report_never_writes_through_a_linked_figures_folder(tmp_path):
    """unseen24 V1: with run/figures replaced by a link to the user's own folder, `ocdsl
    report run` replaced the user's states-0.svg and solver.pdf there (exit 0). Refused now,
    exit 2, the user's folder byte for byte as it was."""
    from ocdsl.report.build import make_report

    run = _result("r").write(tmp_path / "run")
    make_report(run, formats=("html",))
    assert (run / "figures").is_dir()
    mine = tmp_path / "paper_figs"
    mine.mkdir()
    (mine / "states-0.svg").write_text("my figure")
    (mine / "keep.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in mine.iterdir()}
    import shutil

    shutil.rmtree(run / "figures")
    (run / "figures").symlink_to(mine)
    r = _ocdsl("report", run)
    assert r.returncode == 2 and "symbolic link" in r.stderr, r.stderr
    assert {p.name: p.read_bytes() for p in mine.iterdir()} == before


def test_an_ipopt_output_file_stays_in_the_run_folder(tmp_path):
    """unseen24 V2: `solver: {options: {output_file: ipopt.log}}` emptied the user's ipopt.log
    (and ipopt.2.log) in the working folder, and the run folder kept no log. A relative name
    now goes into the run folder; an absolute one that exists is refused before any work; a
    stray ipopt.opt in the working folder is not read."""
    text = PROBLEM.read_text().split("expect:")[0] + "solver: {options: {output_file: ipopt.log, file_print_level: 5}}\n"
    (tmp_path / "p.yaml").write_text(text)
    for name in ("ipopt.log", "ipopt.2.log"):
        (tmp_path / name).write_text("my notes")
    (tmp_path / "ipopt.opt").write_text("max_iter 1\n")        # would stop every solve at once
    r = _ocdsl("run", tmp_path / "p.yaml", "--out", tmp_path / "run", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert (tmp_path / "ipopt.log").read_text() == "my notes" == (tmp_path / "ipopt.2.log").read_text()
    assert "Ipopt" in (tmp_path / "run" / "ipopt.log").read_text()
    assert json.loads((tmp_path / "run" / "result.json").read_text())["status"] == "optimal"
    absolute = text.replace("output_file: ipopt.log", f"output_file: {tmp_path / 'ipopt.log'}")
    (tmp_path / "q.yaml").write_text(absolute)
    r = _ocdsl("run", tmp_path / "q.yaml", "--out", tmp_path / "run2", "-q", cwd=tmp_path)
    assert r.returncode == 2 and "q.yaml:" in r.stderr and "exists" in r.stderr, r.stderr
    assert not (tmp_path / "run2").exists() and (tmp_path / "ipopt.log").read_text() == "my notes"


def test_an_output_folder_that_cannot_be_made_is_refused_before_the_solve(tmp_path):
    """unseen24: --out under a file, a name with no room for its temporary twin, a user's file
    named `runs`: each was a traceback after the solve, the result lost. Now one line, exit 2,
    before any work; nothing written."""
    (tmp_path / "afile").write_text("mine")
    for out in (tmp_path / "afile" / "sub", tmp_path / ("L" * 250)):
        r = _ocdsl("run", PROBLEM, "--out", out, "-q", cwd=tmp_path)
        assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.startswith("Error:"), r.stderr
    assert "is a file" in _ocdsl("run", PROBLEM, "--out", tmp_path / "afile" / "sub", cwd=tmp_path).stderr
    assert sorted(os.listdir(tmp_path)) == ["afile"] and (tmp_path / "afile").read_text() == "mine"
    (tmp_path / "runs").write_text("my runs")           # the default --out is runs/<stem>
    r = _ocdsl("run", PROBLEM, "-q", cwd=tmp_path)
    assert r.returncode == 2 and "is a file" in r.stderr and (tmp_path / "runs").read_text() == "my runs"


def test_a_problem_file_that_is_not_a_file_is_refused(tmp_path):
    """unseen24: `check /dev/zero` read until a MemoryError; a named pipe hung."""
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    for path in ("/dev/zero", fifo):
        r = _ocdsl("check", path, cwd=tmp_path)
        assert r.returncode == 2 and "not a regular file" in r.stderr, r.stderr


def test_a_report_that_cannot_be_written_is_one_line_naming_the_folder(tmp_path, monkeypatch):
    """unseen24 F39 / unseen25: `ocdsl report` into a read-only folder was a traceback, then a
    line naming ocdsl's temporary file; one line naming the folder now."""
    import errno

    from click.testing import CliRunner

    import ocdsl.report.build as build
    from ocdsl.cli import main

    run = _result("r").write(tmp_path / "run")

    def read_only(*a, **k):
        raise OSError(errno.EROFS, "Read-only file system", str(run / ".report.html.ocdsl-abc123"))

    monkeypatch.setattr(build, "make_report", read_only)
    r = CliRunner().invoke(main, ["report", str(run)])
    assert r.exit_code == 1 and f"could not be written in {run}: Read-only file system" in r.output, r.output
    assert "ocdsl-abc123" not in r.output and r.exception is None or isinstance(r.exception, SystemExit)


def test_a_resumed_study_refuses_a_users_point_folder_before_writing_anything(tmp_path):
    """unseen24 S08/S09: resuming a study whose point folder the user had replaced by a folder
    of their own solved that point, refused to install it, and rewrote study.json under a
    message that said nothing was changed. The point folders are checked first now."""
    from ocdsl.study.run import StudyError, run_points

    points = [{"id": f"p{k}", "parameters": {}} for k in range(2)]
    out = tmp_path / "st"
    run_points(PROBLEM, out, points, serial=True, quiet=True)
    import shutil

    shutil.rmtree(out / "points" / "p1")
    (out / "points" / "p1").mkdir()
    (out / "points" / "p1" / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    with pytest.raises(StudyError, match="point p1: .*notes.txt"):
        run_points(PROBLEM, out, points, serial=True, quiet=True, resume=True)
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    assert (out / "points" / "p1" / "notes.txt").read_text() == "mine"


def test_a_report_of_a_folder_that_is_not_a_run_is_a_usage_error(tmp_path):
    """unseen33 F12: `ocdsl report` of a missing folder exited 2, of a folder that is not a run
    folder 1: both are the caller's input, one line, exit 2."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "a.txt").write_text("x")
    r = _ocdsl("report", mine, cwd=tmp_path)
    assert r.returncode == 2 and "neither a run folder nor a study folder" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and sorted(p.name for p in mine.iterdir()) == ["a.txt"]


def test_a_report_the_user_edited_is_theirs(tmp_path):
    """unseen40 F2: notes appended to report.html were lost: `ocdsl report RUN` rewrote the
    file, and `ocdsl run --out RUN` (no --report) deleted it, where an edited trajectory.csv
    is refused. The report's and figures' digests are recorded when ocdsl writes them."""
    from ocdsl.report.build import ReportError, make_report

    run = _result("r").write(tmp_path / "run")
    make_report(run, formats=("html",))
    make_report(run, formats=("html",))                  # ocdsl's own report: replaced
    assert "report.html" in run_folder.read_marker(run)["digests"]
    assert any(n.startswith("figures/") for n in run_folder.read_marker(run)["digests"])
    edited = (run / "report.html").read_text() + "<p>my notes</p>"
    (run / "report.html").write_text(edited)
    with pytest.raises(ReportError, match="report.html was changed since ocdsl wrote it"):
        make_report(run, formats=("html",))
    with pytest.raises(run_folder.FolderError, match=r"report.html \(changed since ocdsl wrote it\)"):
        _result("again").write(run)
    assert (run / "report.html").read_text() == edited and _holds(run, "r")
