"""`make bench-peers` compares one solve of the same mesh: the case's problem file drops
`mesh:` (adaptive refinement is the mesh table's business, ocdsl.bench.mesh), for single- and
multi-phase files alike (no CasADi needed to write the script)."""
from pathlib import Path

import pytest
import yaml

from conftest import CONFIGS
from ocdsl.bench.peers import prepare


@pytest.mark.parametrize("name", ["lit_free_flying_robot", "two_phase_double_integrator",
                                  "lit_goddard_three_phase", "mesh_moon_landing"])
def test_the_case_solves_the_files_initial_mesh(name, tmp_path):
    yml, script, _, _ = prepare(CONFIGS / f"{name}.yaml", tmp_path)
    data = yaml.safe_load(Path(yml).read_text())
    methods = [data.get("method") or {}] + [(p or {}).get("method") or {} for p in (data.get("phases") or {}).values()]
    assert all("mesh" not in m for m in methods)
    assert Path(script).exists()
    original = yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())
    assert data["method"].get("segments") == (original.get("method") or {}).get("segments")
