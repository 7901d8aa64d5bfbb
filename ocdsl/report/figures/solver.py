"""NLP solver convergence per iteration."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ocdsl.report.figures.base import Fig, _new_figure, _styled


@_styled
def fig_solver_history(history: Sequence[Sequence[float]]) -> list[Fig]:
    """NLP solver convergence: rows ``(iteration, objective, inf_pr, inf_du)``."""
    h = np.array([list(r)[:4] for r in history if len(r) >= 4], float)
    if h.size == 0 or len(h) < 2:
        return []
    fig, axes = _new_figure(2, height=2.3)
    ax = axes[0]
    for j, lab, c in ((2, "primal infeasibility", "#1f4e9c"), (3, "dual infeasibility", "#c0392b")):
        y = np.where(h[:, j] > 0, h[:, j], np.nan)
        ax.semilogy(h[:, 0], y, label=lab, color=c, marker="o", markersize=2)
    ax.set_xlabel("iteration")
    ax.set_ylabel("infeasibility")
    ax.legend(fontsize=7, frameon=False)
    ax = axes[1]
    ax.plot(h[:, 0], h[:, 1], color="#2a9d55", marker="o", markersize=2)
    ax.set_xlabel("iteration")
    ax.set_ylabel("NLP objective")
    return [Fig("solver", "NLP solver convergence: infeasibilities (left) and objective (right) per iteration.", fig)]
