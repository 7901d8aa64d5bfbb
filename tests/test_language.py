"""Problem-language conveniences: YAML merge keys and the `definitions:` home for anchors,
the `==` hint, and models added by other packages through the `ocdsl.models` entry points."""
import sys

import pytest

from conftest import write
from ocdsl.spec.compile import load
from ocdsl.spec.errors import SpecError

BASE = """
name: merge
definitions:
  common: &common
    time: {t0: 0, tf: free}
    objective: minimize tf
  unit_box: &box [-1 <= u <= 1]
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  <<: *common
  constraints: [-1 <= u <= 1, x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, 0.1 <= tf <= 10]
"""


def test_merge_key_and_definitions(tmp_path):
    f = load(write(tmp_path, BASE))
    ph = f.problem.phases[0]
    assert ph.tf is None and f.problem.objective.sense == "minimize"


def test_keys_written_beside_a_merge_win(tmp_path):
    text = BASE.replace("  <<: *common\n", "  <<: *common\n  objective: maximize tf\n")
    assert load(write(tmp_path, text)).problem.objective.sense == "maximize"


def test_error_in_merged_text_points_at_the_anchor_line(tmp_path):
    text = BASE.replace("objective: minimize tf", "objective: minimize tff")
    with pytest.raises(SpecError) as e:
        load(write(tmp_path, text))
    issue = e.value.issues[0]
    assert issue.line == 6 and "tff" in issue.message


def test_merge_of_a_non_mapping_is_one_clear_error(tmp_path):
    text = BASE.replace("  <<: *common\n", "  <<: *box\n")
    with pytest.raises(SpecError, match="merge key"):
        load(write(tmp_path, text))


def test_single_equals_gets_a_hint(tmp_path):
    with pytest.raises(SpecError, match=r"written with ==") as e:
        load(write(tmp_path, BASE.replace("x(t0) == 1", "x(t0) = 1")))
    assert e.value.issues[0].line == 14


def test_third_party_models_through_entry_points(tmp_path, monkeypatch):
    from ocdsl.symbolic import registry

    (tmp_path / "acme_models.py").write_text(
        "from ocdsl.symbolic.model import Model, syms\n"
        "from ocdsl.symbolic.registry import register\n"
        "@register('acme_integrator', description='x'' = u')\n"
        "def build(options):\n"
        "    x, u = syms('x u')\n"
        "    return Model('acme_integrator', (x,), (u,), {x: u})\n")
    info = tmp_path / "acme-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: acme\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[ocdsl.models]\nacme = acme_models\n")
    registry.model_names()     # the project's own first: their modules register only once
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_LOADED", False)
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))
    try:
        assert "acme_integrator" in registry.model_names()
        assert registry.build_model("acme_integrator").states[0].name == "x"
        text = BASE.replace("  states: [x, v]\n  controls: [u]\n  dynamics: {x: v, v: u}\n",
                            "  use: acme_integrator\n")
        text = text.replace(", v(t0) == 0, x(tf) == 0, v(tf) == 0", ", x(tf) == 0")
        assert load(write(tmp_path, text)).problem.phases[0].states[0].name == "x"
    finally:
        sys.modules.pop("acme_models", None)


def test_the_project_models_load_as_ocdsl_models_not_a_top_level_package():
    from ocdsl.symbolic import registry

    registry.model_names()
    assert "ocdsl.models.classic" in sys.modules
    assert "models" not in sys.modules and "models.classic" not in sys.modules
