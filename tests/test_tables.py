"""Interpolation tables (ocdsl/symbolic/tables.py, the `tables:` block): the SymPy spline is
SciPy's interpolant, twice continuously differentiable, evaluates alike in NumPy and Pyomo,
is usable in dynamics, named expressions and path constraints, and bad tables are errors at
their lines."""
import textwrap

import numpy as np
import pytest
import sympy as sp
from scipy.interpolate import CubicSpline

from ocdsl.spec.compile import load
from ocdsl.spec.errors import SpecError
from ocdsl.symbolic.tables import Table

MACH = [0, 0.4, 0.8, 0.9, 1.0, 1.2, 1.4, 1.6, 1.8]
CD0 = [0.013, 0.013, 0.013, 0.014, 0.031, 0.041, 0.039, 0.036, 0.035]


@pytest.mark.parametrize("bc", ["not-a-knot", "natural"])
def test_1d_table_is_scipys_cubic_spline(bc):
    x = np.linspace(-0.1, 1.9, 801)       # beyond both ends too: the end cubics continue
    got = Table.build("cd0", [MACH], CD0, bc).evaluate(x)
    assert np.max(np.abs(got - CubicSpline(MACH, CD0, bc_type=bc)(x))) < 1e-13


def test_2d_table_is_the_tensor_product_of_1d_splines():
    gx, gy = np.linspace(0, 1.8, 10), np.array([0, 5, 10, 15, 20, 25, 30, 40, 50, 70.0])
    V = 20 + 10 * np.sin(gx)[:, None] * np.cos(gy / 30)[None, :] + 0.1 * gy[None, :]
    a = np.random.default_rng(1).uniform(0, 1.8, 60)
    b = np.random.default_rng(2).uniform(0, 70, 60)
    ref = [CubicSpline(gx, CubicSpline(gy, V, axis=1)(bb))(aa) for aa, bb in zip(a, b)]
    assert np.max(np.abs(Table.build("t", [gx, gy], V).evaluate(a, b) - ref)) < 1e-10 * np.abs(V).max()


def test_spline_is_c2_across_its_knots():
    x = sp.Symbol("x", real=True)
    e = Table.build("cd0", [MACH], CD0)(x)
    d1, d2 = [sp.lambdify([x], sp.diff(e, x, k), "numpy") for k in (1, 2)]
    for knot in MACH[1:-1]:
        for f in (d1, d2):
            assert abs(f(knot - 1e-9) - f(knot + 1e-9)) < 1e-5
    # the third derivative jumps (a cubic spline is C2, not C3): the test can tell
    d3 = sp.lambdify([x], sp.diff(e, x, 3), "numpy")
    assert abs(d3(1.0 - 1e-6) - d3(1.0 + 1e-6)) > 1.0


def test_pyomo_and_numpy_agree():
    import pyomo.environ as pyo

    from ocdsl.transcribe.pyomo_expr import pyomo_function

    x = sp.Symbol("x", real=True)
    e = Table.build("cd0", [MACH], CD0)(x)
    m = pyo.ConcreteModel()
    m.x = pyo.Var(initialize=0.95)
    (expr,) = pyomo_function([x], [e])(m.x)
    assert pyo.value(expr) == pytest.approx(float(CubicSpline(MACH, CD0)(0.95)), rel=1e-12)


def _write(tmp_path, body: str, csv: str | None = None):
    if csv is not None:
        (tmp_path / "data.csv").write_text(csv)
    p = tmp_path / "p.yaml"
    p.write_text(textwrap.dedent(body))
    return p


BASE = """\
name: table use
tables:
  lin: {x: [-2, -1, 0, 1, 2], values: [-2, -1, 0, 1, 2]}
  cube: {csv: data.csv, x: v, values: v3}
model:
  states: [x, v]
  controls: [u]
  expressions: {a: lin(u)}
  dynamics: {x: v, v: a}
problem:
  time: {t0: 0, tf: free}
  constraints: [-1 <= u <= 1, cube(v) <= 8, x(t0) == -1, v(t0) == 0, x(tf) == 0, v(tf) == 0, 0.5 <= tf <= 5]
  objective: minimize tf
  guess: {tf: 2.5}
method: {transcription: LGR, segments: 10, degree: 4}
"""
CSV = "v,v3\n" + "\n".join(f"{v},{v**3}" for v in range(-3, 4)) + "\n"


def test_tables_in_expressions_dynamics_and_path_constraints(tmp_path):
    f = load(_write(tmp_path, BASE, CSV))
    ph = f.problem.phases[0]
    assert len(ph.path) == 1
    v = ph.model.symbol("v")
    # a cubic through a cubic's samples is that cubic (not-a-knot): the table is v**3 exactly
    g = sp.lambdify([v], ph.path[0].expr, "numpy")
    assert g(1.7) == pytest.approx(1.7**3, rel=1e-12)
    # the report shows the call, not the spline's expansion
    assert f.problem.description["phases"]["main"]["expressions_latex"]["a"] == r"\operatorname{lin}{\left(u \right)}"


@pytest.mark.ipopt
def test_a_problem_with_tables_solves_to_the_analytic_optimum(tmp_path):
    from ocdsl.api import load as api_load

    res = api_load(str(_write(tmp_path, BASE, CSV))).solve()
    assert res.status == "optimal"
    assert res.tf == pytest.approx(2.0, rel=1e-6)       # min-time double integrator: tf = 2
    assert res.verification["status"] == "verified"


@pytest.mark.parametrize("change, csv, message", [
    ("lin: {x: [-2, -1, 0, 1, 2], values: [-2, -1, 0, 1]}", CSV, "values have shape [4], the grid needs [5]"),
    ("lin: {x: [-2, -1, 0, 0, 2], values: [-2, -1, 0, 1, 2]}", CSV, "strictly increasing"),
    ("lin: {x: [-2, -1, 0, 1, 2], y: [0, 1], values: [-2, -1, 0, 1, 2]}", CSV, "one row per x"),
    ("lin: {csv: data.csv, x: vv, values: v3}", CSV, "has no column 'vv' (did you mean 'v'?)"),
    ("lin: {csv: nothere.csv, x: v, values: v3}", CSV, "table file 'nothere.csv' not found"),
    ("lin: {csv: data.csv, x: v, values: v3}", "v,v3\n1,x\n", "'x' in column 'v3' is not a number"),
])
def test_bad_tables_are_errors_at_their_lines(tmp_path, change, csv, message):
    body = BASE.replace("lin: {x: [-2, -1, 0, 1, 2], values: [-2, -1, 0, 1, 2]}", change)
    with pytest.raises(SpecError) as e:
        load(_write(tmp_path, body, csv))
    text = str(e.value)
    assert message in text and "p.yaml:3:" in text


def test_wrong_arity_and_unknown_table_name_the_expression(tmp_path):
    body = BASE.replace("a: lin(u)", "a: 'lin(u, u)'")
    with pytest.raises(SpecError, match=r"p.yaml:\d+: table 'lin' takes 1 argument, got 2"):
        load(_write(tmp_path, body, CSV))
    body = BASE.replace("a: lin(u)", "a: lni(u)")
    with pytest.raises(SpecError, match=r"unknown function 'lni' \(did you mean 'lin'\?\)"):
        load(_write(tmp_path, body, CSV))


def test_2d_csv_must_be_a_full_grid(tmp_path):
    body = BASE.replace("cube: {csv: data.csv, x: v, values: v3}",
                        "cube: {csv: data.csv, x: v, values: v3}\n  g2: {csv: grid.csv, x: a, y: b, values: f}")
    (tmp_path / "grid.csv").write_text("a,b,f\n0,0,1\n0,1,2\n1,0,3\n")
    with pytest.raises(SpecError, match=r"not a full grid: no row for \(a, b\) = \(1, 1\)"):
        load(_write(tmp_path, body, CSV))
    (tmp_path / "grid.csv").write_text("a,b,f\n0,0,1\n0,1,2\n1,0,3\n1,1,5\n")
    load(_write(tmp_path, body, CSV))


@pytest.mark.slow
@pytest.mark.ipopt
def test_min_time_to_climb_reaches_the_published_time(tmp_path):
    """configs/min_time_to_climb.yaml: Bryson's climb with tabulated thrust (bicubic),
    aerodynamics and atmosphere (CSV), 321.0 s in dymos' tests (to 2e-2)."""
    from conftest import ROOT
    from ocdsl.api import run_file

    res = run_file(ROOT / "configs" / "min_time_to_climb.yaml", tmp_path / "run")
    assert res.status == "optimal"
    assert res.verification["status"] == "verified", res.verification.get("summary")
    assert all(c["passed"] for c in res.expect)
    assert res.tf == pytest.approx(321.0, rel=2e-2)
