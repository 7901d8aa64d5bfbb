"""Ipopt's C interface through ctypes (ocdsl/solve/ipopt_c.py) is cyipopt's Problem without its
element-wise copies: on the same NLP, options and library it takes the same iterations to the
same point and multipliers, bit for bit; an exception in a callback is raised after the solve;
an evaluation error makes Ipopt cut its step back. The library is CasADi's newer build where
installed (a dependency), cyipopt's otherwise, or the one OCDSL_IPOPT_LIBRARY names; a run
records which."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ocdsl.api import compile_file
from ocdsl.solve import ipopt, ipopt_c
from ocdsl.transcribe import direct_nlp, pseudospectral
from ocdsl.transcribe.guess import make_guess
from ocdsl.transcribe.mesh import Mesh

pytestmark = pytest.mark.ipopt


def _nlp(configs, name="brachistochrone", segments=6):
    file = compile_file(configs / f"{name}.yaml")
    meshes = {ph.name: Mesh.uniform(file.method.transcription, segments, file.method.degree)
              for ph in file.problem.phases}
    guesses = {ph.name: make_guess(file.problem, ph) for ph in file.problem.phases}
    nlp, why = direct_nlp.DirectNLP.of(pseudospectral.build(file.problem, meshes, guesses))
    assert nlp is not None, why
    return nlp


def _solve(make, nlp, iterations):
    nlp.intermediate = lambda *a: iterations.append(a[1]) or True    # before: cyipopt binds it then
    problem = make(nlp)
    for k, v in {**ipopt.DEFAULT_OPTIONS, "print_level": 0, "sb": "yes"}.items():
        problem.add_option(k, v)
    try:
        return problem.solve(nlp.x0)
    finally:
        problem.close()


def test_same_iterates_as_cyipopt(configs):
    import cyipopt

    assert ipopt_c.available()
    nlp = _nlp(configs)
    it_ref, it_own = [], []
    ref = _solve(lambda p: cyipopt.Problem(n=p.n, m=p.m, problem_obj=p, lb=p.xl, ub=p.xu, cl=p.gl, cu=p.gu),
                 nlp, it_ref)
    own = _solve(lambda p: ipopt_c.Problem(p, library=ipopt_c._cyipopt_library()), nlp, it_own)
    assert it_ref == it_own and len(it_own) > 5
    assert ref[1]["status"] == own[1]["status"] == 0 and ref[1]["status_msg"] == own[1]["status_msg"]
    for k in ("x", "mult_g", "mult_x_L", "mult_x_U"):
        assert np.array_equal(ref[1][k], own[1][k]), k


def test_a_callback_exception_is_raised_after_the_solve(configs):
    nlp = _nlp(configs)
    calls = []

    def broken(x, lagrange, obj_factor):
        calls.append(1)
        raise RuntimeError("hessian broke")

    nlp.hessian = broken
    with pytest.raises(RuntimeError, match="hessian broke"):
        _solve(ipopt_c.Problem, nlp, [])
    assert len(calls) == 1            # nothing evaluated after it


def test_an_evaluation_error_cuts_the_step_back(configs):
    import cyipopt

    nlp = _nlp(configs)
    real = nlp.constraints
    failed = []

    def picky(x):
        if len(failed) < 3 and np.any(x != nlp.x0):
            failed.append(1)
            raise cyipopt.CyIpoptEvaluationError("not here")
        return real(x)

    nlp.constraints = picky
    x, info = _solve(ipopt_c.Problem, nlp, [])
    assert len(failed) == 3 and info["status"] == 0


def test_casadis_build_is_the_default_and_reaches_the_same_optimum(configs):
    path, source = ipopt_c.library_choice()
    assert source == "casadi" and "casadi" in path      # installed with ocdsl
    assert ipopt_c.name().startswith("Ipopt 3.14.") and ipopt_c.name().endswith("(casadi)")
    import cyipopt

    assert ipopt_c.cyipopt_name() == f"Ipopt {'.'.join(map(str, cyipopt.IPOPT_VERSION))} (cyipopt)"
    nlp = _nlp(configs)
    ref = _solve(lambda p: ipopt_c.Problem(p, library=ipopt_c._cyipopt_library()), nlp, [])
    own = _solve(ipopt_c.Problem, _nlp(configs), [])
    assert ref[1]["status"] == own[1]["status"] == 0
    assert abs(ref[1]["obj_val"] - own[1]["obj_val"]) < 1e-9 * abs(ref[1]["obj_val"])
    assert np.allclose(ref[1]["x"], own[1]["x"], atol=1e-6)


def _run(configs, tmp_path, env):
    out = tmp_path / "run"
    p = subprocess.run([sys.executable, "-m", "ocdsl.cli", "run", str(configs / "double_integrator.yaml"),
                        "--out", str(out), "-q"], env={**os.environ, **env}, capture_output=True, text=True)
    return p, (json.loads((out / "result.json").read_text()) if (out / "result.json").exists() else None)


def test_a_run_records_its_library_and_the_environment_chooses_it(configs, tmp_path):
    p, result = _run(configs, tmp_path, {})
    assert p.returncode == 0 and result["nlp"]["ipopt"].endswith("(casadi)")
    cyipopts = subprocess.run([sys.executable, "-c", "from ocdsl.solve import ipopt_c; "
                               "print(ipopt_c._cyipopt_library())"], capture_output=True, text=True).stdout.strip()
    p, result = _run(configs, tmp_path, {ipopt_c.LIBRARY_ENV: cyipopts})
    assert p.returncode == 0 and result["nlp"]["ipopt"] == "Ipopt (OCDSL_IPOPT_LIBRARY)"   # 3.14.11 cannot tell its version
    assert result["tf"] == pytest.approx(2.0, rel=1e-6)


@pytest.mark.parametrize("library", ["nothing.so", "libm"])
def test_a_library_that_does_not_load_is_one_clear_error(configs, tmp_path, library):
    import ctypes.util

    path = str(tmp_path / library) if library.endswith(".so") else ctypes.util.find_library("m")
    p, result = _run(configs, tmp_path, {ipopt_c.LIBRARY_ENV: path})     # missing; not Ipopt
    assert p.returncode == 1 and "Traceback" not in p.stderr + p.stdout
    assert result["status"] == "error" and "OCDSL_IPOPT_LIBRARY" in result["message"]
