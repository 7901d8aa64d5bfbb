"""`ocdsl schema` (the JSON Schema an editor validates problem files with) admits what ocdsl
reads: every problem file of configs/, and the constant-expression times of the language."""
import json
import re
from pathlib import Path

import jsonschema
import pytest
from click.testing import CliRunner

from ocdsl.cli import main
from ocdsl.spec.loader import load_yaml

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
# YAML 1.1 (PyYAML) reads 3.986e14 as text, a YAML 1.2 reader (an editor's) as a number
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _as_editor_reads(value):
    if isinstance(value, dict):
        return {k: _as_editor_reads(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_as_editor_reads(v) for v in value]
    if isinstance(value, str) and _NUMBER.match(value):
        return float(value)
    return value


@pytest.fixture(scope="module")
def validator():
    out = CliRunner().invoke(main, ["schema"])
    assert out.exit_code == 0, out.output
    schema = json.loads(out.output)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


# every file of configs/, controller files included (their block was untyped, unseen9 D2); a
# Pareto file is its own format, a study or search block is validated by its own loader
PROBLEM_FILES = [p for p in sorted(CONFIGS.glob("*.yaml"))
                 if not {"pareto", "study", "search"} & set(load_yaml(p).data)]


@pytest.mark.parametrize("path", PROBLEM_FILES, ids=[p.stem for p in PROBLEM_FILES])
def test_every_problem_file_of_configs_is_valid_under_the_exported_schema(validator, path):
    errors = [f"{list(e.absolute_path)}: {e.message[:200]}"
              for e in validator.iter_errors(_as_editor_reads(load_yaml(path).data))]
    assert not errors, errors


def test_constant_expression_times_are_valid_and_a_list_is_not(validator):
    text = (CONFIGS / "minimal_double_integrator.yaml").read_text()
    data = _as_editor_reads(load_yaml(CONFIGS / "minimal_double_integrator.yaml").data)
    data["problem"]["time"] = {"t0": 0, "tf": "2*pi"}
    data["problem"]["guess"] = {"tf": "sqrt(2)"}
    assert not list(validator.iter_errors(data))
    data["problem"]["time"]["tf"] = [1, 2]
    assert list(validator.iter_errors(data)), "a list is no time"
    assert "tf: free" in text


def test_the_back_end_blocks_are_typed(validator):
    """A misspelt key in a method or controller block is a schema error (each was `{}`)."""
    for name, block, key in [("minimal_double_integrator", "method", "segmnts")]:
        data = _as_editor_reads(load_yaml(CONFIGS / f"{name}.yaml").data)
        data[block][key] = 1
        assert list(validator.iter_errors(data)), (name, block)
    ctrl = next(p for p in sorted(CONFIGS.glob("*.yaml")) if "controller" in load_yaml(p).data)
    data = _as_editor_reads(load_yaml(ctrl).data)
    data["controller"]["Qq"] = [1]
    assert list(validator.iter_errors(data)), ctrl.name
