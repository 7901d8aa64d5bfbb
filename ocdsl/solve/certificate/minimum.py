"""The minimum condition of the minimum principle: at every node the solution's control minimises
H over the control's whole range, not only locally. The other checks are first order (dH/du = 0
or its sign at a bound), which a local minimiser of an H not convex in u meets as well: Newton's
minimal-resistance nose (L = r / (1 + u^2), u >= 0) stopped on every mesh with u jumping from 0
to 0.67 where H's global minimiser jumps to 1, J 0.56 % high, and the advice "raise
max_iterations" (unseen48 F3). H is sampled on a grid of each control's range (the solution's own
range widened where a bound is missing) at the nodes; where the grid beats the solution's control
by more than a share of H's terms, the record names the times and the better control.

It is a diagnosis: the NLP's costates carry the mesh's error, so it says where the solution is
an extremal but not H's minimum, and leaves the verdict to the other checks."""
from __future__ import annotations

from typing import Any

import numpy as np

from ...verify.checks import RESOLUTION
from .nodes import _hamiltonian_nodes, node_shares

#: grid points per control (one control); per axis for two; each control alone for more
SAMPLES_ONE, SAMPLES_TWO = 401, 61
#: a node's H beaten by more than this share of its terms (|L| + |lambda|^T |f|, the larger of
#: the solution's control's and the better control's)
GAIN_SHARE = 1e-2
#: dH/du within this share of its terms: the solution's control is stationary there (the
#: refined Newton nose's beaten nodes: up to 3 %, its costates carrying the mesh's error)
STATIONARY_SHARE = 1e-1
#: ... at this many nodes or more
MIN_NODES = 2
#: rows per evaluation of H (nodes x samples)
CHUNK_ROWS = 200_000
#: a share of the phase at least this long where H's terms stay below the NLP's resolution
#: whatever the control: J does not determine the control there
UNDETERMINED_SHARE = 0.05


def _ranges(U: np.ndarray, bounds: list[tuple[float, float]]) -> list[np.ndarray]:
    grids = []
    n = SAMPLES_ONE if U.shape[1] == 1 else SAMPLES_TWO
    for j, (lo, hi) in enumerate(bounds):
        u = U[:, j]
        span = float(np.ptp(u)) + float(np.max(np.abs(u))) + 1.0
        lo_eff = lo if np.isfinite(lo) else float(np.min(u)) - 2.0 * span
        hi_eff = hi if np.isfinite(hi) else float(np.max(u)) + 2.0 * span
        grids.append(np.linspace(lo_eff, hi_eff, n))
    return grids


def _trials(U: np.ndarray, grids: list[np.ndarray]):
    """Blocks of controls to try, each (k, m) values with the column(s) they set: the full
    grid for one or two controls; for more, each control over its grid alone, the others at
    the node's own."""
    m = U.shape[1]
    if m <= 2:
        yield np.stack(np.meshgrid(*grids, indexing="ij"), axis=-1).reshape(-1, m), list(range(m))
        return
    for j in range(m):
        yield grids[j][:, None], [j]


def _hamiltonian(num, t, X, U, Lam) -> np.ndarray:
    return num.L_nodes(t, X, U) + np.einsum("ki,ki->k", Lam, num.f_nodes(t, X, U))


def minimum_condition(num, t, X, U, Lam, bounds: list[tuple[float, float]], names: list[str]) -> dict[str, Any] | None:
    """``num``: the phase's _Numeric; t, X, U, Lam at the nodes; ``bounds`` per control
    (+-inf where missing). None where H cannot be evaluated over the grid."""
    if U.shape[1] == 0 or len(t) < 2:
        return None
    H_own, dHdu, H_terms, dHdu_terms = _hamiltonian_nodes(num, t, X, U, Lam)
    N = len(t)
    best, best_U = H_own.copy(), U.copy()
    chunk = max(1, CHUNK_ROWS // N)       # samples per evaluation: every node at once
    with np.errstate(all="ignore"):
        for grid, columns in _trials(U, _ranges(U, bounds)):
            for start in range(0, len(grid), chunk):
                values = grid[start:start + chunk]
                k = len(values)
                trial = np.tile(U, (k, 1))
                trial[:, columns] = np.repeat(values, N, axis=0)
                try:
                    H = _hamiltonian(num, np.tile(t, k), np.tile(X, (k, 1)), trial, np.tile(Lam, (k, 1)))
                except (ValueError, ZeroDivisionError, FloatingPointError, TypeError):
                    return None
                H = np.where(np.isfinite(H), H, np.inf).reshape(k, N)
                i = np.argmin(H, axis=0)
                low = H[i, np.arange(N)]
                better = low < best
                best[better] = low[better]
                best_U[better] = trial.reshape(k, N, -1)[i[better], np.flatnonzero(better)]
    undetermined = _undetermined(num, t, X, U, Lam, bounds, H_terms, names)
    gain = H_own - best
    # the terms at the better control too: a control of 0 with costates near 0 has terms of 0,
    # and the share was "4.4e+290" (unseen59 F4)
    with np.errstate(all="ignore"):
        terms_best = _hamiltonian_nodes(num, t, X, best_U, Lam)[2]
    scale = np.maximum.reduce([H_terms, np.nan_to_num(terms_best), np.full(len(t), 1e-300)])
    # nodes whose H the NLP does not resolve (terms x duration below its resolution: a
    # discount e^{-5 t} late in [0, 100]) are not judged: "lower by 41 times its terms" of
    # 1e-10 at a control on its bound 1e-8 was "another branch" of a convex H (unseen60 F3)
    resolved = scale * float(t[-1] - t[0]) > RESOLUTION
    # a better control within a millionth of the range of the solution's own is the barrier's
    # distance from a bound the solution sits on (c = 1.135e-8 on c >= 1e-8 of [1e-8, 10], H
    # with ln c: "2.1e-02 lower", unseen60 F3), not another control
    spans = np.array([g[-1] - g[0] for g in _ranges(U, bounds)])
    apart = np.any(np.abs(best_U - U) > 1e-6 * spans, axis=1)
    beaten = (gain > GAIN_SHARE * scale) & resolved & apart
    out: dict[str, Any] = {"passed": bool(beaten.sum() < MIN_NODES), "nodes": int(len(t)),
                           "nodes_beaten": int(beaten.sum())}
    if undetermined:
        out["undetermined"] = undetermined
    if beaten.sum() < MIN_NODES:
        return out
    k = int(np.argmax(np.where(beaten, gain / scale, -np.inf)))
    out.update(first=float(t[beaten][0]), last=float(t[beaten][-1]), worst_time=float(t[k]),
               worst_share=float(gain[k] / scale[k]),
               control={n: float(U[k, j]) for j, n in enumerate(names)},
               better_control={n: float(best_U[k, j]) for j, n in enumerate(names)})
    shown = lambda d: ", ".join(f"{n} = {v:.4g}" for n, v in d.items())  # noqa: E731
    where = (f"the control is not H's minimiser at {out['nodes_beaten']} of {len(t)} nodes, t in "
             f"[{out['first']:.4g}, {out['last']:.4g}] (at t = {out['worst_time']:.4g}, {shown(out['control'])} "
             f"where {shown(out['better_control'])} gives an H lower by {out['worst_share']:.1e} of its terms)")
    moving = ~_stationary(U, dHdu, dHdu_terms, bounds)[beaten]
    out["stationary"] = bool(moving.mean() <= 0.5)
    if not out["stationary"]:
        # not an extremal: dH/du is not 0 there either (a solve stopped at its start, unseen59 F4)
        out["note"] = (f"{where}, and not stationary at {int(moving.sum())} of them (dH/du is not 0 within its "
                       "terms): the solve stopped short of the minimum principle's conditions, not on another "
                       "branch of them")
    else:
        out["note"] = (f"{where}: the solution is an extremal, not the minimum principle's (which asks for H's "
                       "global minimum over the control's range), and no finer mesh or more iterations change "
                       "that; a guess with the better control there starts the solve on the other branch")
    return out


def _undetermined(num, t, X, U, Lam, bounds, H_terms, names) -> dict | None:
    """Where H's terms (|L| + |lambda|^T |f|) stay below the NLP's resolution at the solution's
    control and at every control's range ends, over ``UNDETERMINED_SHARE`` of the phase or
    more but not all of it: J does not determine the controls there (an integrand discounted
    by e^{-5 t} over [0, 100] after t = 4). An exact tracking optimum (L = 0, lambda = 0) has
    terms at the other controls, a singular arc in |lambda| |f|: neither is undetermined."""
    duration = float(t[-1] - t[0])
    if duration <= 0:
        return None
    terms = H_terms.copy()
    for j, grid in enumerate(_ranges(U, bounds)):
        for end in (grid[0], grid[-1]):
            trial = U.copy()
            trial[:, j] = end
            with np.errstate(all="ignore"):
                terms = np.maximum(terms, np.nan_to_num(_hamiltonian_nodes(num, t, X, trial, Lam)[2], nan=np.inf))
    faint = terms * duration <= RESOLUTION
    part = float(node_shares(t)[faint].sum() / duration)
    if part < UNDETERMINED_SHARE or faint.all():
        return None
    first, last = float(t[faint][0]), float(t[faint][-1])
    return {"share": part, "first": first, "last": last,
            "note": (f"H's terms are below what the NLP resolves ({RESOLUTION:g}) on t in [{first:.4g}, {last:.4g}] "
                     f"({part:.0%} of the phase) whatever {', '.join(names)}: J does not determine "
                     f"{'it' if len(names) == 1 else 'them'} there (an integrand made negligible by a discount), "
                     "and the trajectory there is not judged")}


def _stationary(U, dHdu, dHdu_terms, bounds) -> np.ndarray:
    """Per node: every control stationary (dH/du within STATIONARY_SHARE of its terms) or at a
    bound (the sign of dH/du there is the certificate's switching check)."""
    ok = np.abs(dHdu) <= STATIONARY_SHARE * np.maximum(dHdu_terms, 1e-300)
    for j, (lo, hi) in enumerate(bounds):
        if np.isfinite(lo):
            ok[:, j] |= U[:, j] <= lo + 1e-6 * (1 + abs(lo))
        if np.isfinite(hi):
            ok[:, j] |= U[:, j] >= hi - 1e-6 * (1 + abs(hi))
    return ok.all(axis=1)
