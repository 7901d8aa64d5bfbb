"""The construction fast paths of the transcription give the same optimum as the plain path.

``ocdsl.transcribe.pseudospectral.FAST`` switches the levers of reports/bench/levers.md;
both settings must reach the same optimum (to 1e-8) on the examples. Not timed.
"""
import pytest

import ocdsl
from ocdsl.transcribe import pseudospectral

EXAMPLES = ["double_integrator", "brachistochrone", "bryson_denham", "moon_landing", "goddard"]


def _solve(configs, name, fast: bool, monkeypatch):
    for k in pseudospectral.FAST:
        monkeypatch.setitem(pseudospectral.FAST, k, fast)
    res = ocdsl.load(configs / f"{name}.yaml").solve()
    assert res.status == "optimal", res.message
    return res


@pytest.mark.ipopt
@pytest.mark.parametrize("name", EXAMPLES)
def test_fast_paths_same_optimum(configs, name, monkeypatch):
    plain = _solve(configs, name, False, monkeypatch)
    fast = _solve(configs, name, True, monkeypatch)
    assert fast.objective == pytest.approx(plain.objective, rel=1e-8, abs=1e-10)
    assert fast.nlp["variables"] == plain.nlp["variables"]
    assert fast.nlp["constraints"] == plain.nlp["constraints"]
    assert fast.nlp["nonzeros"] == plain.nlp["nonzeros"]
    for s in plain.phase().states:
        assert fast.phase().states[s] == pytest.approx(plain.phase().states[s], rel=1e-6, abs=1e-7)


def test_fast_path_switches_exist():
    assert set(pseudospectral.FAST) >= {"no_gc", "linear_defects"}


def test_bench_cli_imports_only_click():
    """``ocdsl bench`` can be registered without slowing ``ocdsl --help``."""
    import subprocess
    import sys

    code = ("import sys, ocdsl.bench.cli; "
            "print(any(m in sys.modules for m in ('sympy', 'pyomo', 'casadi', 'numpy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


@pytest.mark.ipopt
@pytest.mark.parametrize("scheme", ["LGR", "LG", "LGL"])
def test_generated_casadi_script_same_optimum(configs, tmp_path, scheme):
    """The bench's CasADi script (same transcription, bounds, guess, options) finds ocdsl's optimum."""
    pytest.importorskip("casadi")
    import json
    import subprocess
    import sys

    from ocdsl.api import compile_file
    from ocdsl.bench.casadi_gen import write_script

    p = tmp_path / "bd.yaml"
    p.write_text((configs / "bryson_denham.yaml").read_text().replace("transcription: LGR", f"transcription: {scheme}"))
    res = ocdsl.load(p).solve()
    script = write_script(tmp_path / "bd_casadi.py", compile_file(p))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, check=True).stdout
    line = next(ln for ln in out.splitlines() if ln.startswith("CASADI_RESULT "))
    ca = json.loads(line.split(" ", 1)[1])
    assert ca["status"] == "Solve_Succeeded"
    assert ca["variables"] - res.nlp["variables"] >= 0   # CasADi counts fixed variables too
    assert ca["objective"] == pytest.approx(res.objective, rel=1e-8)


def test_gc_left_as_found_after_build_and_hand_over(configs):
    """build() and run's gc_frozen() leave the collector enabled and nothing frozen."""
    import gc

    from ocdsl.transcribe.pseudospectral import gc_frozen

    assert gc.isenabled() and gc.get_freeze_count() == 0
    with gc_frozen():
        assert gc.get_freeze_count() > 0
    assert gc.isenabled() and gc.get_freeze_count() == 0
    res = ocdsl.load(configs / "brachistochrone.yaml").solve()
    assert res.status == "optimal"
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_dropped_models_are_freed_by_the_next_build(configs):
    """Models handed to the oldest generation by the gc levers bypass CPython's trigger for
    full collections; the next build collects, so a process solving point after point does
    not keep every dropped model (they hold reference cycles)."""
    import weakref

    from ocdsl.api import compile_file
    from ocdsl.transcribe.guess import make_guess
    from ocdsl.transcribe.mesh import Mesh
    from ocdsl.transcribe.pseudospectral import build

    f = compile_file(configs / "brachistochrone.yaml")
    problem, method = f.problem, f.method

    def one_model():
        meshes = {ph.name: Mesh.uniform(method.transcription, 20, 4) for ph in problem.phases}
        guesses = {ph.name: make_guess(problem, ph, None) for ph in problem.phases}
        return build(problem, meshes, guesses).model

    refs = []
    for _ in range(3):
        model = one_model()
        refs.append(weakref.ref(model))
        del model
    assert refs[0]() is None and refs[1]() is None, "dropped models are still alive"
