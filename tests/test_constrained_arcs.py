"""A single solve whose state bound binds inside the phase is checked on the mesh with every
segment bisected (unseen5): on 3 LG segments the speed-limited transfer is feasible, verified
and passes the certificate at J = 12.24, while the problem's optimum is 12.1956; it said
``optimal`` and exited 0."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ocdsl.api import run_file
from ocdsl.solve.arcs import AGREEMENT_SHARE, Bisection, Level
from ocdsl.transcribe.mesh import Mesh
from ocdsl.transcribe.nodes import scheme

SPEED_LIMIT = """name: speed limit
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: 1}
  constraints: [LIMIT, x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0]
  objective: minimize integral(u**2)
method: {transcription: METHOD}
VERIFY
"""


def exact(vmax: float) -> float:
    """8 vmax^2 / (3 t1), t1 = 1.5 (1 - 1/vmax): the speed-limited minimum energy."""
    return 8 * vmax ** 2 / (3 * 1.5 * (1 - 1 / vmax))


def _run(tmp_path, limit: str, method: str = "LG, segments: 3, degree: 3", verify: str = ""):
    p = tmp_path / "s.yaml"
    p.write_text(SPEED_LIMIT.replace("LIMIT", limit).replace("METHOD", method).replace("VERIFY", verify))
    res = run_file(p, None)
    return res, [n for n in res.extra.get("notes", []) if "fixed mesh" in n]


def test_a_fixed_mesh_missing_a_state_arcs_junctions_is_not_called_optimal(tmp_path):
    res, notes = _run(tmp_path, "v <= 1.4")
    assert res.objective - exact(1.4) > 1e-3 * exact(1.4)          # the mesh's optimum, not the problem's
    assert res.verification["status"] == "verified"                # feasible: the verification cannot tell
    assert res.status == "mesh_not_converged" and not res.ok
    check = res.extra["bisection"]
    assert check["agrees"] is False and check["levels"][0]["objective"] < res.objective
    assert "`v <= 1.4`" in res.message and "bisected" in res.message and "mesh:" in res.message
    assert notes == []


def test_a_junction_pinned_to_a_kept_breakpoint_still_fails_the_check(tmp_path):
    # 7 LG segments of degree 3: the arc starts at the breakpoint 2/7, which the bisected mesh
    # keeps; J's error only falls from 1.25e-4 to 9.2e-5, a difference of 3.3e-5
    res, _ = _run(tmp_path, "v <= 1.25", "LG, segments: 7, degree: 3")
    assert res.objective / exact(1.25) - 1 > 1e-5
    assert res.status == "mesh_not_converged", res.extra.get("bisection")


def test_the_check_off_keeps_the_note_and_the_solvers_status(tmp_path):
    res, notes = _run(tmp_path, "v <= 1.4", verify="verify: {bisection_check: false}")
    assert res.status == "optimal" and "bisection" not in res.extra
    assert len(notes) == 1 and "bisection check is off" in notes[0] and "`v <= 1.4`" in notes[0]


def test_a_junction_on_a_breakpoint_passes_the_check(tmp_path):
    # v <= 1.4: junctions at t1 = 1.5 (1 - 1/1.4) = 3/7 and 4/7, breakpoints of 7 segments
    res, notes = _run(tmp_path, "v <= 1.4", "LGR, segments: 7, degree: 4")
    assert abs(res.objective / exact(1.4) - 1) < 1e-7
    assert res.status == "optimal" and res.ok, res.message
    check = res.extra["bisection"]
    assert check["agrees"] is True and check["relative_differences"][0] < AGREEMENT_SHARE * 1e-5
    assert len(notes) == 1 and "within a quarter of the verification's tolerance" in notes[0]


def test_a_bound_that_never_binds_and_a_state_leaving_its_bound_from_rest_are_not_named(tmp_path):
    # neither is named as binding; J is checked on the bisected mesh all the same, as no flight
    # judged it (the minimum principle's control predicts no gain: not flown, unseen53 F1)
    for limit in ("v <= 5",                        # the unconstrained peak speed is 1.5
                  "x >= 0"):                       # x(t0) = 0 on the bound, then leaving it
        res, notes = _run(tmp_path, limit)
        assert res.status == "optimal" and res.extra["bisection"]["agrees"] is True
        assert len(notes) == 1 and "binds" not in notes[0] and "not flown" in notes[0], notes


def _check(*objectives, floor=1e-7):
    levels = tuple(Level(j, "optimal" if j is not None else "infeasible", 10, 3) for j in objectives[1:])
    return Bisection(objectives[0], levels, 1e-5, floor)


@pytest.mark.parametrize("fine, agrees", [(1.0 + 0.24e-5, True), (1.0 + 1.1e-5, False), (None, None),
                                          (1.0 + 5e-8, True)])
def test_one_bisection_decides_below_a_quarter_of_the_tolerance_and_above_it(fine, agrees):
    check = _check(1.0, fine)
    assert check.agrees is agrees and not check.needs_second
    tiny = _check(1e-9, 3e-9)
    assert tiny.agrees is True            # 2e-9 apart: within Ipopt's accuracy, whatever the ratio
    assert "relative difference 6.7e-01" in tiny.describe() and "accuracy" in tiny.describe()
    # the printed difference is the measured one, not the judged 0 (unseen7: "0.0e+00" for 5e-8)
    close = _check(1.0, 1.0 + 5e-8)
    assert close.agrees is True and "relative difference 5.0e-08" in close.describe()
    assert close.record()["relative_differences"] == [pytest.approx(5e-8, rel=1e-6)]


def test_between_the_two_a_second_bisection_measures_the_convergence():
    # Goddard's uniform mesh: differences 3.9e-6 then 2.1e-6, error 8.1e-6 against the published J
    first = _check(1.012584469, 1.01258057)
    assert first.needs_second and first.agrees is None
    second = _check(1.012584469, 1.01258057, 1.012578475)
    assert not second.needs_second and second.agrees is True
    assert second.error == pytest.approx(8.3e-6, rel=0.05)
    # differences that do not shrink: not converging, whatever their size
    assert _check(1.0, 1.0 + 5e-6, 1.0 + 1e-5).agrees is False
    # shrinking too slowly: 5e-6 then 4e-6 put the error at 2.5e-5
    assert _check(1.0, 1.0 + 5e-6, 1.0 + 9e-6).agrees is False
    assert _check(1.0, 1.0 + 5e-6, None).agrees is None


def test_bisected_mesh_halves_every_segment_and_keeps_its_polynomials():
    mesh = Mesh.uniform("LGR", [0.0, 0.3, 1.0], [3, 5])
    fine = mesh.bisected()
    assert np.allclose(fine.breakpoints, [0, 0.15, 0.3, 0.65, 1.0]) and fine.degrees == (3, 3, 5, 5)
    assert fine.scheme_name == "LGR" and scheme("LGR", 3).support.size == fine.scheme(0).support.size


def test_a_switch_held_on_a_wrong_breakpoint_of_a_fixed_mesh_is_not_called_optimal(tmp_path):
    """unseen14 (a false claim): the switch at t = 2.15 held on the breakpoint 2.10 of a fixed
    LGR 3 x 5 mesh, J 1.2e-3 below e^2.15: optimal, verified, certificate pass, exit 0. The
    breakpoint's envelope gradient and the switching function's sign change predict a gain
    above the tolerance; with the breakpoint free the solve confirms it: mesh_not_converged.
    The minimum-time double integrator's switch, exactly on its breakpoint, stays optimal."""
    import math
    from pathlib import Path

    res = run_file(Path(__file__).parent / "data" / "invest_consume_fixed.yaml", None)
    assert res.status == "mesh_not_converged" and not res.ok, res.message
    pinned = res.extra["pinned_switches"]
    assert abs(pinned["objective_with_switches_free"] - math.exp(2.15)) < 1e-6 * math.exp(2.15)
    assert "exactly on a breakpoint" in res.message and "t = 2.1" in res.message
    di = run_file(Path(__file__).parents[1] / "configs" / "double_integrator.yaml", None)
    assert di.status == "optimal" and "pinned_switches" not in di.extra


def test_a_flight_that_ran_and_judged_nothing_gives_its_own_reason():
    """unseen48 F4: Rayleigh on LGL 10 x 5, one phase, no path constraint, H quadratic in u:
    the bisection refuted J (29.7279 against 29.7496) and the message listed the cases the
    flight is "not made for", none of which applies; the flight had run and judged nothing.
    Its own reason is given now."""
    from pathlib import Path

    res = run_file(Path(__file__).parent / "data" / "rayleigh_free_lgl_10x5.yaml", None)
    assert res.status == "mesh_not_converged" and not res.ok
    assert "it is not made for several phases" not in res.message
    assert "the flight of the minimum principle's control judged no J on this fixed mesh (H's minimiser" in res.message


NONAUTONOMOUS_LQ = Path(__file__).parent / "data" / "nonautonomous_lq.yaml"


@pytest.mark.parametrize("method, ok", [("LG, segments: 3, degree: 2", False), ("LG, segments: 3, degree: 4", True)])
def test_a_flight_not_flown_judges_nothing(tmp_path, method, ok):
    """unseen53 F1: x' = u, x(1) free, min int u^2/2 + t x (J* = -1/15, x cubic): LG 3 x 2
    gave J = -0.0666581 (1.3e-4 off, lambda(tf) 9.3e-3 for 0), optimal, verified, certificate
    pass, exit 0: H's minimiser, from the mesh's own costates, predicted a gain of 2.1e-7,
    "not flown", and that counted as a judgement, so no bisection ran. Now it is bisected:
    mesh_not_converged; degree 4 holds the cubic and stays optimal."""
    p = tmp_path / "lq.yaml"
    p.write_text(NONAUTONOMOUS_LQ.read_text().replace("LG, segments: 3, degree: 2", method))
    res = run_file(p, None)
    assert res.extra["bisection"] is not None
    if ok:
        assert res.status == "optimal" and res.objective == pytest.approx(-1 / 15, rel=1e-9)
    else:
        assert abs(res.objective + 1 / 15) > 1e-4 / 15
        assert res.status == "mesh_not_converged" and not res.ok
        assert "(H's minimiser gains" in res.message and "not flown)" in res.message


def test_at_a_bound_is_within_a_share_of_the_quantitys_range():
    """unseen59 F5: a state about 1e7 travelling 0.11 to x <= 1e7 + 1/9 was "at its bound at 17
    nodes" up to 0.087 below it (1e-7 x (1 + |b|) is 1 there), and the bound printed `x <= 1e+07`."""
    from ocdsl.solve.arcs import _bound_text
    from ocdsl.solve.mesh.segments import activity

    b = 1e7 + 1 / 9
    x = 1e7 + np.array([0.0, 0.0973, 0.1111, 0.11111111, 0.1112, 0.0973, 0.0])
    assert activity(x, -np.inf, b, 1e-7).tolist() == [1, 1, 1, 1, 1, 1, 1]       # by |b| alone
    assert activity(x, -np.inf, b, 1e-7, span=float(np.ptp(x))).tolist() == [0, 0, 1, 1, 1, 0, 0]
    # a quantity of order 1: as before
    assert activity(np.array([0.0, 1 - 1e-8, 0.5]), 0.0, 1.0, 1e-7, span=1.0).tolist() == [-1, 1, 0]
    assert _bound_text("x", -np.inf, b) == "x <= 10000000.111111112" and _bound_text("x", 0.0, 1.0) == "0 <= x <= 1"


def test_a_spurious_kkt_point_is_not_blamed_on_the_mesh_alone():
    """unseen61 F4: Bryson's orbit raising in SI units stopped at a point with the thrust angle
    on its -pi bound, 1.65 % short; the bisection moved J elsewhere again and the message said
    only that the mesh misses the arcs' junctions. The certificate finds the control neither H's
    minimiser nor stationary: the message says refining does not cure that."""
    from pathlib import Path

    from ocdsl.api import run_file

    res = run_file(Path(__file__).parent / "data" / "orbit_raising_si_spurious.yaml", None)
    assert res.status == "mesh_not_converged" and not res.ok
    assert "no extremal of the problem" in res.message and "refining does not cure" in res.message
