"""The Pareto front in the plane of the result's two objectives."""
from __future__ import annotations

from typing import Any

from matplotlib.figure import Figure

from ocdsl.report.tables import finite_or_none, truthy
from ocdsl.report.figures.base import Fig, WIDTH_IN, _run_colors, _styled, axis_label


# --------------------------------------------------------------------- studies
@_styled
def fig_pareto(rows: list[dict[str, Any]], criteria: tuple[str, str], units: dict | None = None,
               flag: str = "pareto", senses: tuple[str, str] | None = None) -> list[Fig]:
    """Criteria plane: every solution (hollow, coloured by ``family`` when present), the
    Pareto-optimal ones filled and joined by the boundary of the region they dominate: a
    staircase whose corners are dominated points, never better than the set (``senses``,
    minimize unless said: a maximised first criterion turns the steps, unseen35 P43, where the
    min-min staircase drew utopia corners for a range-against-time front)."""
    a, b = criteria
    pts = [(r, finite_or_none(r.get(a)), finite_or_none(r.get(b))) for r in rows]
    pts = [(r, x, y) for r, x, y in pts if x is not None and y is not None]
    if not pts:
        return []
    fig = Figure(figsize=(WIDTH_IN * 0.8, WIDTH_IN * 0.58), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    fams = []
    for r, _, _ in pts:
        f = str(r.get("family", "")) if r.get("family") not in (None, "") else ""
        if f not in fams:
            fams.append(f)
    colors = dict(zip(fams, _run_colors(len(fams))))
    for f in fams:
        xs = [x for r, x, _ in pts if str(r.get("family", "") or "") == f]
        ys = [y for r, _, y in pts if str(r.get("family", "") or "") == f]
        ax.plot(xs, ys, linestyle="none", marker="o", markersize=5, markerfacecolor="none",
                color=colors[f], label=f"family {f}" if f else "all solutions")
    par = sorted([(x, y) for r, x, y in pts if truthy(r.get(flag))])
    if par:
        # sorted by the first criterion, the next point is reached first along the axis in
        # which the previous one is better: the corner between is dominated by both
        steps = "steps-pre" if (senses or ("minimize",))[0] == "maximize" else "steps-post"
        ax.plot([p[0] for p in par], [p[1] for p in par], color="#c0392b", marker="o", markersize=5,
                linewidth=1.0, drawstyle=steps if len(par) > 1 else "default", label="Pareto set")
    if len(pts) <= 40:
        lab_key = next((k for k in ("label", "solution", "name", "point") if k in pts[0][0]), None)
        if lab_key:
            for r, x, y in pts:
                ax.annotate(str(r.get(lab_key)), (x, y), fontsize=6.5, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel(axis_label(a, units or {}, r"\mathrm{%s}" % a.replace("_", r"\_")))
    ax.set_ylabel(axis_label(b, units or {}, r"\mathrm{%s}" % b.replace("_", r"\_")))
    ax.legend(fontsize=7, frameon=False, loc="best")
    return [Fig("pareto", f"Pareto front in the ({a}, {b}) criteria plane: all solutions hollow, "
                "Pareto-optimal solutions filled and joined in red by the boundary of the region they "
                "dominate (its corners are dominated points, not solutions).", fig)]
