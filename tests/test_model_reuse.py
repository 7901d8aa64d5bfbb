"""Model reuse across study points (ocdsl/solve/reuse.py): one Pyomo model with the swept
constants as mutable Params, re-solved per point, gives the optima of fresh builds; a point
whose structure differs gets a fresh build. Not timed (reports/bench/levers.md has the CPU)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from ocdsl.api import load
from ocdsl.study.run import run_study

ROOT = Path(__file__).resolve().parents[1]


def _moon(tmp_path: Path, extra_params: str = "", bound: str = "0 <= T <= 1.227", bisection: bool = False) -> Path:
    """The moon-landing study on 12 segments, where the bisection check (m = 1 while coasting
    counts as an arc) finds J 1.3e-5 off: off unless ``bisection``, as it is not what reuse changes."""
    text = (ROOT / "configs" / "study_moon_landing_sweep.yaml").read_text()
    if not bisection:
        text += "verify: {bisection_check: false}\n"
    text = re.sub(r"segments: \d+", "segments: 12", text)
    text = text.replace("{g: 1.0, E: 2.349}", "{g: 1.0, E: 2.349" + extra_params + "}")
    text = text.replace("0 <= T <= 1.227", bound)
    text = text.replace("E: {start: 2.2, stop: 2.6, num: 32}", "E: [2.2, 2.35, 2.5, 2.6]")
    p = tmp_path / "moon.yaml"
    p.write_text(text)
    return p


def _same(a, b, tol=1e-8):
    assert a.status == b.status == "optimal"
    assert abs(a.objective - b.objective) <= tol * max(1.0, abs(b.objective))
    assert abs(a.tf - b.tf) <= tol * max(1.0, abs(b.tf))
    for pa, pb in zip(a.phases, b.phases):
        ca, cb = pa.columns(), pb.columns()
        assert set(ca) == set(cb)
        for k in ("t", "h", "v", "m", "T"):
            assert np.array_equal(np.isnan(ca[k]), np.isnan(cb[k])), k   # rows without a control
            assert np.nanmax(np.abs(ca[k] - cb[k])) <= 1e-6, k


def test_reused_model_same_optima_as_fresh_builds(tmp_path):
    f = _moon(tmp_path)
    fresh, reused = load(f), load(f)
    hows = []
    points = [{"E": 2.2}, {"E": 2.35}, {"E": 2.5}, {"E": 2.6}, {"E": 2.35, "g": 0.9}, {"E": 2.5, "g": 1.1}]
    for p in points:
        a = fresh.solve(parameters=p)
        b = reused.solve(parameters=p, reuse=True)
        _same(b, a)
        assert b.iterations == a.iterations          # same start, same NLP: same iterates
        assert b.parameters["E"] == p["E"]
        hows.append(b.extra["model_reuse"])
        assert "model_reuse" not in a.extra
    # one model for the points that sweep E, another for those that sweep (E, g)
    assert hows == ["built", "reused", "reused", "reused", "built", "reused"]
    assert reused._reuse.counts == {"built": 2, "reused": 4, "fresh": 0}


def test_reused_points_get_the_bisection_check_of_fresh_builds(tmp_path):
    f = _moon(tmp_path, bisection=True)
    fresh, reused = load(f), load(f)
    levels = []
    for p in ({"E": 2.2}, {"E": 2.35}, {"E": 2.349}):
        a = fresh.solve(parameters=p)
        b = reused.solve(parameters=p, reuse=True)
        assert a.status == b.status and b.extra["bisection"]["agrees"] is a.extra["bisection"]["agrees"]
        got = [lv["objective"] for lv in b.extra["bisection"]["levels"]]
        assert got == pytest.approx([lv["objective"] for lv in a.extra["bisection"]["levels"]], rel=1e-8)
        levels.append(len(got))
    # J moves 7e-7 at E = 2.2, 7.6e-6 at 2.35 and 7.7e-6 at 2.349: there the second bisection
    # (1.1e-6, 3.0e-7) measures the convergence, and both paths make it
    assert levels == [1, 2, 2], levels


def test_reused_model_with_warm_start_and_seed(tmp_path):
    f = _moon(tmp_path)
    fresh, reused = load(f), load(f)
    base = fresh.solve(tmp_path / "base", parameters={"E": 2.3})
    for v in (2.35, 2.4):
        a = fresh.solve(parameters={"E": v}, warm_start=tmp_path / "base")
        b = reused.solve(parameters={"E": v}, warm_start=tmp_path / "base", reuse=True)
        _same(b, a)
        assert b.iterations == a.iterations
    assert base.status == "optimal"


def test_structure_that_differs_falls_back_to_a_fresh_build(tmp_path):
    # Tmax sets a variable bound and h0 a boundary value: the compiler folds both into
    # numbers, so a model with them as Params would not be the same NLP; such points are
    # built afresh (and still correct), the E points of the same handle keep their model
    f = _moon(tmp_path, ", Tmax: 1.227, h0: 1.0", "0 <= T <= Tmax")
    f.write_text(f.read_text().replace("h(t0) == 1", "h(t0) == h0"))
    fresh, reused = load(f), load(f)
    points = [({"E": 2.2}, "built"), ({"Tmax": 1.2}, "bounds"), ({"E": 2.4}, "reused"),
              ({"h0": 1.05}, "boundary constraints"), ({"E": 2.5, "h0": 1.0}, "boundary constraints"),
              ({"E": 2.6}, "reused")]
    for p, how in points:
        a = fresh.solve(parameters=p)
        b = reused.solve(parameters=p, reuse=True)
        _same(b, a)
        assert b.iterations == a.iterations
        if how in ("built", "reused"):
            assert b.extra["model_reuse"] == how
        else:
            assert "model_reuse" not in b.extra
            assert how in reused._reuse.last_fresh
    assert reused._reuse.counts == {"built": 1, "reused": 2, "fresh": 3}


def test_study_reuse_model_on_and_off(tmp_path):
    f = _moon(tmp_path)
    on = run_study(f, tmp_path / "on", serial=True, quiet=True)
    text = f.read_text().replace("study:\n", "study:\n  reuse_model: false\n")
    g = tmp_path / "off.yaml"
    g.write_text(text)
    off = run_study(g, tmp_path / "off", serial=True, quiet=True)
    rows_on = {r["id"]: r for r in on.rows}
    for r in off.rows:
        assert r["status"] == rows_on[r["id"]]["status"] == "optimal"
        assert abs(r["objective"] - rows_on[r["id"]]["objective"]) <= 1e-8
    hows = [json.loads((tmp_path / "on" / "points" / r["id"] / "result.json").read_text())
            .get("extra", {}).get("model_reuse") for r in on.rows]
    assert hows[0] == "built" and set(hows[1:]) == {"reused"}
    hows_off = [json.loads((tmp_path / "off" / "points" / r["id"] / "result.json").read_text())
                .get("extra", {}).get("model_reuse") for r in off.rows]
    assert hows_off == [None] * len(hows_off)
