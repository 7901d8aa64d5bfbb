"""What a run imports (issue 26, start-up): the direct NumPy route of a pseudospectral solve,
its post-processing and its verification import neither SciPy nor Numba nor Matplotlib.

SciPy alone was 0.5-0.8 s of a small run's 1.5-2 s of CPU (cyipopt's ``minimize_ipopt``
front end, scipy.sparse for one product, scipy.integrate for the verification). Each run is
a fresh process (``sys.modules`` of that process at its end); the warm run (cache filled
by the cold one) must give the cold run's result.
"""
import json
import subprocess
import sys

import pytest

HEAVY = ("scipy", "numba", "matplotlib")

_CODE = """
import json, sys
from ocdsl.cli import main
try:
    main(["run", sys.argv[1], "--out", sys.argv[2], "-q"], standalone_mode=False)
finally:
    print("MODULES " + json.dumps(sorted({m.split(".")[0] for m in sys.modules})))
"""


def _run(path, out, env):
    p = subprocess.run([sys.executable, "-c", _CODE, str(path), str(out)], capture_output=True, text=True,
                       env=env, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("MODULES "))
    return set(json.loads(line.split(" ", 1)[1]))


@pytest.mark.ipopt
@pytest.mark.parametrize("name", ["double_integrator", "brachistochrone"])
def test_cold_and_warm_runs_import_no_scipy_and_agree(configs, tmp_path, name):
    import os

    env = {**os.environ, "OCDSL_CACHE": str(tmp_path / "cache")}
    env.pop("OCDSL_NO_CACHE", None)
    cold = _run(configs / f"{name}.yaml", tmp_path / "cold", env)
    warm = _run(configs / f"{name}.yaml", tmp_path / "warm", env)
    for mods in (cold, warm):
        assert not mods & set(HEAVY), sorted(mods & set(HEAVY))
    rc, rw = (json.loads((tmp_path / n / "result.json").read_text()) for n in ("cold", "warm"))
    assert rc["nlp"]["evaluation"] == "direct (NumPy)"
    assert rc["status"] == rw["status"] == "optimal"
    assert rc["verification"]["status"] == rw["verification"]["status"] == "verified"
    assert rc["objective"] == rw["objective"]
    assert (tmp_path / "cold" / "trajectory.csv").read_text() == (tmp_path / "warm" / "trajectory.csv").read_text()
