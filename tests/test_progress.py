"""Progress of long stages (ocdsl/progress.py): stage, count, elapsed and ETA; plain lines
without a terminal (what a log or CI sees), one rewritten line on a terminal."""
import io

import pytest

from ocdsl.progress import Stage, format_seconds


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_plain_lines_without_a_terminal_with_elapsed_and_eta():
    out, clock = io.StringIO(), Clock()
    bar = Stage("swarm (PSO)", 10, stream=out, interval=5.0, clock=clock)
    for k in range(1, 11):
        clock.t = 2.0 * k
        bar.update(k, f"best J {100 - k}")
    bar.close("best J 90")
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue()
    # one line at most every 5 s of the 20 s, plus the final one
    assert len(lines) == 5
    assert lines[0] == "swarm (PSO)  1/10  elapsed 2.0 s  ETA 18 s  best J 99"
    assert lines[-1] == "swarm (PSO)  10/10  done in 20 s  best J 90"


def test_an_upper_bound_and_an_unknown_total_say_so():
    out, clock = io.StringIO(), Clock()
    bar = Stage("mesh refinement", 10, stream=out, interval=0.0, at_most=True, clock=clock)
    clock.t = 30.0
    bar.update(2)
    assert out.getvalue().splitlines()[-1] == "mesh refinement  2/<=10  elapsed 30 s  ETA <= 2 min 00 s"
    out2 = io.StringIO()
    Stage("continuation", None, stream=out2, interval=0.0, clock=clock).update(3, "tf 11.2")
    assert "ETA" not in out2.getvalue() and "continuation  3  elapsed" in out2.getvalue()


def test_a_terminal_gets_one_rewritten_line_with_a_bar():
    out, clock = Tty(), Clock()
    bar = Stage("study", 4, stream=out, clock=clock)
    for k in range(1, 5):
        clock.t = float(k)
        bar.update(k)
    bar.close()
    text = out.getvalue()
    assert text.count("\n") == 1 and text.count("\r") == 5 and "[#####" in text
    assert text.rstrip().endswith("study  4/4  done in 4.0 s")


def test_disabled_writes_nothing():
    out = io.StringIO()
    with Stage("x", 3, stream=out, enabled=False) as bar:
        bar.update(1)
    assert out.getvalue() == ""


def test_format_seconds():
    assert [format_seconds(s) for s in (3.21, 42, 125, 7300)] == ["3.2 s", "42 s", "2 min 05 s", "2 h 01 min"]


@pytest.mark.ipopt
def test_mesh_refinement_prints_plain_progress_lines_in_a_log(tmp_path, capfd):
    from conftest import ROOT
    from ocdsl.api import run_file

    run_file(ROOT / "configs" / "mesh_double_integrator.yaml", tmp_path / "run", quiet=False)
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("mesh refinement")]
    assert lines and "\r" not in err
    assert "1/<=" in lines[0] and "elapsed" in lines[0] and "ETA <=" in lines[0] and "mesh  1:" in lines[0]
    assert "done in" in lines[-1]
