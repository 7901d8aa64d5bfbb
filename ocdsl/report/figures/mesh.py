"""Mesh refinement: history per iteration, breakpoints per iteration, final error per segment."""
from __future__ import annotations

import numpy as np

from ocdsl.report.figures.base import (
    Fig, MAX_LEGEND, MAX_PANELS, _new_figure, _nonempty, _phase_colors, _run_colors, _styled)


@_styled
def fig_mesh_history(table: dict[str, np.ndarray], history: list | None = None,
                     error_table: dict[str, np.ndarray] | None = None, tolerance: float | None = None) -> list[Fig]:
    """Mesh refinement history: error and mesh size per iteration, and, when the table has
    one row per segment (``t`` column), error per segment against time and the mesh per
    iteration."""
    if not table:
        return []
    it_key = next((k for k in ("iteration", "iter", "mesh_iteration", "k") if k in table), None)
    n = len(next(iter(table.values())))
    it = np.asarray(table[it_key], float) if it_key else np.arange(n, dtype=float)
    cols = [k for k in table if k != it_key and k != "t" and _nonempty(table[k])]
    out: list[Fig] = []
    per_segment = "t" in table and len(np.unique(it[np.isfinite(it)])) < n
    if per_segment:
        t = np.asarray(table["t"], float)
        iters = np.unique(it[np.isfinite(it)])
        err_key = next((k for k in cols if "err" in k.lower()), None)
        fig, axes = _new_figure(2 if err_key else 1)
        colors = _run_colors(len(iters))
        if err_key:
            ax = axes[0]
            for c, k in zip(colors, iters):
                m = it == k
                e = np.asarray(table[err_key], float)[m]
                ax.semilogy(t[m], np.where(e > 0, e, np.nan), marker="o", markersize=2.5, color=c,
                            label=f"iteration {int(k)}", linewidth=0.9)
            ax.set_xlabel("$t$")
            ax.set_ylabel(err_key.replace("_", " "))
            if len(iters) <= MAX_LEGEND:
                ax.legend(fontsize=7, frameon=False)
        ax = axes[-1]
        for c, k in zip(colors, iters):
            m = it == k
            ax.plot(t[m], np.full(m.sum(), k), "|", color=c, markersize=8)
        ax.set_xlabel("$t$")
        ax.set_ylabel("mesh iteration")
        out.append(Fig("mesh-segments", "Mesh refinement: error per segment against time (left) "
                       "and the mesh points of every iteration (right).", fig))
        return out
    # one row per iteration: the error first, then what changes; constants and bookkeeping
    # (phase index, where the error sat) are left out
    keep = [k for k in MESH_PANELS if k in cols] + [k for k in cols if k not in MESH_PANELS
                                                   and k not in MESH_BOOKKEEPING]
    keep = [k for k in keep if len(np.unique(np.asarray(table[k], float)[np.isfinite(np.asarray(table[k], float))])) > 1
            or k == "max_error"]
    if not keep:
        return []
    fig, axes = _new_figure(len(keep), ncols=2 if len(keep) > 1 else 1)
    for ax, k in zip(axes, keep):
        y = np.asarray(table[k], float)
        ax.plot(it, y, marker="o", markersize=3)
        pos = y[np.isfinite(y)]
        if k == "max_error" or (pos.size and np.all(pos > 0) and pos.max() / pos.min() > 100):
            if pos.size and np.all(pos > 0):
                ax.set_yscale("log")
        if k == "max_error" and tolerance is not None:
            ax.axhline(tolerance, color="#c0392b", linestyle="--", linewidth=0.9, label=f"tolerance {tolerance:g}")
            ax.legend(fontsize=7, frameon=False)
        ax.set_xlabel("mesh iteration")
        ax.set_ylabel(MESH_LABELS.get(k, k.replace("_", " ")))
        ax.xaxis.get_major_locator().set_params(integer=True)
    out.append(Fig("mesh-history", "Mesh refinement history, one point per mesh iteration"
                   + (" (dashed: the tolerance)." if tolerance is not None else "."), fig))
    out += _mesh_points(history or [])
    if error_table:
        out += _mesh_error(error_table)
    return out


MESH_PANELS = ("max_error", "segments", "nodes", "nlp_variables", "ipopt_iterations", "objective", "time_s")
MESH_BOOKKEEPING = ("phase", "max_error_segment", "max_error_t", "nlp_constraints")
MESH_LABELS = {"max_error": "largest estimated error", "segments": "segments", "nlp_variables": "NLP variables",
               "ipopt_iterations": "Ipopt iterations", "time_s": "solve time [s]", "min_degree": "smallest degree",
               "max_degree": "largest degree"}


def _mesh_points(history: list[dict]) -> list[Fig]:
    """The breakpoints of every iteration's mesh (``extra.mesh_history[].meshes``), one row
    per iteration, in the phase's normalised time."""
    rows = [(int(h.get("iteration", i + 1)), (h.get("meshes") or {})) for i, h in enumerate(history)
            if isinstance(h, dict) and isinstance(h.get("meshes"), dict)]
    if not rows:
        return []
    phases: list[str] = []
    for _, m in rows:
        phases += [p for p in m if p not in phases]
    fig, axes = _new_figure(len(phases[:MAX_PANELS]), ncols=1, height=0.6 + min(2.6, 0.28 * len(rows) + 0.8)
                            * len(phases[:MAX_PANELS]))
    for ax, ph in zip(axes, phases):
        for k, m in rows:
            bp = np.asarray((m.get(ph) or {}).get("breakpoints") or [], float)
            if bp.size:
                ax.plot(bp, np.full(bp.size, k), "|", color="#1f4e9c", markersize=9, markeredgewidth=1.1)
                ax.annotate(f"{bp.size - 1} seg.", (1.01, k), xycoords=("axes fraction", "data"), fontsize=6.5,
                            va="center")
        ax.set_ylim(max(k for k, _ in rows) + 0.6, min(k for k, _ in rows) - 0.6)
        ax.set_xlim(-0.02, 1.02)
        ax.yaxis.get_major_locator().set_params(integer=True)
        ax.set_ylabel("mesh iteration")
        ax.set_xlabel("normalised time $(t - t_0)/(t_f - t_0)$" + (f", phase {ph}" if len(phases) > 1 else ""))
        ax.grid(False, axis="y")
    return [Fig("mesh-points", "Mesh breakpoints of every refinement iteration (one row per iteration, "
                "first at the top): where the refinement placed its segments.", fig)]


def _mesh_error(table: dict[str, np.ndarray]) -> list[Fig]:
    """The final mesh's estimated error per segment (``tables/mesh_error.csv``) against time."""
    if not all(k in table for k in ("t_start", "t_end", "error")):
        return []
    t0, t1 = np.asarray(table["t_start"], float), np.asarray(table["t_end"], float)
    e = np.asarray(table["error"], float)
    ph = np.asarray(table.get("phase", np.zeros_like(e)), float)
    fig, axes = _new_figure(1, height=2.4)
    ax = axes[0]
    for k, c in zip(np.unique(ph), _phase_colors(len(np.unique(ph)))):
        m = ph == k
        for a, b, y in zip(t0[m], t1[m], e[m]):
            if y > 0 and np.isfinite(y):
                ax.plot([a, b], [y, y], color=c, linewidth=1.6)
    pos = e[np.isfinite(e) & (e > 0)]
    if pos.size:
        ax.set_yscale("log")
    ax.set_xlabel("$t$")
    ax.set_ylabel("estimated error")
    return [Fig("mesh-error", "Estimated error of each segment of the final mesh (one bar per segment).", fig)]
