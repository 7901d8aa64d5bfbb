"""Quantities a report draws that an older or leaner run folder does not hold.

A run folder of a pseudospectral solve has the states, controls and costates at the nodes
and the copy of its problem file (``problem.yaml``), but not necessarily the Hamiltonian
``H = L + lambda^T f``, its control gradients ``dH/du`` (the switching functions) or the
re-integrated trajectory. :func:`complete_from_problem_file` compiles the copied problem
file (parse and SymPy only: nothing is solved) and evaluates them from the stored arrays,
with the same minimisation form as the run's optimality certificate
(:mod:`ocdsl.solve.certify`): ``L`` is the integrand weighted by the objective's
derivative in each integral, negated for ``maximize``. Everything here is optional: a
failure leaves the result as it was and returns a note.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ocdsl.result import Result

HAMILTONIAN_KEYS = ("H", "hamiltonian")


def _needs_hamiltonian(res: Result) -> bool:
    return any(p.costates and p.controls and not any(k in p.extra for k in HAMILTONIAN_KEYS)
               for p in res.phases)


def _needs_reintegration(res: Result) -> bool:
    return bool(res.phases) and not any(k == "reintegration" or k.startswith("reintegration_")
                                        for k in res.tables)


def complete_from_problem_file(run_dir: Path, res: Result) -> tuple[list[str], list[str]]:
    """Add ``hamiltonian`` / ``dH_d<u>`` to each phase's ``extra`` and a ``reintegration``
    table (``reintegration_<phase>`` for several phases) when the run folder lacks them and
    holds ``problem.yaml``. Returns (notes on what was computed, warnings on what failed)."""
    src = Path(run_dir) / "problem.yaml"
    want_h, want_r = _needs_hamiltonian(res), _needs_reintegration(res)
    if not (want_h or want_r) or not src.is_file() or not res.phases:
        return [], []
    try:
        from ocdsl.api import compile_file

        file = compile_file(src)
    except Exception as exc:  # noqa: BLE001
        return [], [f"the Hamiltonian and the re-integration could not be computed from problem.yaml "
                    f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"]
    problem = file.problem
    if problem is None or len(problem.phases) != len(res.phases):
        return [], []
    done: list[str] = []
    warns: list[str] = []
    if want_h:
        try:
            if _add_hamiltonian(problem, res):
                done.append("the Hamiltonian and its control gradients")
        except Exception as exc:  # noqa: BLE001
            warns.append(f"Hamiltonian not computed ({type(exc).__name__}: {exc})")
    if want_r:
        try:
            if _add_reintegration(problem, res):
                done.append("the re-integrated trajectory")
        except Exception as exc:  # noqa: BLE001
            warns.append(f"re-integration not computed ({type(exc).__name__}: {exc})")
    notes = []
    if done:
        notes.append(" and ".join(done).capitalize() + (" were" if len(done) > 1 or " and " in done[0] else " was")
                     + " evaluated by the report from the run's states, controls and costates and its copy "
                     "of the problem file (nothing re-solved).")
    return notes, warns


def _params(ph, res: Result) -> dict[str, float]:
    """The phase's constants, overridden by the run's parameter values (a sweep's point)."""
    out = {str(k): float(v) for k, v in ph.constants.items()}
    for k, v in (res.parameters or {}).items():
        try:
            out[str(k)] = float(v)
        except (TypeError, ValueError):
            pass
    return out


def _lagrange(problem, ph):
    import sympy as sp

    sign = 1.0 if problem.objective.sense == "minimize" else -1.0
    J = sign * problem.objective.expr
    L = sp.Integer(0)
    for s, integrand in ph.integrals.items():
        coef = sp.diff(J, s)
        if coef.free_symbols:
            raise ValueError("the objective is nonlinear in an integral")
        L += coef * integrand
    return L


def _collocated(traj) -> np.ndarray:
    col = traj.extra.get("collocated")
    if col is None:
        return np.ones(len(traj.time), bool)
    return np.asarray(col, float) > 0


def _add_hamiltonian(problem, res: Result) -> bool:
    from ocdsl.solve.certificate import hamiltonian_arrays

    added = False
    for ph, traj in zip(problem.phases, res.phases):
        if not traj.costates or any(k in traj.extra for k in HAMILTONIAN_KEYS):
            continue
        names = [s.name for s in ph.states]
        if any(n not in traj.costates for n in names) or any(c.name not in traj.controls for c in ph.controls):
            continue
        nan = np.where(_collocated(traj), 1.0, np.nan)
        arrays = {"time": traj.time, "states": traj.states, "controls": traj.controls,
                  "costates": {k: np.asarray(v, float) * nan for k, v in traj.costates.items()}}
        extra = hamiltonian_arrays(ph.model, _params(ph, res), arrays, _lagrange(problem, ph))
        traj.extra.update(extra)
        added = True
    return added


def _add_reintegration(problem, res: Result) -> bool:
    """Integrate each phase's dynamics from its first collocated state with the stored
    control (piecewise-polynomial per mesh segment when the mesh is known, else linear),
    Radau at rtol 1e-10, sampled at 6 points per node interval."""
    from scipy.integrate import solve_ivp

    from ocdsl.solve.certificate import _Numeric
    from ocdsl.verify.interpolate import SegmentPolynomials as _ControlInterp

    multi = len(res.phases) > 1
    added = False
    meshes = (res.method or {}).get("meshes") or {}
    for ph, traj in zip(problem.phases, res.phases):
        sn = [s.name for s in ph.states]
        cn = [c.name for c in ph.controls]
        if any(n not in traj.states for n in sn) or any(n not in traj.controls for n in cn):
            continue
        keep = _collocated(traj)
        t = np.asarray(traj.time, float)
        X = np.column_stack([np.asarray(traj.states[n], float) for n in sn])
        U = np.column_stack([np.asarray(traj.controls[n], float) for n in cn]) if cn else np.zeros((len(t), 0))
        keep &= np.isfinite(t) & np.isfinite(X).all(axis=1) & np.isfinite(U).all(axis=1)
        tk, Xk, Uk = t[keep], X[keep], U[keep]
        if len(tk) < 2 or np.any(np.diff(tk) <= 0):
            continue
        num = _Numeric(ph.model, _params(ph, res), 0)
        bounds = [tuple(b if math.isfinite(b) else (-np.inf if i == 0 else np.inf)
                        for i, b in enumerate(ph.control_bounds.get(c, (-math.inf, math.inf)))) for c in ph.controls]
        mesh = meshes.get(ph.name) if isinstance(meshes, dict) else None
        segments = None
        if isinstance(mesh, dict) and mesh.get("breakpoints"):
            t0, tf = float(t[np.isfinite(t)][0]), float(t[np.isfinite(t)][-1])
            segments = [t0 + (tf - t0) * float(b) for b in mesh["breakpoints"]]
        try:
            uf = _ControlInterp(tk, Uk, bounds, segments)
        except Exception:  # noqa: BLE001  (nodes do not match the mesh: linear interpolation)
            uf = _ControlInterp(tk, Uk, bounds, None)
        fun = lambda tt, x: num.f_point(tt, x, uf(tt))  # noqa: E731
        jac = lambda tt, x: num.fx_point(tt, x, uf(tt))  # noqa: E731
        t_eval = np.unique(np.concatenate([np.linspace(a, b, 6, endpoint=False) for a, b in zip(tk[:-1], tk[1:])]
                                          + [tk[-1:]]))
        scale = np.maximum(np.ptp(Xk, axis=0), 1e-12)
        sol = solve_ivp(fun, (tk[0], tk[-1]), Xk[0], method="Radau", jac=jac, rtol=1e-10,
                        atol=1e-10 * scale, t_eval=t_eval, max_step=float(np.median(np.diff(tk))))
        if sol.t.size < 2:
            raise RuntimeError(sol.message)
        table: dict[str, Any] = {"t": sol.t}
        table.update({n: sol.y[i] for i, n in enumerate(sn)})
        res.tables[f"reintegration_{ph.name}" if multi else "reintegration"] = table
        added = True
    return added
