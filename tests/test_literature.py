"""Published optimal-control problems written from the docs as a user would
(configs/lit_*.yaml, docs/literature.md; issue 24). Each run must either match its published
value within the file's stated tolerance and be verified, or be flagged as not verified; the
verdict of every file is pinned here. The reference values that are closed forms or exact
integrations are recomputed independently of ocdsl below (SciPy only)."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.integrate import quad, solve_ivp
from scipy.linalg import expm
from scipy.optimize import brentq, fsolve

from conftest import CONFIGS


# matched and verified at the file's own method: name -> slow (docs/literature.md has the
# numbers and wall times)
MATCHED = {
    "catenary": False, "orbit_raising": False, "linear_tangent": False,
    "linear_tangent_parameters": False, "bryson_denham_touch": False, "isoperimetric": False,
    "brachistochrone_wall": False, "hypersensitive_linear": False,
    "bryson_denham_three_phase": False, "goddard_three_phase": False,
    "min_fuel_double_integrator": True, "rayleigh_mixed": True, "catalyst_mixing": True,
    "singular_aly": True, "delta_iii": True, "lotka_fishing": True, "robot_arm": True,
    # from a new user's trial (unseen4), closed forms checked below
    "zermelo": False, "lqr_terminal_weight": False, "min_energy_free_velocity": False,
    "brachistochrone_to_line": False,
    # written from the docs in the sixth session of 2026-12-06
    "min_time_energy": False,
    # written in the tenth session of 2026-12-07 (unseen27 FC2)
    "obstacle_chord": False,
    # written in the eleventh session of 2026-12-07
    "dubins_uturn": False,
    # written in the twelfth session of 2026-12-07
    "oscillator_min_time": False,
}
# not verified: adaptive refinement stops at max_iterations (largest estimated error 2e-5),
# J settles at 7.910916, 4.5e-5 above the published 7.91055654 (expect fails at rtol 1e-6)
FFR = "free_flying_robot"
# not converged: its refinement ends 1.8e-8 above the tolerance 1e-8 (verified, tf to 2e-7;
# it was 1.6e-3 late and flagged before the switch times were NLP unknowns)
TUMOUR = "tumour"
# not verified: h(tf) matches (5.9e-6), but the mesh's `regularise` term is in the NLP's
# objective, so its stationarity in tf is v(tf) + d(reg)/dtf = 0: v(tf) = 5.0e-5 at tf =
# 0.1988254, and the verification, which sees the unregularised J = h(tf), finds dJ/dtf != 0
# (free final time 7.8e-4): tf is right to about 5e-5, not to 1e-5
GODDARD_COPS = "goddard_cops"
# optimal and verified, but 4.6e-5 above the published optimum of a maximisation (expect
# fails): the published number is not the optimum (test below flies the control)
PUBLISHED_LOW = "batch_reactor_temperature"
# optimal on the mesh (terminal conditions judged per segment: the flight from y(0) amplifies
# by 3.7e17) and J within 1e-6 of Betts; verified piece by piece, the flight from y(0) (which
# misses y(tf) by 1e7, as any discrete solution of this unstable block would) not judged
ALP_RIDER = "alp_rider"


def test_every_literature_file_has_a_pinned_verdict():
    files = {p.stem[len("lit_"):] for p in CONFIGS.glob("lit_*.yaml")}
    assert files == set(MATCHED) | {FFR, TUMOUR, GODDARD_COPS, ALP_RIDER, PUBLISHED_LOW}


def _run(name: str, out: Path) -> dict:
    from ocdsl.api import run_file

    run_file(CONFIGS / f"lit_{name}.yaml", out / name)
    return json.loads((out / name / "result.json").read_text())


def _assert_matched(name: str, data: dict) -> None:
    v = data["verification"]
    assert data["status"] == "optimal", (name, data["status"], data.get("message"))
    assert v["status"] == "verified", (name, v.get("summary"))
    checks = data["expect"]
    assert checks, f"{name}: no expect checks"
    for check in checks:
        # the published value at the file's tolerance, as ocdsl compared it; recomputed here
        ref, val = check["reference"], check["value"]
        tol = (check["rtol"] or 0) * abs(ref) + (check["atol"] or 0)
        assert (abs(val - ref) <= tol) == check["passed"], (name, check)
        assert check["passed"], (name, check)


def _params():
    for name, slow in MATCHED.items():
        marks = [pytest.mark.ipopt] + ([pytest.mark.slow] if slow else [])
        yield pytest.param(name, marks=marks, id=name)


@pytest.mark.parametrize("name", list(_params()))
def test_published_problem(name, tmp_path):
    _assert_matched(name, _run(name, tmp_path))


@pytest.mark.ipopt
def test_tumour_uniform_mesh_not_verified_with_wrong_tf(tmp_path):
    """D2: on a uniform LG 12 x 4 mesh the solve stops at the guess tf = 1.2 (3.2e-3 after
    the exact 1.1963497; the dose ends on a segment boundary, so the trajectory flies
    exactly). It once said optimal and verified; the objective is not stationary in the
    free tf, and the verification says so."""
    import yaml
    from ocdsl.api import run_file

    spec = yaml.safe_load((CONFIGS / "lit_tumour.yaml").read_text())
    spec["method"] = {"transcription": "LG", "segments": 12, "degree": 4}
    path = tmp_path / "tumour_lg.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    run_file(path, tmp_path / "run")
    data = json.loads((tmp_path / "run" / "result.json").read_text())
    assert data["status"] == "optimal" and abs(data["tf"] - 1.1963497) > 1e-3
    v = data["verification"]
    assert v["status"] == "failed" and v["summary"].startswith("not verified: free final time")
    dynamics = [c for c in v["checks"] if c["name"].startswith("dynamics")]
    assert dynamics and all(c["passed"] for c in dynamics)     # it flies: only optimality fails


@pytest.mark.slow
@pytest.mark.ipopt
def test_tumour_switch_solved_but_not_converged(tmp_path):
    """The dose window's end is solved as an NLP unknown (switches.solve_switch_times): tf =
    1.1963499 against the exact 1.1963497 (it was 1.19793, 1.6e-3 late, flagged by the free
    final time check), p(tf) and tf match and the verification passes; the refinement still
    ends 1.8e-8 above its tolerance 1e-8 at the window's end (the integral of u), and says so."""
    data = _run(TUMOUR, tmp_path)
    assert data["status"] == "mesh_not_converged"
    p_tf, tf = data["expect"]
    assert p_tf["passed"] and tf["passed"]
    assert abs(data["tf"] - 1.1963497) < 1e-6
    assert data["verification"]["status"] == "verified", data["verification"]["summary"]


@pytest.mark.slow
@pytest.mark.ipopt
def test_goddard_cops_flagged_tf_not_resolved(tmp_path):
    data = _run(GODDARD_COPS, tmp_path)
    assert data["status"] == "optimal" and all(c["passed"] for c in data["expect"])
    v = data["verification"]
    failed = [c["name"] for c in v["checks"] if not c["passed"]]
    assert v["status"] == "failed" and failed == ["free final time"], v["summary"]


@pytest.mark.slow
@pytest.mark.ipopt
def test_alp_rider_optimal_and_verified_piece_by_piece(tmp_path):
    """The mesh converges with the terminal conditions judged segment by segment (the run
    says so) and J matches Betts; the verification passes every check per piece, and leaves
    the three that fly the controls from y(0) not judged (the flight amplifies a change of
    y(0) by 3.7e17), saying so. Until 2026-12-07 those three failed it."""
    data = _run(ALP_RIDER, tmp_path)
    assert data["status"] == "optimal", data["message"]
    assert "judged with each segment flown from its own start" in data["message"]
    assert all(c["passed"] for c in data["expect"])
    v = data["verification"]
    assert v["status"] == "verified", v["summary"]
    unjudged = {(c["name"], c.get("detail", "")) for c in v["checks"] if c["passed"] is None}
    assert {name for name, _ in unjudged} == {"dynamics from x(t0)", "boundary conditions", "objective"}, unjudged
    assert all(name == "dynamics from x(t0)" or "from x(t0)" in detail for name, detail in unjudged), unjudged
    assert all(c["passed"] for c in v["checks"] if c["passed"] is not None)
    assert "amplifies a change of x(t0) by 3.7e+17" in v["summary"]


@pytest.mark.slow
@pytest.mark.ipopt
def test_free_flying_robot_not_verified(tmp_path):
    data = _run(FFR, tmp_path)
    assert data["status"] == "mesh_not_converged"
    # the best mesh is verified all the same (its NLP converged); the run is still not ok
    assert data["verification"]["status"] in ("verified", "failed")
    (check,) = data["expect"]
    assert not check["passed"] and 1e-5 < check["relative_error"] < 1e-4


# ---- the reference values, recomputed independently of ocdsl --------------------------------

def test_catenary_reference():
    """x = a cosh((t - b)/a) + c through (0, 1), (1, 3) with length 4: J = 5.068480."""
    def eqs(p):
        a, b, c = p
        return [a * math.cosh(-b / a) + c - 1, a * math.cosh((1 - b) / a) + c - 3,
                a * (math.sinh((1 - b) / a) + math.sinh(b / a)) - 4]
    a, b, c = fsolve(eqs, [0.3, 0.3, -0.5], xtol=1e-14)
    assert max(map(abs, eqs([a, b, c]))) < 1e-10
    J = quad(lambda t: (a * math.cosh((t - b) / a) + c) * math.cosh((t - b) / a), 0, 1,
             epsabs=1e-13, limit=200)[0]
    assert J == pytest.approx(5.068480, abs=5e-7)


def test_aly_reference():
    """u = -1 to ts, then the singular arc u = x1 with x2(5) = 0 (x1 = C cosh(5 - t))."""
    ts = brentq(lambda s: (1 - s) + (s - s * s / 2) * math.tanh(5 - s), 1.0, 2.0, xtol=1e-15)
    C = (ts - ts * ts / 2) / math.cosh(5 - ts)
    J = quad(lambda t: ((t - t * t / 2) ** 2 + (1 - t) ** 2) / 2, 0, ts, epsabs=1e-15)[0] \
        + quad(lambda t: C * C * (math.cosh(5 - t) ** 2 + math.sinh(5 - t) ** 2) / 2, ts, 5,
               epsabs=1e-15)[0]
    assert J == pytest.approx(0.3769919302879714, rel=1e-12)


def test_min_fuel_reference():
    """Bryson & Ho pp. 116-117: simulate the bang-off-bang control, check the end state."""
    x0, v0, tf = 0.1, 0.5, 1.5
    r = math.sqrt((tf - v0) ** 2 - 4 * x0 - 2 * v0 ** 2)
    t1, t2 = (tf + v0 - r) / 2, (tf + v0 + r) / 2
    u = lambda t: -1.0 if t < t1 else (0.0 if t < t2 else 1.0)
    sol = solve_ivp(lambda t, y: [y[1], u(t)], [0, tf], [x0, v0], rtol=1e-12, atol=1e-14,
                    max_step=1e-3)
    assert np.abs(sol.y[:, -1]).max() < 1e-5
    assert t1 + (tf - t2) == pytest.approx(1.1837722339831620, rel=1e-14)


def test_bryson_denham_touch_reference():
    """Two cubics meeting x = l, v = 0 at t = 1/2: J = 8 (1 - 6 l + 12 l**2)."""
    l = 1 / 5
    # x = t + a t^2 + b t^3 on [0, 1/2] with x(1/2) = l, v(1/2) = 0; mirrored after
    a, b = np.linalg.solve([[1 / 4, 1 / 8], [1.0, 3 / 4]], [l - 1 / 2, -1.0])
    J = 2 * quad(lambda t: (2 * a + 6 * b * t) ** 2 / 2, 0, 0.5)[0]
    assert J == pytest.approx(8 * (1 - 6 * l + 12 * l * l), rel=1e-12) and J == pytest.approx(2.24)


def test_hypersensitive_reference():
    """Hamiltonian system z' = A z, z = (x, lambda), u = -lambda, against dymos' closed form."""
    A = np.array([[-1.0, -1.0], [-1.0, 1.0]])
    lam0 = (1.0 - expm(A * 10)[0, 0] * 1.5) / expm(A * 10)[0, 1]
    z0 = np.array([1.5, lam0])
    J = quad(lambda t: 0.5 * np.sum((expm(A * t) @ z0) ** 2), 0, 10, limit=400, epsabs=1e-13)[0]
    assert J == pytest.approx(1.673093978412, rel=1e-10)


@pytest.mark.ipopt
def test_batch_reactor_beats_its_published_optimum(tmp_path):
    """Floudas et al. 1999 give max x2(1) = 0.610775 for the temperature-controlled A -> B -> C
    reactor. ocdsl's verified optimum is 0.6108029; its temperature rows, linearly
    interpolated (within the bounds, so a feasible control) and flown with SciPy at rtol
    1e-12 independently of ocdsl, reach the same x2(1), above the published value by more
    than its tolerance: the published number is a lower bound, not the optimum, and ocdsl's
    failed expectation is the honest verdict."""
    import csv

    from scipy.interpolate import interp1d

    data = _run(PUBLISHED_LOW, tmp_path)
    assert data["status"] == "optimal" and data["verification"]["status"] == "verified"
    (check,) = data["expect"]
    assert not check["passed"] and check["value"] > check["reference"] * (1 + check["rtol"])
    with open(tmp_path / PUBLISHED_LOW / "trajectory.csv") as fh:
        rows = [(float(r["t"]), float(r["T"])) for r in csv.DictReader(fh) if r["T"] != "nan"]
    t, T = np.array(rows).T
    assert 298 - 1e-9 <= T.min() and T.max() <= 398 + 1e-9
    temp = interp1d(t, T, bounds_error=False, fill_value=(T[0], T[-1]))

    def rhs(_t, x):
        Tt = float(temp(_t))
        k1, k2 = 4000 * math.exp(-2500 / Tt), 620000 * math.exp(-5000 / Tt)
        return [-k1 * x[0] ** 2, k1 * x[0] ** 2 - k2 * x[1]]

    fly = solve_ivp(rhs, [0, 1], [1.0, 0.0], rtol=1e-12, atol=1e-14, max_step=1e-3)
    x2 = fly.y[1, -1]
    assert x2 == pytest.approx(data["objective"], rel=1e-5)
    assert x2 > 0.610775 * (1 + 2e-5)


def test_zermelo_reference():
    """Uniform current w = 0.5, speed 1, (0, 0) -> (1, 1): a constant heading, so
    (1 - w T)^2 + 1 = T^2; flown with that heading the boat arrives."""
    T = brentq(lambda T: (1 - 0.5 * T) ** 2 + 1 - T * T, 0.5, 3.0, xtol=1e-15)
    th = math.atan2(1.0, 1.0 - 0.5 * T)
    assert (math.cos(th) + 0.5) * T == pytest.approx(1.0, abs=1e-14) and math.sin(th) * T == pytest.approx(1.0)
    assert T == pytest.approx(1.0971675407097272, rel=1e-14)


def test_lqr_terminal_weight_reference():
    """p' = p^2 - 2p - 1 backwards from p(1) = 2; J* = p(0) x0^2, and the closed loop
    u = -p x flown forwards gives the same cost."""
    back = solve_ivp(lambda t, p: [p[0] ** 2 - 2 * p[0] - 1], [1, 0], [2.0], rtol=1e-13, atol=1e-14,
                     dense_output=True)
    p0 = back.y[0, -1]
    assert p0 == pytest.approx(2.3858185961863385, rel=1e-11)
    fwd = solve_ivp(lambda t, z: [(1 - back.sol(t)[0]) * z[0], z[0] ** 2 * (1 + back.sol(t)[0] ** 2)],
                    [0, 1], [1.0, 0.0], rtol=1e-12, atol=1e-14)
    x1, cost = fwd.y[:, -1]
    assert cost + 2 * x1 ** 2 == pytest.approx(p0, rel=1e-9)


def test_min_energy_free_velocity_reference():
    """u = c (T - t), c = 3 d / T^3: x(T) = d, and J = c^2 T^3 / 6 = 1.5 d^2 / T^3."""
    d, T = 1.0, 2.0
    c = 3 * d / T ** 3
    x_T = quad(lambda t: quad(lambda s: c * (T - s), 0, t)[0], 0, T)[0]
    J = quad(lambda t: (c * (T - t)) ** 2 / 2, 0, T)[0]
    assert x_T == pytest.approx(d, rel=1e-12) and J == pytest.approx(0.1875, rel=1e-12)


def test_min_time_energy_reference():
    """J(tf) = tf + 1/(2 tf) for the constant control 1/tf: least at 1/sqrt(2), J* = sqrt(2); the
    constant control is the minimum principle's (u = -lambda, lambda constant), and at the free
    t_f H = u^2/2 - u^2 = -1 = -dPhi/dtf holds there."""
    from scipy.optimize import minimize_scalar

    best = minimize_scalar(lambda tf: tf + 1 / (2 * tf), bounds=(0.1, 10), method="bounded",
                           options={"xatol": 1e-12})
    assert best.x == pytest.approx(1 / math.sqrt(2), rel=1e-6)
    assert best.fun == pytest.approx(math.sqrt(2), rel=1e-12)
    u = 1 / best.x
    assert u ** 2 / 2 - u ** 2 == pytest.approx(-1.0, rel=1e-6)


def test_obstacle_chord_reference():
    """Shortest path from a to b around the disc (c, r), the chord through c: a tangent from
    each end and the arc between the tangent points, L = 2 sqrt(d^2 - r^2) + r (pi - 2
    acos(r / d)) with d = |a - c| = |b - c|; at constant speed over T = 1, J = L^2 (the
    minimum of int |u|^2 for a path of length L)."""
    a, b, c, r = np.array([0.0, 0.0]), np.array([1.2, 1.6]), np.array([0.6, 0.8]), math.sqrt(0.1)
    u, v = b - a, c - a
    assert u[0] * v[1] - u[1] * v[0] == pytest.approx(0.0, abs=1e-15)      # c on the chord
    d = float(np.linalg.norm(a - c))
    L = 2 * math.sqrt(d * d - r * r) + r * (math.pi - 2 * math.acos(r / d))
    spec = yaml.safe_load((CONFIGS / "lit_obstacle_chord.yaml").read_text())
    assert L ** 2 == pytest.approx(spec["expect"]["objective"]["value"], rel=1e-10)


def _dubins_lengths(start, goal, r: float = 1.0) -> dict[str, float]:
    """Lengths of Dubins' six words (LSL, RSR, LSR, RSL, RLR, LRL) from pose ``start`` to pose
    ``goal`` (x, y, heading), turning radius ``r``, by the standard normalised formulas
    (Shkel and Lumelsky 2001); an impossible word is left out."""
    dx, dy = goal[0] - start[0], goal[1] - start[1]
    d = math.hypot(dx, dy) / r
    th = math.atan2(dy, dx)
    a, b = (start[2] - th) % (2 * math.pi), (goal[2] - th) % (2 * math.pi)
    sa, sb, ca, cb, cab = math.sin(a), math.sin(b), math.cos(a), math.cos(b), math.cos(a - b)
    m = lambda x: x % (2 * math.pi)  # noqa: E731
    out = {}
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)
    if p2 >= 0:
        t = m(-a + math.atan2(cb - ca, d + sa - sb))
        out["LSL"] = t + math.sqrt(p2) + m(b - math.atan2(cb - ca, d + sa - sb))
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)
    if p2 >= 0:
        out["RSR"] = m(a - math.atan2(ca - cb, d - sa + sb)) + math.sqrt(p2) + m(-b + math.atan2(ca - cb, d - sa + sb))
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        w = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2, p)
        out["LSR"] = m(-a + w) + p + m(-b + w)
    p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        w = math.atan2(ca + cb, d - sa - sb) - math.atan2(2, p)
        out["RSL"] = m(a - w) + p + m(b - w)
    q = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8
    if abs(q) <= 1:
        p = m(2 * math.pi - math.acos(q))
        t = m(a - math.atan2(ca - cb, d - sa + sb) + p / 2)
        out["RLR"] = t + p + m(a - b - t + p)
    q = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8
    if abs(q) <= 1:
        p = m(2 * math.pi - math.acos(q))
        t = m(-a - math.atan2(ca - cb, d + sa - sb) + p / 2)
        out["LRL"] = t + p + m(b - a - t + p)
    return {k: v * r for k, v in out.items()}


def test_dubins_uturn_reference():
    """The shortest of Dubins' six words from (0, 0, east) to (0, 4, west) at radius 1 is
    LSL, pi/2 + 2 + pi/2; at unit speed its length is the minimum time. The word lengths are
    checked on a pose pair whose answer is plain (straight ahead: S alone) first."""
    assert _dubins_lengths((0, 0, 0), (5, 0, 0))["LSL"] == pytest.approx(5.0, abs=1e-12)
    words = _dubins_lengths((0, 0, 0), (0, 4, math.pi))
    best = min(words, key=words.get)
    assert best == "LSL" and words[best] == pytest.approx(math.pi + 2, rel=1e-12)
    spec = yaml.safe_load((CONFIGS / "lit_dubins_uturn.yaml").read_text())
    assert words[best] == pytest.approx(spec["expect"]["objective"]["value"], rel=1e-12)


def _oscillator_min_time(x0) -> tuple[float, list[float]]:
    """x1' = x2, x2' = -x1 + u, |u| <= 1 to the origin in minimum time: u = -sign(lambda_2),
    lambda_2 sinusoidal, so the arcs but the first and the last last pi; for each number of
    inner arcs and first sign, the two free arcs solve x(T) = 0 (fsolve from a grid of
    starts); the shortest T and its arcs."""
    def flow(x, u, t):       # a rotation about (u, 0)
        c, s = math.cos(t), math.sin(t)
        return np.array([u + c * (x[0] - u) + s * x[1], -s * (x[0] - u) + c * x[1]])

    best = (math.inf, [])
    for first in (1.0, -1.0):
        for inner in range(6):
            def miss(z, first=first, inner=inner):
                x, u = flow(np.asarray(x0, float), first, z[0]), first
                for _ in range(inner):
                    u = -u
                    x = flow(x, u, math.pi)
                return flow(x, -u, z[1])
            for g in np.linspace(0.1, 3.1, 7):
                for h in np.linspace(0.1, 3.1, 7):
                    z, _, ok, _ = fsolve(miss, [g, h], full_output=True, xtol=1e-14)
                    if ok == 1 and 0 < min(z) and max(z) <= math.pi + 1e-9 and np.max(np.abs(miss(z))) < 1e-12:
                        T = z[0] + inner * math.pi + z[1]
                        if T < best[0] - 1e-12:
                            best = (T, [z[0]] + [math.pi] * inner + [z[1]])
    return best


def _oscillator_lp_time(x0, steps: int) -> float:
    """The same minimum time by bisection on T of the feasibility LP of the exact
    zero-order-hold discretisation on ``steps`` steps (no maximum principle)."""
    from scipy.optimize import linprog

    A, B = np.array([[0.0, 1.0], [-1.0, 0.0]]), np.array([[0.0], [1.0]])

    def reachable(T):
        M = expm(np.block([[A, B], [np.zeros((1, 3))]]) * (T / steps))
        Ad, Bd = M[:2, :2], M[:2, 2:]
        cols, P = [], np.eye(2)
        for _ in range(steps):
            cols.append(P @ Bd)
            P = Ad @ P
        res = linprog(np.zeros(steps), A_eq=np.hstack(cols[::-1]), b_eq=-(P @ np.asarray(x0, float)),
                      bounds=[(-1, 1)] * steps, method="highs")
        return res.status == 0

    lo, hi = 7.0, 9.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if reachable(mid) else (mid, hi)
    return hi


def test_oscillator_min_time_reference():
    """From (5, 0): u = -1, +1, -1, +1, arcs 0.16686, pi, pi, 1.48737; the exact-discretisation
    LP on 4,000 steps agrees to its O(h^2) (about 1e-6)."""
    T, arcs = _oscillator_min_time((5.0, 0.0))
    assert len(arcs) == 4 and arcs[0] == pytest.approx(0.16686017, abs=1e-8)
    spec = yaml.safe_load((CONFIGS / "lit_oscillator_min_time.yaml").read_text())
    assert T == pytest.approx(spec["expect"]["objective"]["value"], rel=1e-11)
    assert _oscillator_lp_time((5.0, 0.0), 4000) == pytest.approx(T, rel=2e-6)


def test_brachistochrone_to_line_reference():
    """The cycloid of radius 1/pi arriving horizontally at x = 1: time pi sqrt(R / g) =
    sqrt(pi), depth 2R; its arc length over speed integrates to the same time."""
    R = 1 / math.pi
    # along x = R (phi - sin phi), y = R (1 - cos phi): ds = 2 R sin(phi/2) dphi, v = sqrt(2 g y)
    t = quad(lambda phi: 2 * R * math.sin(phi / 2) / math.sqrt(2 * R * (1 - math.cos(phi))), 1e-12, math.pi)[0]
    assert R * (math.pi - math.sin(math.pi)) == pytest.approx(1.0)
    assert t == pytest.approx(1.7724538509055159, rel=1e-9) and 2 * R == pytest.approx(0.6366197723675814)


def test_tumour_bang_off_reference():
    """Full dose to t = A/a = 0.2, then none until p = q: p = 7571.670038 at tf = 1.1963497,
    1.5e-7 below Betts' 7571.6712."""
    xi, b, d, G, mu, A, a = 0.084, 5.85, 0.00873, 0.15, 0.02, 15.0, 75.0
    pmax = ((b - mu) / d) ** 1.5
    rhs = lambda t, y, u: [-xi * y[0] * math.log(y[0] / y[1]),
                           y[1] * (b - (mu + d * y[0] ** (2 / 3) + G * u))]
    y = solve_ivp(rhs, [0, A / a], [pmax / 2, pmax / 4], args=(a,), rtol=1e-12, atol=1e-9).y[:, -1]
    meet = lambda t, y, u: y[0] - y[1]
    meet.terminal = True
    s = solve_ivp(rhs, [A / a, 5], y, args=(0.0,), rtol=1e-12, atol=1e-9, events=meet)
    p, tf = s.y_events[0][0][0], s.t_events[0][0]
    assert p == pytest.approx(7571.670038, abs=2e-6) and tf == pytest.approx(1.1963497, abs=1e-7)
    assert p < 7571.6712


def test_one_phase_under_phases_is_no_traceback(tmp_path):
    """Found while cutting the Delta III file down to one phase: `ocdsl check` must either
    accept a `phases:` block with a single phase or refuse it in one message, never crash."""
    from click.testing import CliRunner

    from ocdsl.cli import main

    path = tmp_path / "one_phase.yaml"
    path.write_text("""name: one phase under phases
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
phases:
  only:
    time: {t0: 0, tf: 1}
    constraints: [x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0]
    objective: integral(u**2)
objective: minimize 0
""")
    res = CliRunner().invoke(main, ["check", str(path)])
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert res.exit_code in (0, 2), res.output


@pytest.mark.ipopt
def test_exp_with_small_scale_height_solves(tmp_path):
    """Found writing the Delta III ascent (density exp(-(r - 1)/hs), hs = h0/R_e = 1.13e-3):
    x' = u + 0.001 exp(-(x - 2)/H) from 2 to 3 must solve like the same problem written in
    y = x - 2 (which does: optimal, verified). SymPy once folded the constant out of the
    exponential into a float beyond 1e308 (D4); substituted numbers now keep it whole
    (ocdsl/symbolic/numbers.py, safe_exp)."""
    from ocdsl.api import run_file

    text = """name: exp with a small scale height
model:
  states: [{s}]
  controls: [u]
  parameters: {{H: 0.001}}
  dynamics: {{{s}: u + 0.001*exp(-({s} - {a})/H)}}
problem:
  time: {{t0: 0, tf: 1}}
  constraints: [{s}(t0) == {a}, {s}(tf) == {b}]
  objective: minimize integral(u**2)
method: {{transcription: LGR, segments: 4, degree: 4}}
"""
    (tmp_path / "y.yaml").write_text(text.format(s="y", a=0, b=1))
    (tmp_path / "x.yaml").write_text(text.format(s="x", a=2, b=3))
    shifted = run_file(tmp_path / "y.yaml", tmp_path / "y")
    assert shifted.status == "optimal" and shifted.verified
    res = run_file(tmp_path / "x.yaml", tmp_path / "x")
    assert res.status == "optimal", res.message
    assert res.objective == pytest.approx(shifted.objective, rel=1e-8)


@pytest.mark.ipopt
def test_scalar_lq_regulator_with_a_free_end_matches_the_riccati_solution():
    """Kirk (1970) sec. 5.2, written from the docs alone (seventeenth session's hook): x' = u,
    x(0) = 1, min int x^2 + u^2 on [0, 1], x(1) free. Riccati p = tanh(1 - t), u = -p x, so
    J* = tanh(1) and x(1) = 1/cosh(1), both recomputed here. No flight judges J (H's minimiser
    is the solution's control), so the fixed mesh is bisected, and agrees."""
    from ocdsl.api import run_file

    res = run_file(Path(__file__).parent / "data" / "lq_tanh_free_end.yaml", None)
    assert res.status == "optimal" and res.ok and res.verified
    assert res.objective == pytest.approx(math.tanh(1.0), rel=1e-10)
    x = res.phases[0].states["x"]
    assert x[-1] == pytest.approx(1 / math.cosh(1.0), rel=1e-9)
    assert res.extra["bisection"]["agrees"] is True
