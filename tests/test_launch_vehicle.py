"""configs/launch_vehicle.yaml: GPOPS-II's four-phase launch vehicle in SI units, one shared
model, one continuity line, orbital elements at the final time, `scaling: {mode: auto}`;
7529.712 kg published."""
import pytest

from conftest import ROOT


def test_the_file_is_one_model_and_one_continuity_line():
    from ocdsl.api import load

    f = load(str(ROOT / "configs" / "launch_vehicle.yaml")).file
    assert f.spec.model is not None and all(p.model is None for p in f.spec.phases.values())
    assert f.spec.links == ["continuous(stage1, stage2, stage3, stage4, [r, w])"]
    assert f.spec.scaling.mode == "auto"
    # per-phase values of the shared model's constants
    consts = {ph.name: {s.name: v for s, v in ph.constants.items()} for ph in f.problem.phases}
    assert [consts[p]["boosters"] for p in ("stage1", "stage2", "stage3", "stage4")] == [6, 3, 0, 0]
    assert [consts[p]["second"] for p in ("stage1", "stage2", "stage3", "stage4")] == [0, 0, 0, 1]


@pytest.mark.slow
@pytest.mark.ipopt
def test_launch_vehicle_reaches_the_published_final_mass(tmp_path):
    from ocdsl.api import run_file

    res = run_file(ROOT / "configs" / "launch_vehicle.yaml", tmp_path / "run")
    assert res.status == "optimal"
    assert res.verification["status"] == "verified", res.verification.get("summary")
    final_mass = next(c for c in res.expect if c["name"] == "stage4.m(tf)")
    assert final_mass["passed"] and abs(final_mass["value"] - 7529.712) <= 1e-5 * 7529.712
    assert res.extra["scaling"]["stage1"]["x"] == pytest.approx(2 * 6378145.0)
    # the certificate's Hamiltonian was NaN while SymPy split exp(885 - r/H) (safe_exp)
    assert res.certificate["passed"], res.certificate.get("phases")
