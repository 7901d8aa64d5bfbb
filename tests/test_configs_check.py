"""Every problem file in configs/ validates (what `ocdsl check` does), without solving."""
import pytest
from click.testing import CliRunner

from conftest import CONFIGS
from ocdsl.cli import main

FILES = sorted(CONFIGS.glob("*.yaml"))


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_config_checks(path):
    res = CliRunner().invoke(main, ["check", str(path)])
    assert res.exit_code == 0, res.output
    assert "ok" in res.output
