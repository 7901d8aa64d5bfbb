"""Ipopt's C interface through ctypes (ocdsl/solve/ipopt_c.py) is cyipopt's Problem without its
element-wise copies: on the same NLP and options it takes the same iterations to the same
point and multipliers, bit for bit (the same library, fed the same numbers); an exception in a
callback is raised after the solve; an evaluation error makes Ipopt cut its step back."""
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
    own = _solve(ipopt_c.Problem, nlp, it_own)
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
