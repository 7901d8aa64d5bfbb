"""Seed 2: the problem files of configs/ solved by flat B-splines (as written) and by the
core's pseudospectral transcription in the full state space (LGR, 10 segments x 5 points,
method replaced on the same file): both verified, the refined flat optimum agrees with the
full-state one to 2e-6 on every row of Tables 2 and 3 (the paper's collocated 15/15 level is
not verified), the flat NLP is smaller, and the flat run's expect checks (0.1 kg, 0.5 %)
pass. Slow (a minute or more per table on a busy machine); one row of each table runs in
tests/test_flat_problem.py."""
import math

import pytest
from scipy.integrate import solve_ivp

from conftest import CONFIGS
from ocdsl.models.lunar_lander import TABLE2, TABLE3, constants, mass_flow
from ocdsl.transcribe.flat_bspline_compare import compare

C = constants("km")


def _check(c, tf_key=None, expect_passes=True):
    """Both converged and verified; the refined flat optimum is the full-state one (t_f and
    final mass to 2e-6, final thrust angles to 0.05 deg); the paper's collocated 15/15 level
    is not verified. A verified flat result with another value would fail here."""
    f, p = c["flat"], c["pseudospectral"]
    assert f["status"] in ("optimal", "acceptable") and p["status"] in ("optimal", "acceptable")
    assert f["verification"] == p["verification"] == "verified"
    assert abs(f["objective"] - p["objective"]) <= 2e-6 * abs(p["objective"])
    assert abs(f["tf"] - p["tf"]) <= 2e-6 * abs(p["tf"])
    paper = f["refinement"][0]
    assert (paper["control_points"], paper["residual"], paper["verification"]) == (15, "collocation", "failed")
    for ph in (ph for ph in p["result"].phases if "beta" in ph.controls):
        fb, pb = f["result"].phase(ph.name).controls["beta"][-1], ph.controls["beta"][-1]
        # the same angle on either export's branch (LGR's strategy-1 beta ends at -238 deg)
        d = (fb - pb + math.pi) % (2 * math.pi) - math.pi
        assert abs(math.degrees(d)) < 0.05, (ph.name, math.degrees(fb), math.degrees(pb))
    assert f["variables"] < p["variables"] and f["constraints"] < p["constraints"]
    if expect_passes:
        assert all(ok for _, ok in f["expect"].values()), f["expect"]


@pytest.mark.slow
@pytest.mark.ipopt
@pytest.mark.parametrize("h", sorted(TABLE2, reverse=True))
def test_table2_flat_vs_pseudospectral(h):
    from ocdsl.study.spec import load_study

    if h == 100:
        c = compare(CONFIGS / "seed2_strategy1.yaml")
    else:
        pt = next(p for p in load_study(CONFIGS / "seed2_strategy2.yaml").points if p.parameters["h_i"] == h)
        c = compare(CONFIGS / "seed2_strategy2.yaml", pt.parameters)
        assert all(ok for _, ok in c["pseudospectral"]["expect"].values())
    _check(c)
    paper = c["flat"]["refinement"][0]
    assert paper["variables"] == 31 and paper["constraints"] == 22


@pytest.mark.slow
@pytest.mark.ipopt
@pytest.mark.parametrize("h", sorted(TABLE3, reverse=True))
def test_table3_flat_vs_pseudospectral_and_lands(h):
    """Both transcriptions agree; the flat run's descent, integrated independently (SciPy,
    full upward thrust from its v12 and mass), reaches -5 m/s at the ground at its
    landing time: the reference values of the file's study are a descent that lands,
    where the printed rows (but 2 km) cannot (tests/test_lander.py)."""
    from ocdsl.study.spec import load_study

    pt = next(p for p in load_study(CONFIGS / "seed2_strategy3.yaml").points if p.parameters["h_v"] == h)
    c = compare(CONFIGS / "seed2_strategy3.yaml", pt.parameters, tf_key="descent")
    # the file expects the printed rows, which cannot land (configs/seed2_strategy3.yaml): the
    # optimum differs from them in mass by +0.97, +0.58, +0.40 and -0.24 kg at 5, 4, 3 and 1 km,
    # and only the 2 km row is within the expect's 0.1 kg
    _check(c, expect_passes=h == 2)
    off, ok = c["flat"]["expect"]["descent.m(tf) - m_ref"]
    assert ok == (h == 2) and off == pytest.approx({5: 0.97, 4: 0.58, 3: 0.40, 2: 0.0, 1: -0.24}[h], abs=0.06)
    res = c["flat"]["result"]
    de = res.phase("descent")
    v12, m12, td = de.states["v"][0], de.states["m"][0], de.time[-1] - de.time[0]
    f = lambda t, y: [y[1], -C["mu"] / y[0] ** 2 + C["T"] / (1000 * y[2]), -mass_flow()]  # noqa: E731
    ev = lambda t, y: y[1] + 0.005  # noqa: E731
    ev.terminal = True
    s = solve_ivp(f, (0, 3 * td), [C["R"] + h, v12, m12], events=ev, rtol=1e-11, atol=1e-12)
    assert abs(s.y_events[0][0][0] - C["R"]) < 1e-6
    assert s.t_events[0][0] == pytest.approx(td, rel=1e-6)
