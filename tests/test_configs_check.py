"""Every problem file in configs/ validates (what `ocdsl check` does), without solving."""
import subprocess
import sys

import pytest

from conftest import CONFIGS

FILES = sorted(CONFIGS.glob("*.yaml"))


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_config_checks(path):
    proc = subprocess.run([sys.executable, "-m", "ocdsl.cli", "check", str(path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "ok" in proc.stdout
