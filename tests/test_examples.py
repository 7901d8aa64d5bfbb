"""Published optima of the classic benchmarks, for every pseudospectral scheme.

Sources (../shared/seeds/benchmarks-public.md):
- double integrator, tf = 2 (analytic; control-toolbox CTProblems)
- brachistochrone, tf = 1.8016 (dymos), cycloid 1.8016031224530815
- Bryson-Denham with x <= 1/9, J = 4 (Bryson & Ho; dymos; PSOPT 3.999539)
- Meditch moon landing, J = 1.4203125990 exact, tf = 1.3968080891 (PSOPT 1.420408)
- Goddard with v <= 0.1, r(tf) = 1.0125762700748699 (control-toolbox, indirect)
Each file's ``expect:`` holds the value and a tolerance of 1e-4 relative or tighter.
"""
import pytest
import yaml

import ocdsl

EXAMPLES = ["double_integrator", "minimal_double_integrator", "brachistochrone", "bryson_denham",
            "moon_landing", "goddard"]
SCHEMES = ["LG", "LGR", "LGL"]


def _with_scheme(configs, tmp_path, name, scheme):
    data = yaml.safe_load((configs / f"{name}.yaml").read_text())
    data["method"]["transcription"] = scheme
    p = tmp_path / f"{name}_{scheme}.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


@pytest.mark.ipopt
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", EXAMPLES)
def test_published_optimum(configs, tmp_path, name, scheme):
    res = ocdsl.load(_with_scheme(configs, tmp_path, name, scheme)).solve()
    assert res.status == "optimal", res.message
    assert res.expect, "every example states its published optimum"
    for check in res.expect:
        assert check["passed"], check
        assert check["relative_error"] <= max(check["rtol"] or 0, 1e-4)


@pytest.mark.ipopt
def test_two_linked_phases(configs):
    """Links carry states and time across phases; per-phase trajectories and final times."""
    res = ocdsl.load(configs / "two_phase_double_integrator.yaml").solve()
    assert res.ok, (res.status, res.expect)
    assert set(res.tf) == {"accelerate", "brake"}
    acc, brake = res.phase("accelerate"), res.phase("brake")
    assert acc.time[-1] == pytest.approx(brake.time[0], abs=1e-9)
    assert acc.states["v"][-1] == pytest.approx(brake.states["v"][0], abs=1e-9)


@pytest.mark.ipopt
def test_run_folder_contract(configs, tmp_path):
    from ocdsl.api import run_file
    from ocdsl.result import Result

    out = tmp_path / "run"
    res = run_file(configs / "brachistochrone.yaml", out)
    assert res.ok
    data = Result.read(out)
    assert data.status == "optimal" and abs(data.tf - 1.8016) < 1e-3
    for key in ("parse", "symbolic", "build", "solve", "post", "total"):
        assert key in data.wall_time_s
    assert data.nlp["variables"] > 0 and data.nlp["nonzeros"] > 0
    assert set(data.phases[0].states) == {"x", "y", "v"}
    assert len(data["x"]) == len(data["t"]) and data["x"][-1] == pytest.approx(10, abs=1e-6)
    assert set(data.phases[0].costates) == {"x", "y", "v"}
    assert (out / "problem.yaml").read_text() == (configs / "brachistochrone.yaml").read_text()


@pytest.mark.ipopt
def test_resolve_with_other_parameters(configs):
    """A loaded file re-solved with another g: tf scales as 1/sqrt(g) (same cycloid)."""
    handle = ocdsl.load(configs / "brachistochrone.yaml")
    base = handle.solve()
    other = handle.solve(parameters={"g": 9.81})
    assert other.tf == pytest.approx(base.tf * (9.80665 / 9.81) ** 0.5, rel=1e-7)
    assert handle.solve().tf == pytest.approx(base.tf, rel=1e-12)   # the handle is unchanged


@pytest.mark.ipopt
def test_multi_phase_expect_uses_constants():
    """A multi-phase expectation may name a constant parameter (it was NaN before)."""
    from pathlib import Path

    res = ocdsl.load(Path(__file__).parent / "data" / "two_phase_expect_parameter.yaml").solve()
    assert res.expect[0]["passed"], res.expect


@pytest.mark.ipopt
def test_guess_from_a_run_folder(configs, tmp_path):
    """`guess: {from: RUN}` starts from a previous run: same optimum, fewer iterations."""
    from ocdsl.api import run_file

    cold = run_file(configs / "brachistochrone.yaml", tmp_path / "first")
    text = (configs / "brachistochrone.yaml").read_text().replace(
        "  objective: minimize tf", "  objective: minimize tf\n  guess: {from: first}")
    p = tmp_path / "again.yaml"
    p.write_text(text)
    warm = ocdsl.load(p).solve()
    assert warm.tf == pytest.approx(cold.tf, rel=1e-9)
    assert warm.iterations < cold.iterations
