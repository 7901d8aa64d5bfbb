"""What a run imports (issue 26, start-up): the direct NumPy route of a pseudospectral solve,
its post-processing and its verification import neither SciPy nor Numba nor Matplotlib.

SciPy alone was 0.5-0.8 s of a small run's 1.5-2 s of CPU (cyipopt's ``minimize_ipopt``
front end, scipy.sparse for one product, scipy.integrate for the verification). Each run is
a fresh process (``sys.modules`` of that process at its end); the warm run (cache filled
by the cold one) must give the cold run's result. Nor do such runs (no ``tables:``, no
Sundman option) load the table splines or ocdsl.simulate, and the console script pauses
the cyclic collector while a run's modules load (ocdsl/startup.py).
"""
import json
import subprocess
import sys

import pytest

HEAVY = ("scipy", "numba", "matplotlib")
#: ocdsl modules a run loads only for a file that needs them
OPTIONAL = ("ocdsl.symbolic.tables", "ocdsl.spec.tables", "ocdsl.simulate", "ocdsl.report", "ocdsl.study",
            "ocdsl.search", "rich", "ocdsl.solve.mesh.drive")

_CODE = """
import json, sys
from ocdsl.cli import main
try:
    main(["run", sys.argv[1], "--out", sys.argv[2], "-q"], standalone_mode=False)
finally:
    print("MODULES " + json.dumps(sorted(sys.modules)))
"""


def _run(path, out, env):
    p = subprocess.run([sys.executable, "-c", _CODE, str(path), str(out)], capture_output=True, text=True,
                       env=env, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("MODULES "))
    return set(json.loads(line.split(" ", 1)[1]))


def _loaded(mods: set[str], names) -> list[str]:
    return sorted({n for n in names for m in mods if m == n or m.startswith(n + ".")})


@pytest.mark.ipopt
@pytest.mark.parametrize("name", ["double_integrator", "brachistochrone"])
def test_cold_and_warm_runs_import_no_scipy_and_agree(configs, tmp_path, name):
    import os

    env = {**os.environ, "OCDSL_CACHE": str(tmp_path / "cache")}
    env.pop("OCDSL_NO_CACHE", None)
    cold = _run(configs / f"{name}.yaml", tmp_path / "cold", env)
    warm = _run(configs / f"{name}.yaml", tmp_path / "warm", env)
    for mods in (cold, warm):
        assert not _loaded(mods, HEAVY), _loaded(mods, HEAVY)
        assert not _loaded(mods, OPTIONAL), _loaded(mods, OPTIONAL)
        assert "pyomo.core" in mods and "sympy" in mods          # the probe sees what a run loads
    rc, rw = (json.loads((tmp_path / n / "result.json").read_text()) for n in ("cold", "warm"))
    assert rc["nlp"]["evaluation"] == "direct (NumPy)"
    assert rc["status"] == rw["status"] == "optimal"
    assert rc["verification"]["status"] == rw["verification"]["status"] == "verified"
    assert rc["objective"] == rw["objective"]
    assert (tmp_path / "cold" / "trajectory.csv").read_text() == (tmp_path / "warm" / "trajectory.csv").read_text()



@pytest.mark.ipopt
@pytest.mark.parametrize("name", ["mesh_rayleigh_mixed", "mesh_bryson_denham"])
def test_adaptive_mesh_runs_import_no_scipy(configs, tmp_path, name):
    """The mesh stage's estimates, switch and corner location and coarsening use ocdsl's
    DOP853 and Brent root finder (importing scipy.integrate and scipy.optimize was 0.4-0.8 s).
    Not a bang-bang run (mesh_double_integrator, mesh_bang_off_bang): its switch times are
    solved as NLP unknowns on Pyomo's PyNumero route, which imports scipy.sparse (docs/mesh.md;
    a fixed-time switch since a mesh within tolerance held one on a wrong breakpoint)."""
    import os

    mods = _run(configs / f"{name}.yaml", tmp_path / "run", {**os.environ})
    assert not _loaded(mods, HEAVY), _loaded(mods, HEAVY)
    res = json.loads((tmp_path / "run" / "result.json").read_text())
    assert res["status"] == "optimal" and res["verification"]["status"] == "verified"
    assert res["extra"]["mesh"]["iterations"] >= 2           # the refinement ran


_WINDOWS = """
import gc, sys
from ocdsl import startup
with startup.loading("a"):
    print("inactive", gc.isenabled())
startup.one_command_process()
with startup.loading("b"):
    paused = not gc.isenabled()
    made = [[i] for i in range(20000)]
print("paused", paused, gc.isenabled(), gc.get_count()[0] < 1000, gc.get_freeze_count() == 0)
with startup.loading("b"):
    print("once", gc.isenabled())
try:
    with startup.loading("c"):
        raise KeyError
except KeyError:
    print("error", gc.isenabled())
"""


def test_startup_windows_pause_the_collector_only_in_a_one_command_process():
    """In-process callers keep their collector as it is; the console script's window pauses it
    while modules load, hands what they made to the oldest generation (the young one is
    empty after it, nothing stays frozen), turns it back on (also on an error), once."""
    p = subprocess.run([sys.executable, "-c", _WINDOWS], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split("\n")[:-1] == ["inactive True", "paused True True True True", "once True",
                                           "error True"], p.stdout


_COLLECTIONS = """
import gc, sys
import ocdsl.cli as cli
sys.argv = ["ocdsl", "run", sys.argv[1], "--out", sys.argv[2], "-q"]
try:
    cli.entry() if sys.argv[0] == "entry" else cli.main(standalone_mode=True)
except SystemExit as e:
    print("EXIT", e.code, gc.isenabled(), sum(s["collections"] for s in gc.get_stats()))
"""


@pytest.mark.ipopt
def test_console_script_run_collects_less_while_loading(configs, tmp_path):
    """``ocdsl run`` through the console script (``entry``) and in-process (``main``): the same
    result and exit code, the collector on again at the end, and far fewer collections
    through the console script (about 260 -> 30 for this file), which pauses it while the
    run's modules load."""
    counts = {}
    for how in ("entry", "main"):
        code = _COLLECTIONS.replace('sys.argv[0] == "entry"', repr(how == "entry"))
        p = subprocess.run([sys.executable, "-c", code, str(configs / "double_integrator.yaml"),
                            str(tmp_path / how)], capture_output=True, text=True, timeout=300)
        words = p.stdout.split()
        assert words[:3] == ["EXIT", "0", "True"], (p.stdout, p.stderr[-2000:])
        counts[how] = int(words[3])
    assert counts["entry"] * 3 < counts["main"], counts
    ra, rb = (json.loads((tmp_path / h / "result.json").read_text()) for h in ("entry", "main"))
    assert ra["status"] == rb["status"] == "optimal" and ra["objective"] == rb["objective"]


_PROBES = """
import ctypes.util, sys
import pyomo.core as pyo
from ocdsl.solve.ipopt import pynumero_nlp
calls = []
real = ctypes.util.find_library
ctypes.util.find_library = lambda name: calls.append(name) or real(name)
m = pyo.ConcreteModel()
m.x = pyo.Var(initialize=1.0)
m.c = pyo.Constraint(expr=m.x ** 2 >= 1)
m.o = pyo.Objective(expr=m.x)
nlp = pynumero_nlp(m)
print("PROBES", len(calls), nlp.n_primals())
"""


@pytest.mark.skipif(sys.platform == "win32", reason="the probe is skipped off Windows only")
def test_a_pynumero_nlp_probes_no_windows_c_runtime_off_windows():
    """PyomoNLP sets AMPLFUNC through Pyomo's CtypesEnviron, which probed eleven Windows C
    runtimes (msvcrt, msvcr120, ..., kernel32) with ctypes.util.find_library: a subprocess
    each, 0.14 s of every process that takes the PyNumero route (flat B-splines, mesh
    refinement's switch moves; mesh_tumour's run 2.19 -> 1.92 s CPU). Off Windows none
    exists, so none is probed (in a fresh process: Pyomo keeps what it found)."""
    import os

    p = subprocess.run([sys.executable, "-c", _PROBES], capture_output=True, text=True, timeout=300,
                       env={**os.environ})
    assert p.returncode == 0, p.stderr[-2000:]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("PROBES "))
    assert line.split()[1:] == ["0", "1"]
