"""Seed 0 main scenario with a small, independent Legendre-Gauss transcription (Pyomo +
cyipopt), to confirm that the model reproduces the paper's t_f and that the certificate
passes on a real pseudospectral solution. Slow: several seeded starts.

The transcription is Benson's multi-interval GPM (digest section 4): per segment the start
state X0 (shared with the previous segment's end), N LG nodes, collocation
sum_l D_kl X_l - (h/2) f(X_k, U_k) = 0 and the quadrature end state
X_F = X_0 + (h/2) sum_k w_k f(X_k, U_k); costates lambda_k = -(nu_k / w_k + nu_F) with
Pyomo/Ipopt's multiplier sign.
"""
import os

import numpy as np
import pytest
import sympy as sp

from ocdsl.solve.certificate import certificate
from ocdsl.symbolic.registry import build_model

pytestmark = [pytest.mark.slow, pytest.mark.ipopt]

BOUNDS = {"T1": (-50, 50), "T2": (-50, 50), "T3": (-50, 50),
          "F1": (-320, 320), "F2": (-320, 320), "F3": (-320, 320)}


def lg_differentiation(N):
    tau, w = np.polynomial.legendre.leggauss(N)
    pts = np.concatenate([[-1.0], tau])            # support: tau_0 = -1 and the LG nodes
    D = np.zeros((N, N + 1))
    for i in range(N + 1):
        others = np.delete(pts, i)
        denom = np.prod(pts[i] - others)
        poly = np.poly(others) / denom              # Lagrange basis L_i
        D[:, i] = np.polyval(np.polyder(poly), tau)
    return tau, w, D


def solve_lg(model, x0, xf, P=20, N=3, seed=0, tf_guess=30.0):
    os.environ.setdefault("PYOMO_CONFIG_DIR", "/work/main/.venv/share/pyomo")
    import pyomo.environ as pyo

    params = model.default_parameters()
    f = model.rhs(params)
    fun = sp.lambdify([model.states, model.controls], list(f), modules=[{"sqrt": pyo.sqrt}, "math"])
    n, m = model.n_states, model.n_controls
    tau, w, D = lg_differentiation(N)
    rng = np.random.default_rng(seed)

    M = pyo.ConcreteModel()
    M.tf = pyo.Var(bounds=(5, 100), initialize=tf_guess)
    M.XS = pyo.Var(range(P + 1), range(n))
    M.X = pyo.Var(range(P), range(N), range(n))
    ub = [BOUNDS[c.name][1] for c in model.controls]
    M.U = pyo.Var(range(P), range(N), range(m), bounds=lambda M, r, k, j: (-ub[j], ub[j]),
                  initialize=lambda M, r, k, j: rng.uniform(-ub[j], ub[j]))
    for r in range(P + 1):
        s = r / P
        for i in range(n):
            M.XS[r, i].value = (1 - s) * x0[i] + s * xf[i]
    for r in range(P):
        for k in range(N):
            s = (r + (tau[k] + 1) / 2) / P
            for i in range(n):
                M.X[r, k, i].value = (1 - s) * x0[i] + s * xf[i] + (0.01 * rng.normal() if i < 3 else 0)
    for i in range(n):
        M.XS[0, i].fix(x0[i])
        M.XS[P, i].fix(xf[i])

    F = {(r, k): fun([M.X[r, k, i] for i in range(n)], [M.U[r, k, j] for j in range(m)])
         for r in range(P) for k in range(N)}
    h = M.tf / P
    M.defect = pyo.Constraint(range(P), range(N), range(n), rule=lambda M, r, k, i: (
        D[k, 0] * M.XS[r, i] + sum(D[k, l + 1] * M.X[r, l, i] for l in range(N)) - h / 2 * F[r, k][i] == 0))
    M.end = pyo.Constraint(range(P), range(n), rule=lambda M, r, i: (
        M.XS[r + 1, i] - M.XS[r, i] - h / 2 * sum(w[k] * F[r, k][i] for k in range(N)) == 0))
    M.obj = pyo.Objective(expr=M.tf)
    M.dual = pyo.Suffix(direction=pyo.Suffix.IMPORT)
    solver = pyo.SolverFactory("cyipopt")
    solver.config.options.update({"tol": 1e-10, "max_iter": 3000, "print_level": 0, "mu_strategy": "adaptive"})
    res = solver.solve(M, load_solutions=False)
    ok = str(res.solver.termination_condition) == "optimal"
    if not ok:
        return None
    M.solutions.load_from(res)
    tf = pyo.value(M.tf)
    t = np.concatenate([(r + (tau + 1) / 2) * tf / P for r in range(P)])
    X = np.array([[pyo.value(M.X[r, k, i]) for i in range(n)] for r in range(P) for k in range(N)])
    U = np.array([[pyo.value(M.U[r, k, j]) for j in range(m)] for r in range(P) for k in range(N)])
    Lam = np.array([[-(M.dual[M.defect[r, k, i]] / w[k] + M.dual[M.end[r, i]]) for i in range(n)]
                    for r in range(P) for k in range(N)])
    names = [s.name for s in model.states]
    traj = {"time": t, "states": dict(zip(names, X.T)),
            "controls": {c.name: U[:, j] for j, c in enumerate(model.controls)},
            "costates": dict(zip(names, Lam.T))}
    return tf, traj, np.linspace(0, tf, P + 1), res


X0 = [0, 0, 0, 0, 0, 0, 0, 0, 0, 20, 0, 0]
XF = [0, 0, 0, 0, np.tan(np.pi / 8), 0, 0, 0, 0, 0, 0, -10]


@pytest.mark.parametrize("euler,reference", [("printed", 25.8727), ("exact", 25.8731)])
def test_main_scenario_reproduces_paper(euler, reference):
    model = build_model("rendezvous_6dof", {"euler": euler})
    runs = []
    for seed in range(6):
        out = solve_lg(model, X0, XF, seed=seed)
        if out is not None:
            runs.append((out[0], seed, out))
    assert len(runs) >= 3
    tf, seed, (_, traj, edges, _) = min(runs, key=lambda r: r[0])
    print("tf per seed:", [(s, round(t, 6)) for t, s, _ in runs])
    assert tf == pytest.approx(reference, abs=5e-4)
    cert = certificate(model, {}, traj, BOUNDS, 0, "min_tf")
    h, sw, bb = cert["hamiltonian"], cert["switching"], cert["bang_bang"]
    print("H mean/min/max", h["mean"], h["min"], h["max"], "agreement", sw["agreement"],
          "bang-bang", {k: (round(v["fraction_at_bound"], 3), v["switch_count"]) for k, v in bb["per_control"].items()})
    assert abs(h["mean"] + 1) <= 2e-3 and h["max_deviation"] <= 3e-2
    assert sw["agreement"] >= 0.99
    assert all(v["fraction_at_bound"] >= 0.95 for v in bb["per_control"].values())
    # the necessary conditions hold (the re-integration, about 1.3e-2 of the state range at
    # the switches at 20 x 3, is the verification's: tests/test_seed0_pipeline.py)
    assert cert["passed"], cert["failed"]
