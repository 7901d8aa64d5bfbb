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
