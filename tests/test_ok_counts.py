"""What a study and a Pareto set call ok is what their points' own runs call ok (unseen9 F2,
F3): a sweep printed "6 ok, 0 failed" and exited 0 while 5 of its points failed their
expect; a Pareto set exited 0 with 7 of its 8 points not verified."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "ocdsl.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


@pytest.mark.ipopt
def test_a_sweep_point_that_fails_its_expect_is_not_ok(tmp_path):
    """J = 12 D^2 / T^3 (Bryson & Ho): the file's expect (12) holds at D = 1, T = 1 only."""
    run = _cli("study", DATA / "sweep_expect_at_nominal_only.yaml", "--out", tmp_path / "s", "--serial", "-q",
               cwd=tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    data = json.loads((tmp_path / "s" / "study.json").read_text())
    assert data["counts"]["ok"] == 1 and data["counts"]["failed"] == 5
    rows = {(r["D"], r["T"]): r for r in data["points"]}
    for (D, T), r in rows.items():
        assert r["status"] == "optimal" and r["objective"] == pytest.approx(12 * D**2 / T**3, rel=1e-8)
        assert r["ok"] is ((D, T) == (1.0, 1.0))
        # unseen12 F11: the message says why a solved point is not ok (it said 'mesh converged')
        if not r["ok"]:
            assert r["message"].startswith("expect objective: "), r["message"]
            assert "vs 12 FAIL" in r["message"]


@pytest.mark.ipopt
def test_a_pareto_set_with_unverified_points_exits_1_and_names_them(tmp_path):
    """The rocket car's bang-off-bang points on a uniform 30 x 4 mesh: the switches fall inside
    segments, so the points fly off their rows and are not verified (their fuel is right to
    4e-4 of T - sqrt(T^2 - 4), Athans & Falb); the set says so and exits 1."""
    run = _cli("run", DATA / "pareto_rocket_car_unverified.yaml", "--out", tmp_path / "p", cwd=tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    summary = json.loads((tmp_path / "p" / "result.json").read_text())
    v = summary["verification"]
    points = sorted((tmp_path / "p" / "points").iterdir())
    own = {p.name: json.loads((p / "result.json").read_text())["verification"]["status"] for p in points}
    bad = sorted(k for k, s in own.items() if s != "verified")
    assert bad and v["status"] == "failed" and sorted(v["failed_points"]) == bad and not summary["ok"]
    assert f"{len(own) - len(bad)} of {len(own)} points verified" in run.stdout
    for p in points:
        data = json.loads((p / "result.json").read_text())
        T = data["extra"]["objectives"]["time"]
        assert data["extra"]["objectives"]["fuel"] == pytest.approx(T - (T * T - 4) ** 0.5, rel=1e-3)
