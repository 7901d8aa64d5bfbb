"""The seed-0 problem files compile to the intended problem (solving them is in the slow tests)."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from ocdsl.api import compile_file
from ocdsl.study.spec import StudySpec

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def boundary(lf):
    return {c.text.split(" ==")[0]: c.lower for c in lf.problem.boundary}


@pytest.mark.parametrize("name,euler", [("seed0_rendezvous", "printed"), ("seed0_exact_euler", "exact")])
def test_main_scenario_files(name, euler):
    lf = compile_file(CONFIGS / f"{name}.yaml")
    ph = lf.problem.phases[0]
    assert ph.model.name == "rendezvous_6dof" and ph.model.description.endswith(euler)
    assert lf.method.transcription == "LG" and lf.method.segments == 20 and lf.method.degree == 3
    assert lf.method.starts >= 5
    assert lf.problem.objective.sense == "minimize" and str(lf.problem.objective.expr) == "tf"
    assert {c.name: b for c, b in ph.control_bounds.items()} == {
        "T1": (-50, 50), "T2": (-50, 50), "T3": (-50, 50),
        "F1": (-320, 320), "F2": (-320, 320), "F3": (-320, 320)}
    bc = boundary(lf)
    assert len(bc) == 24
    assert bc["x(t0)"] == 20 and bc["z(tf)"] == -10
    assert bc["sigma2(tf)"] == pytest.approx(np.tan(np.pi / 8), abs=1e-15)
    assert all(v == 0 for k, v in bc.items() if k not in ("x(t0)", "z(tf)", "sigma2(tf)"))
    assert ph.tf is None


def test_table4_sweep():
    path = CONFIGS / "seed0_table4.yaml"
    study = StudySpec.model_validate(yaml.safe_load(path.read_text())["study"])
    assert study.sweep.mode == "zip"
    rows = list(zip(*(study.sweep.zip_[k] for k in ("x0", "y0", "z0"))))
    assert rows == [(20, 0, 0), (20, 4, 0), (20, 4, 4), (20, 4, -5), (25, -5, -5)]
    for row in rows:
        lf = compile_file(path, parameters=dict(zip(("x0", "y0", "z0"), row)))
        bc = boundary(lf)
        assert (bc["x(t0)"], bc["y(t0)"], bc["z(t0)"]) == row
        assert bc["z(tf)"] == -10


def test_fine_mesh_file_is_the_main_problem_on_at_least_100_nodes():
    main, fine = (compile_file(CONFIGS / f"{n}.yaml") for n in ("seed0_rendezvous", "seed0_fine"))
    assert boundary(fine) == boundary(main)
    assert fine.problem.phases[0].model.description == main.problem.phases[0].model.description
    assert fine.method.transcription == "LG"
    assert fine.method.segments * fine.method.degree >= 100
    tf = fine.spec.expect["tf"]
    assert tf.value - tf.atol == pytest.approx(25.868) and tf.value + tf.atol == pytest.approx(25.873)
