"""Figures from the run folder's declared frame (seed 1: the Earth-Moon synodic frame with
the Earth, the Moon and L1 marked, equal scales) and the objective typeset as the user wrote
it (an integral, not its internal name)."""
from __future__ import annotations

import re

import numpy as np
import pytest

from ocdsl.models.cr3bp import l1_distance
from ocdsl.report import figures as F
from ocdsl.report.build import build_run_html
from ocdsl.result import PhaseTrajectory, Result
from ocdsl.spec.compile import load

MU = 0.0121506683


def test_l1_solves_the_collinear_quintic():
    g = l1_distance(MU)
    x = 1 - MU - g                 # barycentric x of L1: the net force of the rotating frame is zero there
    force = x - (1 - MU) * (x + MU) / abs(x + MU) ** 3 - MU * (x - 1 + MU) / abs(x - 1 + MU) ** 3
    assert abs(force) < 1e-12
    assert x == pytest.approx(0.836915, abs=1e-6)       # the textbook Earth-Moon L1


@pytest.mark.parametrize("stem, coords, earth_x", [("seed1_2N_optimal", "cartesian", -MU),
                                                   ("seed1_2N_paper", "cylindrical", 0.0)])
def test_seed1_files_declare_the_synodic_frame(stem, coords, earth_x):
    desc = load(f"configs/{stem}.yaml").problem.description
    frame = desc["frame"]
    assert frame["coordinates"] == coords
    bodies = {b["name"]: b["at"] for b in frame["bodies"]}
    assert bodies["Earth"][0] == pytest.approx(earth_x) and bodies["Moon"][0] == pytest.approx(earth_x + 1)
    (l1,) = frame["points"]
    assert l1["name"] == "L1" and l1["at"][0] == pytest.approx(earth_x + 1 - l1_distance(MU))


def _polar_run() -> Result:
    s = np.linspace(0.0, 1.0, 400)
    r, th, z = 0.02 + 0.8 * s, 2 * np.pi * 5 * s, -0.02 * s**4
    desc = load("configs/seed1_2N_paper.yaml").problem.description
    return Result(name="spiral", status="optimal", problem=desc,
                  phases=[PhaseTrajectory("main", s, {"r": r, "theta": th, "z": z})])


def test_frame_figures_mark_the_bodies_with_equal_scales():
    res = _polar_run()
    assert F.fig_positions(res) == []          # drawn once, in its frame
    figs = F.fig_frame(res)
    assert [f.key for f in figs] == ["frame-3d", "frame-projections"]
    ax3 = figs[0].figure.axes[0]
    spans = [hi - lo for lo, hi in (ax3.get_xlim(), ax3.get_ylim(), ax3.get_zlim())]
    box = ax3.get_box_aspect()
    assert np.allclose(box / box[0], np.array(spans) / spans[0], rtol=1e-6)   # z not stretched
    names = {t.get_text().strip() for t in ax3.texts}
    assert {"Earth", "Moon"} <= names
    xy, xz = figs[1].figure.axes[:2]
    for ax in (xy, xz):
        assert ax.get_aspect() == 1.0
    line = xy.get_lines()[0]                  # (r, theta) drawn as x = r cos(theta), y = r sin(theta)
    p = res.phases[0].states
    assert np.allclose(line.get_xdata(), p["r"] * np.cos(p["theta"]))
    assert np.allclose(line.get_ydata(), p["r"] * np.sin(p["theta"]))
    assert any(a.get_text() == "L1" for a in xy.texts)
    assert "Earth-Moon synodic frame" in figs[0].caption and "L1" in figs[0].caption


def test_report_of_a_frame_run_has_the_frame_figures(tmp_path):
    html = build_run_html(_polar_run().write(tmp_path / "run"))
    caps = re.findall(r"<figcaption><b>Figure \d+\.</b> (.*?)</figcaption>", html, re.S)
    assert sum("Earth-Moon synodic frame" in c for c in caps) == 2


@pytest.mark.parametrize("stem", ["bryson_denham", "moon_landing"])
def test_objective_typesets_the_integral_not_its_internal_name(stem):
    obj = load(f"configs/{stem}.yaml").problem.description["objective"]
    assert r"\int" in obj["latex"] and "integral" not in obj["latex"]
    assert "t_{0}" in obj["latex"] and "t_{f}" in obj["latex"]
