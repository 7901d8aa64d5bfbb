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
    # the evaluation route has its own tests (test_direct_nlp.py): its Jacobian pattern keeps
    # entries a fixed variable zeroes, which the NL writer folds, so nonzeros may differ by those
    monkeypatch.setitem(pseudospectral.FAST, "direct_nlp", False)
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


@pytest.mark.parametrize("limit", [0, 8_000])
def test_dropped_models_are_freed_by_the_next_build(configs, monkeypatch, limit):
    """Models handed to the oldest generation by the gc levers bypass CPython's trigger for
    full collections; the next build collects once more than COLLECT_AFTER objects were
    handed over since the last collection, so a process solving point after point does not
    keep every dropped model (they hold reference cycles). A 20 x 4 brachistochrone model
    is a few thousand objects: with the limit at 8,000 the third build has collected."""
    import weakref

    from ocdsl.api import compile_file
    from ocdsl.transcribe import pseudospectral
    from ocdsl.transcribe.guess import make_guess
    from ocdsl.transcribe.mesh import Mesh
    from ocdsl.transcribe.pseudospectral import build

    monkeypatch.setattr(pseudospectral, "COLLECT_AFTER", limit)

    f = compile_file(configs / "brachistochrone.yaml")
    problem, method = f.problem, f.method

    def one_model():
        meshes = {ph.name: Mesh.uniform(method.transcription, 20, 4) for ph in problem.phases}
        guesses = {ph.name: make_guess(problem, ph, None) for ph in problem.phases}
        return build(problem, meshes, guesses).model

    refs = []
    for _ in range(3 if limit == 0 else 6):
        model = one_model()
        refs.append(weakref.ref(model))
        del model
    assert refs[0]() is None and refs[1]() is None, "dropped models are still alive"


@pytest.mark.ipopt
@pytest.mark.parametrize("transcription", ["LGR", "flat-bspline"])
def test_lagrange_cost_with_free_time_keeps_the_hessian_sparse(configs, tmp_path, transcription):
    """A free final time times the quadrature of a Lagrange cost, written in front of the sum,
    made one nonlinear element of all the nodes' variables, whose ASL Hessian is dense
    (moon landing, 800 segments: 10.3 M nonzeros, solve 29 s; per node: 32 k, 2.6 s).
    The Hessian's nonzeros must grow linearly with the mesh. (The flat B-spline quadrature,
    an inline sum, was measured sparse before and after; the case guards it.)"""
    import yaml

    if transcription == "LGR":
        doc = yaml.safe_load((configs / "moon_landing.yaml").read_text())
        sizes, key = (20, 80), "segments"
    else:
        doc = {"name": "minimum time and energy, double integrator",
               "model": {"states": ["x", "v"], "controls": ["u"], "dynamics": {"x": "v", "v": "u"}},
               "problem": {"time": {"t0": 0, "tf": "free"},
                           "constraints": ["x(t0) == 0", "v(t0) == 0", "x(tf) == 1", "v(tf) == 0",
                                           "0.5 <= tf <= 5"],
                           "objective": "minimize tf + integral(u**2)"},
               "method": {"transcription": "flat-bspline", "degree": 5}}
        sizes, key = (20, 80), "control_points"
    doc.pop("expect", None)
    doc["verify"] = {"bisection_check": False}      # the mesh's own NLP is what is measured
    counts = []
    for n in sizes:
        doc["method"][key] = n
        if key == "control_points":
            doc["method"]["collocation_points"] = n
        path = tmp_path / f"{transcription}_{n}.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        res = ocdsl.load(path).solve()
        assert res.status == "optimal", res.message
        counts.append(res.nlp["hessian_nonzeros"])
    growth = sizes[1] / sizes[0]
    assert counts[1] < 1.2 * growth * counts[0], counts      # dense would be ~growth**2


@pytest.mark.ipopt
def test_console_entry_writes_the_whole_run_folder_and_keeps_exit_codes(configs, tmp_path):
    """The console script (ocdsl.serve.client.entry: ocdsl.cli.entry when no server runs)
    skips CPython's final collection; the run folder must still be complete and the exit
    codes unchanged."""
    import csv
    import json
    import subprocess
    import sys
    import tomllib

    scripts = tomllib.loads((configs.parent / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["ocdsl"] == "ocdsl.serve.client:entry"
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", "-q", str(configs / "brachistochrone.yaml"),
                           "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    result = json.loads((out / "result.json").read_text())
    assert result["status"] == "optimal"
    with open(out / "trajectory.csv") as f:
        rows = list(csv.reader(f))
    assert len(rows) > 10 and all(len(r) == len(rows[0]) for r in rows)
    bad = tmp_path / "bad.yaml"
    bad.write_text((configs / "brachistochrone.yaml").read_text().replace("dynamics:", "dynamics: [", 1))
    proc = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(bad), "--out", str(tmp_path / "b")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr


@pytest.mark.ipopt
def test_direct_route_runs_without_pyomo_environ(configs):
    """ocdsl imports pyomo.core only (levers.md section 20); pyomo.environ, whose plugins
    the NL writer and SolverFactory need, is imported by the PyNumero route when it runs."""
    import subprocess
    import sys

    code = (f"import sys, ocdsl; r = ocdsl.load({str(configs / 'moon_landing.yaml')!r}).solve(); "
            "print(r.status, r.nlp['evaluation'].split()[0], 'pyomo.environ' in sys.modules); "
            f"f = ocdsl.load({str(configs / 'seed2_strategy1.yaml')!r}); "
            "r = f.solve(); print(r.status, r.nlp['evaluation'].split()[0], 'pyomo.environ' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split("\n")[:2] == ["optimal direct False", "optimal PyNumero True"], out


def test_pyomo_functions_are_made_once_per_expression_set(monkeypatch):
    """A mesh refinement builds each phase once per mesh: the lambdified SymPy -> Pyomo
    functions are made once per (arguments, expressions) and reused, a different set gets
    its own."""
    import sympy as sp

    from ocdsl.transcribe import pyomo_expr

    made = []
    real = sp.lambdify
    monkeypatch.setattr(pyomo_expr, "_MADE", {})
    monkeypatch.setattr(sp, "lambdify", lambda *a, **k: made.append(a) or real(*a, **k))
    x, u = sp.symbols("x u")
    f = pyomo_expr.pyomo_function([x, u], [x * u, sp.sin(x)])
    assert pyomo_expr.pyomo_function([x, u], [x * u, sp.sin(x)]) is f
    g = pyomo_expr.pyomo_function([x, u], [x * u, sp.cos(x)])
    assert g is not f and len(made) == 2
    assert g(0.0, 2.0) == [0.0, 1.0]


def test_console_script_loads_blas_with_one_thread_unless_the_user_chose(monkeypatch):
    import os

    from ocdsl.serve import client

    for k in client.BLAS_THREADS:
        monkeypatch.delenv(k, raising=False)
    client.one_blas_thread()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
    monkeypatch.delenv("OPENBLAS_NUM_THREADS")
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    client.one_blas_thread()
    assert "OPENBLAS_NUM_THREADS" not in os.environ


def test_model_dynamics_substituted_once_per_parameter_values(monkeypatch):
    """``Model.rhs`` keeps its substitution per parameter values (a mesh refinement asks for
    it once per mesh); each call gets its own copy, so a caller's edit does not reach the next."""
    import sympy as sp

    from ocdsl.symbolic import numbers
    from ocdsl.symbolic.model import Model

    calls = []
    real = numbers.substitute_numbers
    monkeypatch.setattr(numbers, "substitute_numbers", lambda *a: calls.append(a) or real(*a))
    x, u, a = sp.symbols("x u a")
    model = Model("m", (x,), (u,), {x: a * x + u}, {a: 1.0})
    f = model.rhs({a: 2.0})
    f[0] = 0
    assert model.rhs({a: 2.0}) == sp.Matrix([2.0 * x + u])
    assert model.rhs({a: 3.0}) == sp.Matrix([3.0 * x + u])
    assert model.rhs() == sp.Matrix([a * x + u])
    assert len(calls) == 2
