"""Seed 0 through the product: `configs/seed0_*.yaml` solved by ocdsl's LG transcription.

Paper (Mousavi et al. 2022, digest ../shared/seeds/seed_000.md §7.4): main scenario
20 x 3 LG t_f = 25.8727 s; warm-started 40 x 3 in [25.868, 25.873]; exact Euler form 25.8731 s; Table 4 rows [20,4,4] 25.9360 and
[20,4,-5] 25.6607; [20,4,0] and [25,-5,-5] at or below 26.1674 and 28.7185.
Each solve takes 1-2 minutes with 8 starts: these run in `make reproduce`, not in CI.
"""
import numpy as np
import pytest

import ocdsl
from conftest import CONFIGS

pytestmark = [pytest.mark.slow, pytest.mark.ipopt]


def _the_meshs_optimum(res):
    """The paper's meshes do not converge J: bisected, the minimum time falls (20 x 3 LG:
    25.87271 -> 25.87046, 8.7e-5; the digest's 40 x 3 value is 25.870465), so ocdsl reports
    the mesh's optimum as `mesh_not_converged`, with the bisected J; the paper's numbers are
    still reproduced (the expect checks). It once said `optimal`: its flown-control check,
    which could not be corrected onto the twelve final conditions, counted as a check of J."""
    assert res.status == "mesh_not_converged", res.message
    bisection = res.extra["bisection"]
    assert bisection["agrees"] is False and bisection["levels"][0]["objective"] < res.objective
    assert "this mesh's optimum" in res.message
    assert all(c["passed"] for c in res.expect), res.expect


@pytest.fixture(scope="module")
def main_run(tmp_path_factory):
    """The 20 x 3 main scenario, solved once with its run folder (the fine mesh starts from it)."""
    out = tmp_path_factory.mktemp("seed0") / "main"
    return ocdsl.load(CONFIGS / "seed0_rendezvous.yaml").solve(out=out), out


def test_main_scenario_and_certificate(main_run):
    res, _ = main_run
    _the_meshs_optimum(res)
    assert abs(res.tf - 25.8727) <= 5e-5          # half the printed last digit (unseen51 F1)
    assert abs(res.extra["bisection"]["levels"][0]["objective"] - 25.870465) <= 5e-5
    cert = res.certificate
    assert abs(cert["hamiltonian"]["mean"] + 1) <= 2e-3
    assert cert["hamiltonian"]["max_deviation"] <= 3e-2
    assert cert["switching"]["agreement"] >= 0.99
    for u, info in cert["bang_bang"]["per_control"].items():
        assert info["fraction_at_bound"] >= 0.95, u
    assert cert["passed"], cert["failed"]
    # the paper's 20 x 3 nodes do not resolve the bang-bang switches: re-integrated, the
    # trajectory misses by about 1e-2 of a state's range at the switches, so ocdsl does not
    # call it verified (the paper's t_f is still reproduced, and the expect check passes)
    v = res.verification
    assert v["status"] == "failed" and not res.ok
    dyn = next(c for c in v["checks"] if c["name"] == "dynamics per piece")
    assert 1e-3 < dyn["value"] < 5e-2


def test_exported_controls_are_the_solution(main_run):
    """trajectory.csv holds no extrapolated control: LG segment ends are empty, every value
    written is within its bound (the extrapolated F3 was -746.67 N against +-320 N)."""
    _, folder = main_run
    df = np.genfromtxt(folder / "trajectory.csv", delimiter=",", names=True)
    limits = {**{f"T{i}": 50.0 for i in (1, 2, 3)}, **{f"F{i}": 320.0 for i in (1, 2, 3)}}
    for name, bound in limits.items():
        col = df[name]
        written = col[np.isfinite(col)]
        assert 0 < len(written) < len(col), name           # segment ends are left empty
        assert np.max(np.abs(written)) <= bound * (1 + 1e-6), (name, np.max(np.abs(written)))


def test_fine_mesh_warm_start(main_run):
    """40 x 3 LG (120 nodes) warm-started from the 20 x 3 run folder through the API."""
    _, folder = main_run
    res = ocdsl.load(CONFIGS / "seed0_fine.yaml").solve(warm_start=folder)
    _the_meshs_optimum(res)
    assert sum(len(p.time) for p in res.phases) >= 100
    assert res.method["meshes"]["main"]["segments"] * res.method["meshes"]["main"]["degrees"][0] >= 100
    assert 25.868 <= res.tf <= 25.873
    cert = res.certificate
    assert abs(cert["hamiltonian"]["mean"] + 1) <= 2e-3
    assert cert["passed"], cert["failed"]

    # the switch-time resolution halves with h, and so does the re-integration error
    def dynamics(r):
        return next(c["value"] for c in r.verification["checks"] if c["name"] == "dynamics per piece")

    assert dynamics(res) < 0.75 * dynamics(main_run[0])


def test_exact_euler_form():
    res = ocdsl.load(CONFIGS / "seed0_exact_euler.yaml").solve()
    _the_meshs_optimum(res)
    assert abs(res.tf - 25.873064) <= 5e-7        # the digest's 6 decimals (unseen51 F1)


@pytest.mark.parametrize("x0,y0,z0,paper,mode", [
    (20, 4, 4, 25.9360, "equal"), (20, 4, -5, 25.6607, "equal"),
    (20, 4, 0, 26.1674, "at_most"), (25, -5, -5, 28.7185, "at_most")])
def test_table4_row(x0, y0, z0, paper, mode):
    res = ocdsl.load(CONFIGS / "seed0_table4.yaml", parameters={"x0": x0, "y0": y0, "z0": z0}).solve()
    assert res.status == "mesh_not_converged" and res.extra["bisection"]["agrees"] is False, res.message
    # the file-level parameters x0, y0, z0 once made the certificate raise KeyError: 'x0'
    assert res.certificate["passed"], res.certificate.get("failed") or res.certificate.get("error")
    assert res.verification["status"] in ("verified", "failed")    # a verdict, never an error
    if mode == "equal":
        assert abs(res.tf - paper) <= 5e-4
    else:
        assert res.tf <= paper + 5e-4
