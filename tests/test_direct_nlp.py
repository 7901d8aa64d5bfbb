"""The direct (NumPy) evaluation of a pseudospectral NLP is the PyNumero/ASL one.

``ocdsl.transcribe.direct_nlp`` must give, at any point, the same objective, gradient,
constraint residuals, Jacobian and Lagrangian Hessian as PyNumero reads from Pyomo's NL file,
and Ipopt on it the same optimum as the plain route. Not timed (the bench measures speed).
"""
import numpy as np
import pytest
import scipy.sparse as sps

import ocdsl
from ocdsl.api import compile_file
from ocdsl.transcribe import direct_nlp, pseudospectral
from ocdsl.transcribe.guess import make_guess
from ocdsl.transcribe.mesh import Mesh

pytestmark = pytest.mark.ipopt

# every pseudospectral file in configs/ (the others are flat, parametric or feedback methods)
PSEUDOSPECTRAL = ["brachistochrone", "bryson_denham", "double_integrator", "goddard", "mesh_bryson_denham",
                  "mesh_double_integrator", "mesh_goddard", "mesh_moon_landing", "min_time_to_climb",
                  "minimal_double_integrator",
                  "moon_landing", "seed0_exact_euler", "seed0_rendezvous", "seed1_10N_optimal",
                  "seed4_two_burn_nlp", "seed4_unrestricted", "study_moon_landing_sweep",
                  "two_phase_double_integrator"]


def _built(configs, name, segments=3, transcription=None):
    file = compile_file(configs / f"{name}.yaml")
    problem, method = file.problem, file.method
    meshes = {ph.name: Mesh.uniform(transcription or method.transcription, segments, method.degree)
              for ph in problem.phases}
    guesses = {ph.name: make_guess(problem, ph) for ph in problem.phases}
    return pseudospectral.build(problem, meshes, guesses)


def _compare_with_pynumero(tr, trials=2):
    from ocdsl.solve import ipopt

    ipopt.check_available()

    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is not None, why
    ref = ipopt.pynumero_nlp(tr.model)
    col = {id(v): i for i, v in enumerate(nlp.variables)}
    row = {id(c): i for i, c in enumerate(nlp.rows)}
    vp = np.array([col[id(v)] for v in ref.get_pyomo_variables()])
    cp = np.array([row[id(c)] for c in ref.get_pyomo_constraints()])
    assert len(vp) == nlp.n and len(cp) == nlp.m
    # the NL writer moves constants between a row's body and its bounds: compare residuals
    lo, hi = ref.constraints_lb(), ref.constraints_ub()
    ref_side = np.where(np.isfinite(lo), lo, hi)
    own_side = np.where(nlp.gl > -1e19, nlp.gl, nlp.gu)[cp]
    rng = np.random.default_rng(3)
    for _ in range(trials):
        x = nlp.x0 * (1 + 0.05 * rng.standard_normal(nlp.n)) + 0.01 * rng.standard_normal(nlp.n)
        lam, sigma = rng.standard_normal(nlp.m), 0.7
        ref.set_primals(x[vp])
        ref.set_duals(lam[cp])
        ref.set_obj_factor(sigma)

        def close(a, b):
            a, b = np.asarray(a, float), np.asarray(b, float)
            assert np.max(np.abs(a - b), initial=0.0) <= 1e-9 * max(1.0, np.max(np.abs(b), initial=0.0))

        close(nlp.objective(x), ref.evaluate_objective())
        close(nlp.gradient(x)[vp], ref.evaluate_grad_objective())
        close(nlp.constraints(x)[cp] - own_side, ref.evaluate_constraints() - ref_side)
        J = sps.coo_matrix((nlp.jacobian(x), nlp.jacobianstructure()), shape=(nlp.m, nlp.n)).tocsr()[cp][:, vp]
        close(J.toarray(), ref.evaluate_jacobian().toarray())
        lower = sps.coo_matrix((nlp.hessian(x, lam, sigma), nlp.hessianstructure()), shape=(nlp.n, nlp.n))
        H = (lower + sps.triu(lower.T, k=1)).tocsr()[vp][:, vp]
        close(H.toarray(), ref.evaluate_hessian_lag().toarray())
    return nlp


@pytest.mark.parametrize("name", PSEUDOSPECTRAL)
def test_direct_evaluation_equals_pynumero(configs, name):
    _compare_with_pynumero(_built(configs, name))


def test_generated_derivatives_of_table_ramps_and_safe_exp_match_finite_differences():
    """The tables' truncated powers r1..r3 (max(z, 0)**p) and safe_exp on the direct route:
    the generated values are the functions', the first and second derivatives those of
    central differences of the generated values and first derivatives, on both sides of
    each kink and at random points."""
    import sympy as sp

    from ocdsl.symbolic.numbers import safe_exp
    from ocdsl.symbolic.tables import r1, r2, r3

    x, y = sp.symbols("x y", real=True)
    exprs = [3 * r3(x - 0.2) - 2 * r3(0.5 - x) * y, r2(y - 0.1) * x + r2(x * y + 0.3),
             2 * safe_exp(x * y - 0.5), r3(x * y - 0.1) + sp.sin(x)]
    g = direct_nlp._generated(exprs, [x, y])
    values, first, second = (direct_nlp._function(g[k]) for k in ("values", "first", "second"))
    jac, hess = np.array(g["jac"]).reshape(-1, 2), np.array(g["hess"]).reshape(-1, 3)
    rng = np.random.default_rng(5)
    pts = np.concatenate([rng.uniform(-1, 1, (2, 40)),
                          np.array([[0.2 - 1e-3, 0.2 + 1e-3, 0.5 - 1e-3, 0.5 + 1e-3], [0.7, -0.4, 0.9, 1.1]])], axis=1)
    direct_nlp._check_smooth(exprs, "test")
    with pytest.raises(direct_nlp.Unsupported, match="r1"):      # its second derivative is a delta
        direct_nlp._check_smooth([r1(x) * y], "test")
    exact = sp.lambdify([x, y], [e.replace(
        lambda f: isinstance(f, (r1, r2, r3)), lambda f: sp.Max(f.args[0], 0) ** f.power).replace(
        safe_exp, sp.exp) for e in exprs], "numpy")

    def val(p):
        return values(p[0], p[1], np.empty((len(exprs), p.shape[1])))

    def fir(p):
        return first(p[0], p[1], np.empty((len(jac), p.shape[1])))
    assert np.allclose(val(pts), np.array(exact(*pts), float), rtol=1e-13, atol=1e-15)
    h = 1e-6
    for k, (o, a) in enumerate(jac):
        e = np.zeros((2, 1))
        e[a] = h
        fd = (val(pts + e)[o] - val(pts - e)[o]) / (2 * h)
        assert np.allclose(fir(pts)[k], fd, rtol=1e-6, atol=1e-7), (o, a)
    dense = {(o, a): k for k, (o, a) in enumerate(jac)}
    sec = second(pts[0], pts[1], np.empty((len(hess), pts.shape[1])))
    for k, (o, a, b) in enumerate(hess):
        e = np.zeros((2, 1))
        e[b] = h
        fd = (fir(pts + e)[dense[(o, a)]] - fir(pts - e)[dense[(o, a)]]) / (2 * h)
        assert np.allclose(sec[k], fd, rtol=1e-5, atol=1e-6), (o, a, b)
    assert len(hess) >= 6


def test_tables_and_safe_exp_take_the_direct_route(configs):
    """min_time_to_climb (tables: r3 splines) is no longer refused by the direct route."""
    tr = _built(configs, "min_time_to_climb")
    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is not None, why


@pytest.mark.parametrize("scheme", ["LG", "LGL", "LGR"])
def test_direct_evaluation_equals_pynumero_per_scheme(configs, scheme):
    """LG's end equations and LGL's integral form, with a Lagrange cost and a free final time."""
    _compare_with_pynumero(_built(configs, "moon_landing", segments=4, transcription=scheme))
    _compare_with_pynumero(_built(configs, "two_phase_double_integrator", segments=4, transcription=scheme))


# seed 4's unrestricted bang-off-bang run on its 40 x 6 mesh: J moves 1.7e-5 when the mesh is
# bisected (its switches fall inside segments), so the run is that mesh's optimum
FIXED_MESH_OPTIMUM = {"seed4_unrestricted"}


def _solve(configs, name, direct: bool, monkeypatch):
    monkeypatch.setitem(pseudospectral.FAST, "direct_nlp", direct)
    res = ocdsl.load(configs / f"{name}.yaml").solve()
    assert res.status == ("mesh_not_converged" if name in FIXED_MESH_OPTIMUM else "optimal"), res.message
    return res


@pytest.mark.parametrize("name", ["brachistochrone", "moon_landing", "two_phase_double_integrator",
                                  "seed4_unrestricted", "mesh_bryson_denham", "goddard"])
def test_direct_route_same_optimum(configs, name, monkeypatch):
    # a mesh run whose switches end as NLP unknowns (mesh_moon_landing) has its last solve on
    # the PyNumero route either way (DirectNLP declines free breakpoints): a fixed-time one here
    plain = _solve(configs, name, False, monkeypatch)
    fast = _solve(configs, name, True, monkeypatch)
    assert plain.nlp["evaluation"].startswith("PyNumero")
    assert fast.nlp["evaluation"].startswith("direct"), fast.nlp["evaluation"]
    assert fast.objective == pytest.approx(plain.objective, rel=1e-8, abs=1e-10)
    assert fast.nlp["variables"] == plain.nlp["variables"]
    assert fast.nlp["constraints"] == plain.nlp["constraints"]
    for ph in plain.phases:
        other = fast.phase(ph.name)
        for s in ph.states:
            assert other.states[s] == pytest.approx(ph.states[s], rel=1e-6, abs=1e-6)
        # duals loaded into the model: the costates agree
        for s in ph.costates or {}:
            assert other.costates[s] == pytest.approx(ph.costates[s], rel=1e-4, abs=1e-4)


def test_direct_route_takes_added_linear_rows_only(configs):
    import pyomo.environ as pyo

    tr = _built(configs, "brachistochrone")
    X = tr.model.phase_main.X
    # a linear row added after the build (as mesh refinement's junctions) is taken, constant and all
    tr.model.added = pyo.Constraint(expr=2.0 * X[1, 0] - X[2, 1] + 0.5 >= -10.0)
    nlp = _compare_with_pynumero(tr)
    assert nlp.m == len(tr.phases[0].defects) + 1
    tr.model.nonlinear = pyo.Constraint(expr=X[1, 0] * X[2, 1] >= -10.0)
    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is None and "nonlinear" in why
    tr.model.nonlinear.deactivate()
    # a term added to the built objective other than by the regularisation is PyNumero's
    before = tr.model.objective.expr
    tr.model.objective.expr = before + 1e-3 * X[1, 0] ** 2
    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is None and "objective was changed" in why
    tr.model.objective.expr = before
    assert direct_nlp.DirectNLP.of(tr)[0] is not None
    # also when the term is added before the first solve (mesh refinement regularises a
    # freshly built mesh)
    fresh = _built(configs, "brachistochrone")
    fresh.model.objective.expr = fresh.model.objective.expr + 1e-3 * fresh.model.phase_main.X[1, 0] ** 2
    nlp, why = direct_nlp.DirectNLP.of(fresh)
    assert nlp is None and "objective was changed" in why
    tr.phases[0].block.defect[0, 0, 0].deactivate()
    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is None and "no longer active" in why



@pytest.mark.parametrize("name", ["brachistochrone", "mesh_goddard"])      # minimised, maximised
def test_regularised_objective_is_evaluated_directly_as_pynumero_does(configs, name):
    """Mesh refinement's regularisation w * sum (u_{i+1} - u_i)^2 / ds (solve/mesh/regularise.py)
    is taken by the direct route (it sent each regularised mesh through the NL writer and
    ASL: Goddard's solves 1.4 -> 0.35 s): objective, gradient and Hessian equal PyNumero's,
    with both objective senses."""
    from ocdsl.solve.mesh.regularise import regularise

    tr = _built(configs, name, segments=4)
    assert regularise(tr, {tr.phases[0].phase.name: [(-0.6, 0.9)]}, 0.3) is not None
    nlp = _compare_with_pynumero(tr)
    assert len(nlp._pen_c) > 0
    # a term the regularisation did not make still declines the route
    tr.model.objective.expr = tr.model.objective.expr + 1e-3 * tr.model.phase_main.U[1, 0] ** 2
    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is None and "objective was changed" in why


TANK = """name: Draining tank
model:
  states: [h]
  controls: [q]
  dynamics:
    h: q - sqrt(h)
problem:
  time: {t0: 0, tf: 2}
  constraints:
    - 0 <= q <= 1
    - h(t0) == 1
  objective: minimize integral(q**2) + (h(tf) - 0.2)**2
method: {transcription: LGR, segments: 8, degree: 4}
"""
# (4 x 3 was `optimal` 1.7e-4 above this mesh's J until a control not flown counted as
# judging J; its bisection now says mesh_not_converged, unseen53 F1)


def test_a_node_function_outside_its_domain_is_an_evaluation_error(tmp_path):
    """sqrt of a negative level: Ipopt must get its evaluation error (it then cuts the step
    back), not NaNs, as on the PyNumero route."""
    import cyipopt

    path = tmp_path / "tank.yaml"
    path.write_text(TANK)
    file = compile_file(path)
    problem, method = file.problem, file.method
    meshes = {ph.name: Mesh.uniform(method.transcription, method.segments, method.degree) for ph in problem.phases}
    tr = pseudospectral.build(problem, meshes, {ph.name: make_guess(problem, ph) for ph in problem.phases})
    nlp, why = direct_nlp.DirectNLP.of(tr)
    assert nlp is not None, why
    x = np.abs(nlp.x0) + 0.1
    assert np.all(np.isfinite(nlp.constraints(x)))
    x[:] = -0.5
    for call in (nlp.constraints, nlp.jacobian, lambda y: nlp.hessian(y, np.ones(nlp.m), 1.0)):
        with pytest.raises(cyipopt.CyIpoptEvaluationError):
            call(x)
    res = ocdsl.load(path).solve()
    assert res.status == "optimal" and res.nlp["evaluation"].startswith("direct")


@pytest.mark.parametrize("name", ["seed0_rendezvous", "two_phase_double_integrator", "moon_landing"])
def test_evaluation_buffers_are_not_stale_or_shared(configs, name):
    """The evaluations write into buffers kept by the NLP (values, first and second derivatives,
    the Hessian's multipliers): interleaved calls at alternating points and multipliers give,
    entry for entry, what a fresh NLP gives at each point, and two NLPs of one model do not share
    them. Seed 0 at its own 20-segment mesh takes the C route."""
    file = compile_file(configs / f"{name}.yaml")
    tr = _built(configs, name, segments=file.method.segments)
    a = _compare_with_pynumero(tr, trials=1)
    b, _ = direct_nlp.DirectNLP.of(tr)
    rng = np.random.default_rng(5)
    points = [(a.x0 * (1 + 0.05 * rng.standard_normal(a.n)) + 0.01 * rng.standard_normal(a.n),
               rng.standard_normal(a.m), float(rng.uniform(0.1, 2.0))) for _ in range(3)]

    def all_of(nlp, x, lam, sigma):
        return [np.atleast_1d(nlp.objective(x)), nlp.gradient(x), nlp.constraint_values(x), nlp.jacobian(x),
                nlp.hessian(x, lam, sigma)]

    expected = []
    for x, lam, sigma in points:
        fresh, _ = direct_nlp.DirectNLP.of(tr)
        expected.append(all_of(fresh, x, lam, sigma))
    for k in (0, 1, 0, 2, 2, 1):
        x, lam, sigma = points[k]
        b.hessian(points[(k + 1) % 3][0], points[(k + 1) % 3][1], 0.3)   # the other NLP, elsewhere
        got = [a.hessian(x, lam, sigma), np.atleast_1d(a.objective(x)), a.jacobian(x), a.gradient(x),
               a.constraint_values(x)]
        want = expected[k]
        for g, w in zip(got, [want[4], want[0], want[3], want[1], want[2]]):
            assert np.array_equal(g, w)
