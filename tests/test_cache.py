"""The disk cache of generated NLP code (ocdsl/cache.py, used by ocdsl/transcribe/direct_nlp/).

A second compile of the same problem reads every family from the cache and does not
differentiate; a changed expression or ocdsl version misses; a corrupt entry is ignored and
rewritten; two processes writing the same entries at once leave valid entries and no
temporary files; the NLP's values, Jacobian and Hessian, and a whole solve, are the same
with and without the cache; ``--no-cache`` neither reads nor writes it.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ocdsl import cache
from ocdsl.api import compile_file
from ocdsl.transcribe import direct_nlp, pseudospectral
from ocdsl.transcribe.guess import make_guess
from ocdsl.transcribe.mesh import Mesh

pytestmark = pytest.mark.ipopt


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_DIR, str(d))
    monkeypatch.delenv(cache.ENV_OFF, raising=False)
    return d


def _nlp(path, segments=4):
    """A fresh compile (new Phase objects, so nothing is reused in memory) and its DirectNLP."""
    file = compile_file(path)
    meshes = {ph.name: Mesh.uniform(file.method.transcription, segments, file.method.degree)
              for ph in file.problem.phases}
    guesses = {ph.name: make_guess(file.problem, ph) for ph in file.problem.phases}
    nlp, why = direct_nlp.DirectNLP.of(pseudospectral.build(file.problem, meshes, guesses))
    assert nlp is not None, why
    return nlp


def _entries(d):
    return sorted(p.name for p in (d / "nlp").glob("*.json"))


@pytest.fixture
def counted(monkeypatch):
    """How many times differentiation ran."""
    calls = []
    real = direct_nlp.derivatives_cse

    def spy(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(direct_nlp.codegen, "derivatives_cse", spy)   # where _generated looks it up
    return calls


def _evaluate(nlp, seed=0):
    rng = np.random.default_rng(seed)
    x = nlp.x0 * (1 + 0.05 * rng.standard_normal(nlp.n)) + 0.01 * rng.standard_normal(nlp.n)
    lam = rng.standard_normal(nlp.m)
    return [nlp.objective(x), nlp.gradient(x), nlp.constraints(x), nlp.jacobian(x), nlp.hessian(x, lam, 0.7),
            nlp.jacobianstructure()[0], nlp.hessianstructure()[1]]


def test_second_compile_reads_the_cache_and_does_not_differentiate(configs, cache_dir, counted):
    _nlp(configs / "bryson_denham.yaml")
    first = len(counted)
    written = _entries(cache_dir)
    assert first >= 2 and len(written) == first          # one entry per differentiated family
    _nlp(configs / "bryson_denham.yaml")
    assert len(counted) == first                        # nothing differentiated again
    assert _entries(cache_dir) == written


def test_changed_dynamics_and_version_miss(configs, cache_dir, counted, tmp_path, monkeypatch):
    src = (configs / "brachistochrone.yaml").read_text()
    _nlp(configs / "brachistochrone.yaml")
    n0, e0 = len(counted), set(_entries(cache_dir))
    # another gravity: other dynamics expressions, another key for them
    changed = tmp_path / "brach_g.yaml"
    assert "g: 9.80665" in src
    changed.write_text(src.replace("g: 9.80665", "g: 9.8"))
    _nlp(changed)
    assert len(counted) > n0 and set(_entries(cache_dir)) > e0
    # another ocdsl version: every entry misses
    n1, e1 = len(counted), set(_entries(cache_dir))
    import ocdsl

    monkeypatch.setattr(ocdsl, "__version__", ocdsl.__version__ + ".test")
    monkeypatch.setattr(direct_nlp.codegen, "_GENERATOR", [])
    _nlp(configs / "brachistochrone.yaml")
    assert len(counted) - n1 == n0 and len(set(_entries(cache_dir)) - e1) == n0


def test_corrupt_entry_is_ignored_and_rewritten(configs, cache_dir, counted):
    _nlp(configs / "double_integrator.yaml")
    n0 = len(counted)
    victim = cache_dir / "nlp" / _entries(cache_dir)[0]
    victim.write_text('{"n_out": ')                    # a torn write, as if no rename had been used
    _nlp(configs / "double_integrator.yaml")
    assert len(counted) == n0 + 1
    assert isinstance(json.loads(victim.read_text()), dict)


_CHILD = """
import sys
from pathlib import Path
sys.path.insert(0, {tests!r})
from test_cache import _nlp
nlp = _nlp(Path({path!r}), segments=3)
print("OK", nlp.n)
"""


def test_two_processes_writing_the_same_entries(configs, cache_dir):
    code = _CHILD.format(tests=os.path.dirname(__file__), path=str(configs / "moon_landing.yaml"))
    env = {**os.environ, cache.ENV_DIR: str(cache_dir)}
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err[-2000:]
        assert out.startswith("OK")
    names = _entries(cache_dir)
    assert names and not [p for p in (cache_dir / "nlp").iterdir() if p.suffix != ".json"]
    for n in names:
        entry = json.loads((cache_dir / "nlp" / n).read_text())
        assert entry["n_out"] >= 1 and "values" in entry


def test_results_are_identical_with_and_without_the_cache(configs, cache_dir, monkeypatch):
    path = configs / "goddard.yaml"
    monkeypatch.setenv(cache.ENV_OFF, "1")
    off = _evaluate(_nlp(path))
    assert not (cache_dir / "nlp").exists() or not _entries(cache_dir)
    monkeypatch.delenv(cache.ENV_OFF)
    cold = _evaluate(_nlp(path))
    assert _entries(cache_dir)
    warm = _evaluate(_nlp(path))
    for a, b, c in zip(off, cold, warm):
        assert np.array_equal(a, b) and np.array_equal(a, c)


def test_solve_identical_and_no_cache_flag(configs, cache_dir, tmp_path):
    from click.testing import CliRunner

    from ocdsl.cli import main

    runner = CliRunner()
    path = str(configs / "brachistochrone.yaml")
    r = runner.invoke(main, ["run", path, "--out", str(tmp_path / "off"), "-q", "--no-cache"])
    assert r.exit_code == 0, r.output
    assert not (cache_dir / "nlp").exists() or not _entries(cache_dir)
    os.environ.pop(cache.ENV_OFF, None)            # the flag sets it for the process
    for name in ("cold", "warm"):
        r = runner.invoke(main, ["run", path, "--out", str(tmp_path / name), "-q"])
        assert r.exit_code == 0, r.output
    assert _entries(cache_dir)
    rows = {n: (tmp_path / n / "trajectory.csv").read_text() for n in ("off", "cold", "warm")}
    assert rows["off"] == rows["cold"] == rows["warm"]
    objs = {n: json.loads((tmp_path / n / "result.json").read_text())["objective"] for n in rows}
    assert objs["off"] == objs["cold"] == objs["warm"]


def test_long_families_compiled_to_c_cached_and_equal_to_numpy(configs, cache_dir, counted, monkeypatch):
    """Seed 0's dynamics (a source past native.MIN_LINES) are evaluated in C: its shared
    library is cached beside the JSON entry, a second compile reads both (no differentiation,
    identical values), and without the cache the values are the same too; without a compiler the same entry is evaluated by NumPy, equal to
    rounding, and the NLP says so."""
    from ocdsl.transcribe.direct_nlp import native

    if native._compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setattr(native, "_LOADED", {})      # libraries loaded by earlier tests of this process
    path = configs / "seed0_rendezvous.yaml"
    cold = _nlp(path, segments=3)
    assert cold.info()["evaluation"] == "direct (C)"
    assert list((cache_dir / "nlp").glob("*.so"))
    n = len(counted)
    warm = _nlp(path, segments=3)
    assert len(counted) == n and warm.info()["evaluation"] == "direct (C)"
    a, b = _evaluate(cold), _evaluate(warm)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    monkeypatch.setenv(cache.ENV_OFF, "1")           # compiled in a temporary folder, nothing kept
    before = sorted((cache_dir / "nlp").iterdir())
    off = _nlp(path, segments=3)
    assert off.info()["evaluation"] == "direct (C)" and sorted((cache_dir / "nlp").iterdir()) == before
    assert all(np.array_equal(x, y) for x, y in zip(a, _evaluate(off)))
    monkeypatch.delenv(cache.ENV_OFF)
    monkeypatch.setenv("CC", str(cache_dir / "no-such-compiler"))
    plain = _nlp(path, segments=3)
    assert plain.info()["evaluation"].startswith("direct (NumPy: C compile failed")
    for x, y in zip(a, _evaluate(plain)):
        assert np.allclose(x, y, rtol=1e-12, atol=1e-12 * max(1.0, np.max(np.abs(x), initial=0.0)))
