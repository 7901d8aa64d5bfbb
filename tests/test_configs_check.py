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


def test_bench_bad_options_are_one_clear_error():
    """`ocdsl bench` option mistakes: exit 2 with a usage message, never a traceback."""
    from click.testing import CliRunner

    runner = CliRunner()
    brach = str(CONFIGS / "brachistochrone.yaml")
    r = runner.invoke(main, ["bench", brach, "--series-solve", "5"])
    assert r.exit_code == 2 and "--series-solve needs --scaling" in r.output
    r = runner.invoke(main, ["bench", brach, "--scaling", brach, "--scaling-segments", "10,x"])
    assert r.exit_code == 2 and "integers separated by commas" in r.output
