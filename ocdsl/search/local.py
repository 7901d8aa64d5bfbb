"""The local stages of ``method: parametric`` after the swarm, each optional and reported apart:
``polish`` (least squares on the terminal errors / zeta), ``continue_tf`` (tf lowered while
the polish keeps every terminal error inside zeta) and ``refine_objective`` (SLSQP: the
problem's objective minimised subject to every |error|/zeta <= target_ratio)."""
from __future__ import annotations

import numpy as np
import sympy as sp

from ocdsl.spec.parametric import PolishSpec

from .parametric import ParametricProblem


def inside_tolerances(det: dict) -> bool:
    """Every terminal |error|/zeta <= 1 and the flight completed (``pp.details``' status)."""
    return bool(np.all(det["ratio"] <= 1.0)) and det["status"] >= 0 and det["status"] != 2


def continue_tf(pp: ParametricProblem, x: np.ndarray, polish_settings, settings,
                progress: bool = False) -> tuple[np.ndarray, dict, dict]:
    """Lower tf from ``x`` (inside the zeta box) while the polish keeps it inside.

    Integers stay fixed; see :class:`ocdsl.spec.parametric.ContinuationSpec`. Returns the
    last point inside the box, a summary, and the table of every attempt.
    """
    if not pp.tf_free:
        return x, {"continuation": "skipped: tf is fixed"}, {}
    itf = len(pp.variables)
    lo, _, _ = pp.bounds()
    det = pp.details(x)
    restored = None
    if not inside_tolerances(det):
        # the polish with tf fixed failed: let tf move too (either way) to get inside first
        xr, info = polish(pp, x, polish_settings.model_copy(update={"free_tf": True}),
                          stop_ratio=settings.target_ratio,
                          max_evaluations=max(settings.evaluations_per_step, 5 * polish_settings.max_iterations))
        dr = pp.details(xr)
        restored = {"tf": float(xr[itf]), "max_error_over_zeta": float(dr["ratio"].max()),
                    "evaluations": info["polish_evaluations"]}
        if not inside_tolerances(dr):
            return x, {"continuation": "skipped: neither polish (tf fixed, tf free) got inside the zeta box",
                       "max_error_over_zeta": float(det["ratio"].max()), "restored": restored}, {}
        x = xr
    tf0 = tf = float(x[itf])
    step = settings.step * tf
    rows = {k: [] for k in ("attempt", "tf_tried", "accepted", "max_error_over_zeta", "evaluations", "tf")}
    evals = 0
    from ..progress import Stage

    bar = Stage("continuation in tf", settings.max_steps, enabled=progress, at_most=True)
    for k in range(1, settings.max_steps + 1):
        bar.update(k - 1, f"tf {tf:.6g}")
        if step < settings.min_step * tf:
            reason = f"step below {settings.min_step:g} tf"
            break
        tf_try = max(tf - step, lo[itf])
        if tf_try >= tf:
            reason = "tf at its lower bound"
            break
        xt = x.copy()
        xt[itf] = tf_try
        xn, info = polish(pp, xt, polish_settings, stop_ratio=settings.target_ratio,
                          max_evaluations=settings.evaluations_per_step)
        dn = pp.details(xn)
        ok = inside_tolerances(dn)
        evals += info["polish_evaluations"]
        for key, val in (("attempt", k), ("tf_tried", tf_try), ("accepted", float(ok)),
                         ("max_error_over_zeta", float(dn["ratio"].max())),
                         ("evaluations", info["polish_evaluations"])):
            rows[key].append(val)
        if ok:
            x, tf = xn, tf_try
            step *= settings.grow
        else:
            step *= 0.5
        rows["tf"].append(tf)
    else:
        reason = f"max_steps {settings.max_steps}"
    bar.close(f"tf {tf0:.6g} -> {tf:.6g} ({reason})")
    summary = {"continuation": reason, "restored_with_free_tf": restored, "tf_start": tf0, "tf_end": tf, "attempts": len(rows["attempt"]),
               "accepted": int(sum(rows["accepted"])), "evaluations": evals}
    return x, summary, {k: np.asarray(v, float) for k, v in rows.items()}


def _error_ratios(pp: ParametricProblem, X: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    """Terminal errors / zeta of a batch of decision vectors; a failed integration counts
    as 1e6 on every constraint."""
    return _ratios_and_objective(pp, X, zeta)[0]


def _ratios_and_objective(pp: ParametricProblem, X: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``_error_ratios`` and the objective (minimised sense) of the same flights."""
    Yf, status, _, var, tf = pp.final(X)
    E, obj = pp.errors(Yf, var, tf)
    R = E / zeta
    R[(status < 0) | (status == 2)] = 1e6
    return R, obj


def objective_is_tf(pp: ParametricProblem) -> bool:
    return pp.objective == sp.Symbol("tf", real=True)


def refine_box(pp: ParametricProblem, box_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The swarm's box widened about its centre by ``box_scale``; tf keeps its bounds."""
    lo, hi, _ = pp.bounds()
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    wide_lo, wide_hi = centre - box_scale * half, centre + box_scale * half
    if pp.tf_free:
        itf = len(pp.variables)
        wide_lo[itf], wide_hi[itf] = lo[itf], hi[itf]
    return wide_lo, wide_hi


def refine_objective(pp: ParametricProblem, x: np.ndarray, settings, progress: bool = False) -> tuple[np.ndarray, dict]:
    """Minimise the objective (tf for the seed paper's) subject to every |error|/zeta <=
    ``settings.target_ratio`` from ``x``.

    See :class:`ocdsl.spec.parametric.RefineSpec`. The integers stay fixed; tf (where free)
    and the continuous coefficients move (the coefficients within the box widened by
    ``box_scale``). Returns the new point (or ``x`` when the result is not inside the zeta
    box or not better) and a summary. An objective other than tf is differenced with the
    terminal errors, in the same batch of flights (it minimised tf whatever the objective
    was: `minimize tf - 0.5*x(tf)` ended 34 % above its optimum, unseen22 FC1).
    """
    from scipy.optimize import minimize

    lo, hi, is_int = pp.bounds()
    idx = np.flatnonzero(~is_int)
    itf = len(pp.variables)
    by_tf = objective_is_tf(pp)
    if by_tf and (not pp.tf_free or itf not in idx):
        return x, {"refine": "skipped: tf is fixed"}
    if not len(idx):
        return x, {"refine": "skipped: nothing continuous to move"}
    wide_lo, wide_hi = refine_box(pp, settings.box_scale)
    width = np.where(hi[idx] > lo[idx], hi[idx] - lo[idx], 1.0)
    zeta = np.array([t.zeta for t in pp.terminals])
    j_tf = int(np.flatnonzero(idx == itf)[0]) if by_tf else -1
    h = settings.fd_step
    n_evals = [0]
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def point(u):   # SLSQP works in box-normalised coordinates: every variable O(1)
        X = x.copy()
        X[idx] = lo[idx] + u * width
        return X

    def value_of(X, obj):
        return X[:, itf] if by_tf else obj

    def ratios_and_jacobian(u):
        key = u.tobytes()
        if key not in cache:
            U = np.vstack([u, u + h * np.eye(len(u))])
            X = np.tile(x, (len(U), 1))
            X[:, idx] = lo[idx] + U * width
            R, obj = _ratios_and_objective(pp, X, zeta)
            J = value_of(X, obj)
            n_evals[0] += len(U)
            cache.clear()
            cache[key] = (R[0], ((R[1:] - R[0]) / h).T, float(J[0]), (J[1:] - J[0]) / h)
            # SLSQP's iterates may leave the zeta box and its line search may fail: the
            # best iterate inside the box is kept
            if np.all(np.abs(R[0]) <= 1.0) and J[0] < best[0]:
                best[0], best[1] = float(J[0]), X[0].copy()
        return cache[key]

    def tf_of(xe) -> float:
        return float(pp.decode(xe[None, :])[1][0])

    def judged(xe) -> tuple[bool, float]:
        """(inside the zeta box, objective) of one point, from one flight."""
        R, obj = _ratios_and_objective(pp, xe[None, :], zeta)
        return bool(np.all(np.abs(R[0]) <= 1.0)), float(value_of(xe[None, :], obj)[0])

    target = settings.target_ratio
    restoration = {"attempts": 0, "inside": 0}

    def _restore(xe) -> bool:
        """An iterate below the best tf but outside the zeta box: drive its errors back
        inside at that tf (least squares over the coefficients, widened box)."""
        inside, J = judged(xe)
        if J >= best[0] or inside:
            return False
        restoration["attempts"] += 1
        xr, info = polish(pp, xe, PolishSpec(method="least_squares", max_iterations=settings.restore_iterations,
                                             fd_step=settings.fd_step),
                          stop_ratio=target, bounds=(wide_lo, wide_hi))
        n_evals[0] += info["polish_evaluations"]
        inside, J = judged(xr)
        if inside and J < best[0]:
            restoration["inside"] += 1
            best[0], best[1] = J, xr.copy()
            return True
        return False

    constraints = [{"type": "ineq",
                    "fun": lambda u: np.concatenate([target - ratios_and_jacobian(u)[0], target + ratios_and_jacobian(u)[0]]),
                    "jac": lambda u: np.vstack([-ratios_and_jacobian(u)[1], ratios_and_jacobian(u)[1]])}]
    if by_tf:
        grad = np.zeros(len(idx))
        grad[j_tf] = width[j_tf]

        def fun(u):
            return lo[itf] + u[j_tf] * width[j_tf]

        def jac(_u):
            return grad
    else:
        def fun(u):
            return ratios_and_jacobian(u)[2]

        def jac(u):
            return ratios_and_jacobian(u)[3]
    u0 = (x[idx] - lo[idx]) / width
    box = list(zip((wide_lo[idx] - lo[idx]) / width, (wide_hi[idx] - lo[idx]) / width))
    tf0 = tf_of(x)
    j0 = tf0 if by_tf else judged(x)[1]
    best: list = [j0, x.copy()]
    runs, last_best = 0, j0
    from ..progress import Stage

    bar = Stage("refinement (SLSQP)", settings.max_iterations * (settings.restarts + 1), enabled=progress,
                at_most=True)
    steps = [0]

    def step(_u):
        steps[0] += 1
        bar.update(steps[0], f"best {'tf' if by_tf else 'J'} {best[0]:.6g}  evaluations {n_evals[0]}")

    try:
        while True:
            runs += 1
            sol = minimize(fun, u0, jac=jac, bounds=box,
                           constraints=constraints, method="SLSQP", callback=step,
                           options={"maxiter": settings.max_iterations, "ftol": 1e-10})
            message = str(sol.message)
            xn = point(np.clip(sol.x, [b[0] for b in box], [b[1] for b in box]))
            restored = _restore(xn)
            # SLSQP's line search fails (exit mode 8) where the terminal errors curve faster
            # than its linearisation (25 revolutions at 2 N: the differences themselves agree
            # to 1e-4 between steps 1e-7 and 1e-5); start again from the fastest point inside
            # the box, while that keeps improving
            improved = best[0] < last_best - 1e-6 * (tf0 if by_tf else max(abs(j0), 1e-12))
            if (sol.status != 8 and not restored) or runs > settings.restarts or not improved:
                break
            last_best = best[0]
            u0 = (best[1][idx] - lo[idx]) / width
    except Exception as e:  # keep the previous point on any failure
        bar.close(f"failed: {e}")
        return x, {"refine": f"failed: {e}", "evaluations": n_evals[0], "tf_start": tf0, "tf_end": tf0}
    what = "tf" if by_tf else "J"
    bar.close(f"{what} {j0:.6g} -> {best[0]:.6g}")
    dn = pp.details(xn)
    jn = dn["tf"] if by_tf else dn["objective"]
    if not inside_tolerances(dn) or jn > best[0]:
        final = f"final iterate {what} {jn:.6g}, max |e|/zeta {dn['ratio'].max():.3g}"
        xn, dn = best[1], pp.details(best[1])
        message = (f"{message}; {final}; kept the best iterate inside the zeta box" if best[0] < j0
                   else f"rejected ({message}; {final})")
    summary = {"refine": message, "evaluations": n_evals[0], "tf_start": tf0, "tf_end": dn["tf"],
               "max_error_over_zeta": float(dn["ratio"].max()), "box_scale": settings.box_scale,
               "slsqp_runs": runs, "restorations": restoration}
    if not by_tf:
        summary.update(objective_start=j0, objective_end=dn["objective"])
    return xn, summary


class _Reached(Exception):
    def __init__(self, z):
        self.z = z


def polish(pp: ParametricProblem, x: np.ndarray, settings, stop_ratio: float | None = None,
           max_evaluations: int | None = None,
           bounds: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, dict]:
    """Drive the terminal errors / zeta to zero from ``x`` (integers and tf fixed).

    ``stop_ratio``: stop as soon as every |error|/zeta is at or below it (the continuation
    in tf needs points inside the box, not errors at zero). ``max_evaluations`` caps the
    integrations (function and Jacobian) of this call. ``bounds`` replaces the swarm's
    box (the refinement's widened box).
    """
    from scipy.optimize import least_squares

    lo, hi, is_int = pp.bounds()
    if bounds is not None:
        lo, hi = bounds
    free = ~is_int
    if pp.tf_free and not getattr(settings, "free_tf", False):
        free[len(pp.variables)] = False
    idx = np.flatnonzero(free)
    zeta = np.array([t.zeta for t in pp.terminals])
    width = np.where(hi[idx] > lo[idx], hi[idx] - lo[idx], 1.0)
    h = settings.fd_step * width
    n_evals = [0]

    def full(z):
        X = np.tile(x, (len(z), 1))
        X[:, idx] = z
        return X

    def residuals_batch(Z):
        if max_evaluations is not None and n_evals[0] >= max_evaluations:
            raise _Reached(None)
        n_evals[0] += len(Z)
        return _error_ratios(pp, full(Z), zeta)

    def fun(z):
        r = residuals_batch(z[None, :])[0]
        if stop_ratio is not None and np.all(np.abs(r) <= stop_ratio):
            raise _Reached(z.copy())
        best[0] = (float(np.max(np.abs(r))), z.copy()) if float(np.max(np.abs(r))) < best[0][0] else best[0]
        return r

    def jac(z):
        Z = np.vstack([z[None, :], z + np.diag(h)])
        R = residuals_batch(Z)
        return ((R[1:] - R[0]) / h[:, None]).T

    z0 = np.clip(x[idx], lo[idx], hi[idx])
    best = [(np.inf, z0)]
    try:
        sol = least_squares(fun, z0, jac=jac, bounds=(lo[idx], hi[idx]), x_scale=width,
                            method="trf", max_nfev=settings.max_iterations)
        z = sol.x
        msg = sol.message
    except _Reached as r:
        if r.z is not None:
            z, msg = r.z, f"every |error|/zeta <= {stop_ratio:g}"
        else:
            z, msg = best[0][1], f"evaluation budget {max_evaluations} used"
    except Exception as e:  # keep the swarm's best on any failure
        z, msg = z0, f"polish failed: {e}"
    out = x.copy()
    out[idx] = z
    if pp.fitness(out[None, :])[0] > pp.fitness(x[None, :])[0]:
        return x, {"polish": "rejected (worse than the swarm's best)", "polish_evaluations": n_evals[0]}
    return out, {"polish": msg, "polish_evaluations": n_evals[0]}
