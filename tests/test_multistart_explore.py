"""``method: {starts: N}`` on the pseudospectral back end explores (unseen5 finding 2).

Start 0 is the file's guess, exactly the single start; start i >= 1 moves every state and
control by a smooth seeded random curve (clipped into the bounds, boundary values fixed by
equalities kept) and draws the free times around their guess (transcribe/guess.py
``start_guesses``). Before, the starts only redrew the controls as white noise in their
bounds, with the states on the straight line: on the cart-pole swing-up all 8 starts ended
in the local minimum 58.8077, while 57.9447803069 is the best known (Kelly 2017; two
Pontryagin extremals, checked with SciPy in unseen5/refs).
"""
from __future__ import annotations

import numpy as np
import pytest

import ocdsl
from ocdsl.api import compile_file
from ocdsl.transcribe.guess import make_guess, start_guesses

CARTPOLE = """name: cart-pole swing-up (Kelly 2017)
model:
  states: [q1, q2, dq1, dq2]
  controls: [u]
  parameters: {m1: 1.0, m2: 0.3, l: 0.5, g: 9.81}
  dynamics:
    q1: dq1
    q2: dq2
    dq1: (l*m2*sin(q2)*dq2**2 + u + m2*g*cos(q2)*sin(q2))/(m1 + m2*(1 - cos(q2)**2))
    dq2: -(l*m2*cos(q2)*sin(q2)*dq2**2 + u*cos(q2) + (m1 + m2)*g*sin(q2))/(l*m1 + l*m2*(1 - cos(q2)**2))
problem:
  time: {t0: 0, tf: 2}
  constraints:
    - -20 <= u <= 20
    - -2 <= q1 <= 2
    - q1(t0) == 0
    - q2(t0) == 0
    - dq1(t0) == 0
    - dq2(t0) == 0
    - q1(tf) == 1
    - q2(tf) == pi
    - dq1(tf) == 0
    - dq2(tf) == 0
  objective: minimize integral(u**2)
method: METHOD
"""
BEST, OTHER = 57.9447803069, 58.8076674582     # the two local minima (mesh-converged)


def _cartpole(tmp_path, method: str, name: str = "cartpole.yaml"):
    p = tmp_path / name
    p.write_text(CARTPOLE.replace("METHOD", method))
    return p


@pytest.mark.ipopt
def test_cartpole_starts_leave_the_straight_line_basin(tmp_path):
    """Mesh 10 x 5 as unseen5's file: start 0 is the single start bit for bit (58.81, the
    straight-line guess's basin); the perturbed starts reach the lower minimum. Neither run is
    `optimal`: their J is the 10 x 5 mesh's (the single start 6.4e-5 above its bisected mesh,
    the best 2.2e-4 below the mesh-converged 57.94478); both once said `optimal`, as the flight
    that could not be corrected onto the final conditions counted as a check of J."""
    multi = ocdsl.load(_cartpole(tmp_path, "{transcription: LGR, segments: 10, degree: 5, starts: 8, seed: 0}")).solve()
    one = ocdsl.load(_cartpole(tmp_path, "{transcription: LGR, segments: 10, degree: 5}", "one.yaml")).solve()
    rows = multi.extra["starts"]
    assert [r["seed"] for r in rows] == [None, 1, 2, 3, 4, 5, 6, 7]
    assert rows[0]["objective"] == one.objective and rows[0]["iterations"] == one.iterations
    assert rows[0]["status"] == "optimal" and one.status == "mesh_not_converged"   # Ipopt's; the run's
    assert one.extra["bisection"]["agrees"] is False
    assert abs(one.objective - OTHER) < 1e-2              # the single start's local minimum
    assert multi.status == "mesh_not_converged" and multi.objective < OTHER - 0.5, rows
    assert multi.extra["bisection"]["levels"][0]["objective"] == pytest.approx(BEST, rel=1e-4)
    assert multi.objective <= min(r["objective"] for r in rows if r["status"] == "optimal")
    assert sum(abs(r["objective"] - multi.objective) < 1e-6 for r in rows) >= 2, rows


@pytest.mark.ipopt
def test_cartpole_starts_with_mesh_reach_the_best_known_minimum(tmp_path):
    """unseen5/extra/cartpole_swingup_starts8.yaml: starts on the first mesh, refinement from
    the best; before, 58.80767 (expect failed); now the best known value to 1e-6."""
    res = ocdsl.load(_cartpole(tmp_path, "{transcription: LGR, segments: 10, degree: 5, starts: 8, seed: 0, "
                                         "mesh: {tolerance: 1.0e-7, max_iterations: 12}}")).solve()
    assert res.status == "optimal", res.message
    assert res.objective == pytest.approx(BEST, rel=1e-6)
    assert res.extra["starts"][0]["seed"] is None


def _grid():
    return np.concatenate([[0.0], np.linspace(0.0, 1.0, 201)[1:-1], [1.0]])


def test_perturbed_starts_keep_bounds_and_fixed_boundary_values(tmp_path):
    problem = compile_file(_cartpole(tmp_path, "{transcription: LGR, segments: 4, degree: 4, starts: 4}")).problem
    ph = problem.phases[0]
    s = _grid()
    base = make_guess(problem, ph)
    x0, u0 = base.states_at(s), base.controls_at(s)
    moved = 0
    for i in range(1, 40):
        g = start_guesses(problem, {}, i, None, 0)[ph.name]
        x, u = g.states_at(s), g.controls_at(s)
        assert np.all(np.abs(x[:, 0]) <= 2.0) and np.all(np.abs(u) <= 20.0)     # -2 <= q1 <= 2, |u| <= 20
        # every state's two ends are fixed: kept bit for bit
        np.testing.assert_array_equal(x[[0, -1]], x0[[0, -1]])
        assert (g.t0, g.tf) == (0.0, 2.0)
        # the whole guess moves, smoothly: states and controls, inside the interval
        assert np.all(np.abs(x[1:-1] - x0[1:-1]).max(axis=0) > 1e-3)
        assert np.abs(u - u0).max() > 1e-3
        # no node-to-node noise (white noise in the bounds: second differences ~ the span;
        # here at most a kink where a curve is clipped at a bound)
        assert np.abs(np.diff(x, 2, axis=0)).max() < 0.2 and np.abs(np.diff(u, 2, axis=0)).max() < 1.0
        moved += np.any(np.abs(x[:, 0]) >= 2.0 - 1e-12)      # clipped at the bound somewhere
    assert moved < 39          # the amplitude is a fraction of the span, mostly not at the bound


BRACH_FREE_T0 = """name: free times
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: free, tf: free}
  constraints:
    - -1 <= u <= 1
    - 0 <= t0 <= 1
    - 2 <= tf <= 3
    - x(t0) == 0
    - v(t0) == 0
    - x(tf) == 1
  objective: minimize tf - t0
  guess: {t0: 0.5, tf: 2.5}
method: {transcription: LGR, segments: 4, degree: 3, starts: 4}
"""


def test_perturbed_starts_draw_free_times_inside_their_bounds(tmp_path):
    p = tmp_path / "times.yaml"
    p.write_text(BRACH_FREE_T0)
    problem = compile_file(p).problem
    ph = problem.phases[0]
    base = make_guess(problem, ph)
    assert (base.t0, base.tf) == (0.5, 2.5)
    seen = set()
    s = _grid()
    for i in range(1, 30):
        g = start_guesses(problem, {}, i, None, 5)[ph.name]
        assert 0.0 <= g.t0 <= 1.0 and 2.0 <= g.tf <= 3.0
        seen.add((round(g.t0, 9), round(g.tf, 9)))
        x = g.states_at(s)
        assert x[0, 0] == 0.0 and x[0, 1] == 0.0 and x[-1, 0] == 1.0     # fixed ends kept
        assert x[-1, 1] != base.states_at(s)[-1, 1]                      # v(tf) is free: it moves
    assert len(seen) == 29


def test_starts_are_reproducible_by_seed_and_start_0_is_the_guess(tmp_path):
    problem = compile_file(_cartpole(tmp_path, "{transcription: LGR, segments: 4, degree: 4, starts: 4}")).problem
    ph = problem.phases[0]
    s = _grid()

    def values(i, seed, base):
        g = start_guesses(problem, {}, i, seed, base)[ph.name]
        return np.concatenate([g.states_at(s).ravel(), g.controls_at(s).ravel(), [g.t0, g.tf]])

    g0 = make_guess(problem, ph)
    np.testing.assert_array_equal(values(0, None, 0), np.concatenate(
        [g0.states_at(s).ravel(), g0.controls_at(s).ravel(), [g0.t0, g0.tf]]))
    np.testing.assert_array_equal(values(0, None, 0), values(0, None, 9))    # start 0 ignores the seed
    np.testing.assert_array_equal(values(3, None, 0), values(3, None, 0))
    np.testing.assert_array_equal(values(3, None, 0), values(1, None, 2))    # seed 0 + 3 == seed 2 + 1
    assert not np.array_equal(values(3, None, 0), values(4, None, 0))


def test_random_controls_files_keep_their_redrawn_starts(tmp_path):
    """``guess: {random: true}`` (the seed-0 files) or a run seed: start i is a new draw of
    the random controls from seed + i, states on the guess, as before."""
    text = CARTPOLE.replace("METHOD", "{transcription: LGR, segments: 4, degree: 4, starts: 4, seed: 3}").replace(
        "  objective: minimize integral(u**2)", "  objective: minimize integral(u**2)\n  guess: {random: true, seed: 3}")
    p = tmp_path / "random.yaml"
    p.write_text(text)
    problem = compile_file(p).problem
    ph = problem.phases[0]
    s = _grid()
    for i in range(1, 4):
        g, old = start_guesses(problem, {}, i, None, 3)[ph.name], make_guess(problem, ph, seed=3 + i)
        np.testing.assert_array_equal(g.states_at(s), old.states_at(s))
        np.testing.assert_array_equal(g.controls_at(s), old.controls_at(s))
    np.testing.assert_array_equal(start_guesses(problem, {}, 0, None, 3)[ph.name].controls_at(s),
                                  make_guess(problem, ph).controls_at(s))


def test_the_summary_says_how_the_starts_ended():
    """unseen8: eight starts back in one basin read as confirmation; the summary now counts
    where they ended."""
    from ocdsl.cli import _starts_line

    rec = [{"status": "optimal", "objective": j} for j in (25.8727, 26.1567, 25.8727, 26.1567)]
    rec.append({"status": "infeasible", "objective": None})
    assert _starts_line(rec, 25.8727) == "5: 2 ended at this objective, 2 elsewhere (26.1567), 1 did not solve"
    assert _starts_line(rec[:1], 25.8727) == ""
    # every start in one basin: said to be a local optimum all the same (unseen47 F8: eight
    # starts around an obstacle's upper side, 30 % above the lower side's optimum)
    assert _starts_line([{"status": "optimal", "objective": 0.6893}] * 8, 0.6893) == (
        "8: 8 ended at this objective (a local optimum: starts perturb the guess and do not show it global)")


OBSTACLE = """
name: obstacle
model:
  states: [x, y]
  controls: [ux, uy]
  dynamics: {x: ux, y: uy}
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, y(t0) == 0, x(tf) == 1.2, y(tf) == 1.6, (x-0.4)**2 + (y-0.5)**2 >= 0.1]
  objective: minimize integral(ux**2 + uy**2)
  guess: {x: {t: [0, 0.5, 1], values: [0, 0.9, 1.2]}, y: {t: [0, 0.5, 1], values: [0, 0.4, 1.6]}}
method: {transcription: LGR, segments: 4, degree: 4, starts: 8, mesh: {tolerance: 1.0e-7, max_iterations: 10}}
"""


def _shortest_around_circle(a, b, c, r) -> float:
    """Length of the shortest path from a to b around the disc (c, r): tangent, arc, tangent
    on the side that is shorter (both ends outside the disc, the segment a-b through it)."""
    a, b, c = (np.asarray(p, float) for p in (a, b, c))
    da, db = np.linalg.norm(a - c), np.linalg.norm(b - c)
    ta, tb = np.sqrt(da ** 2 - r ** 2), np.sqrt(db ** 2 - r ** 2)
    ang = np.arccos(np.dot(a - c, b - c) / (da * db))
    arc = ang - np.arccos(r / da) - np.arccos(r / db)
    return float(ta + tb + r * arc)


def test_a_mesh_restarted_from_the_guess_starts_from_the_start_that_won(tmp_path):
    """unseen27 FC1: with `starts: 8` a perturbed start passes the obstacle on its short side
    on the first mesh (J 4.4203); the refinement restarts a mesh from the guess where a control
    zigzags, and took the file's guess (the long side): 4.5442, `optimal`. It takes the
    winning start's guess: J = L^2 for the shortest path L around the disc. The summary
    compares the starts with the first mesh's objective."""
    import subprocess
    import sys

    problem = tmp_path / "obstacle.yaml"
    problem.write_text(OBSTACLE)
    out = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(problem), "--out", str(tmp_path / "run")],
                         capture_output=True, text=True, timeout=600)
    result = ocdsl.read(tmp_path / "run")
    best = _shortest_around_circle((0, 0), (1.2, 1.6), (0.4, 0.5), np.sqrt(0.1)) ** 2
    assert best == pytest.approx(4.4211973256, abs=1e-9)
    assert result.objective == pytest.approx(best, abs=1e-6), out.stdout
    assert "ended at the first mesh's objective" in out.stdout, out.stdout


def test_a_junction_inside_a_segment_is_not_called_converged(tmp_path):
    """unseen27 FC2: x' = u, an obstacle centred on the chord. A coarse mesh's exit from the
    circle held a breakpoint at t = 0.503; the true exit, 0.548, sat between two nodes of
    the next segment, where the polynomial states of x' = u are exact: every error estimate
    below 1e-8, J 1.65e-4 high, `optimal`, verified. The constraint's binding (by its
    multipliers) that changes between two inner nodes of a segment is no converged mesh:
    the run says so, or refines on to the optimum."""
    text = OBSTACLE.replace("0.4)**2 + (y-0.5)**2", "0.6)**2 + (y-0.8)**2").replace(
        "starts: 8, ", "").replace("values: [0, 0.9, 1.2]", "values: [0, 1.1, 1.2]").replace(
        "values: [0, 0.4, 1.6]", "values: [0, 0.5, 1.6]")
    problem = tmp_path / "chord.yaml"
    problem.write_text(text)
    result = ocdsl.load(problem).solve()
    best = _shortest_around_circle((0, 0), (1.2, 1.6), (0.6, 0.8), np.sqrt(0.1)) ** 2
    assert best == pytest.approx(4.4136106983, abs=1e-9)
    flagged = [h for h in result.extra["mesh_history"] if h.get("inner_junctions")]
    assert flagged
    # converged or not, the reported mesh is not one the estimate is blind on (unseen28: the
    # "best" mesh reported, J 1.65e-4 high, was such a mesh, beside later ones that were right)
    assert result.objective == pytest.approx(best, abs=1e-5 * (1 + best)), result.message
    assert "inner_junctions" not in result.extra["mesh_history"][result.extra["mesh"]["chosen_iteration"] - 1]
