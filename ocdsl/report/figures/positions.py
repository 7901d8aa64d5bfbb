"""Trajectories in space: the position states (``problem.positions``) drawn as a path."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ocdsl.result import Result
from ocdsl.report.figures.frame import declared_frame
from ocdsl.report.figures.base import (
    Fig, WIDTH_IN, _marker_kw, _phase_colors, _styled, axis_label, tex_name, unit_tex)


def _position_groups(problem: dict) -> list[list[str]]:
    pos = problem.get("positions") or []
    if pos and all(isinstance(p, str) for p in pos):
        pos = [pos]
    return [list(g) for g in pos if isinstance(g, (list, tuple)) and 2 <= len(g) <= 3]


@_styled
def fig_positions(res: Result) -> list[Fig]:
    """2-D or 3-D trajectory view of the position states (``problem.positions``)."""
    out: list[Fig] = []
    units = res.problem.get("units") or {}
    reint = {k[len("reintegration_"):] if k != "reintegration" else None: v
             for k, v in res.tables.items() if k == "reintegration" or k.startswith("reintegration_")}
    if declared_frame(res.problem or {}) is not None:
        return []           # drawn in its frame, with its bodies (figures/frame.py)
    for gi, group in enumerate(_position_groups(res.problem)):
        segs = [(p.name, [np.asarray(p.states[n], float) for n in group]) for p in res.phases
                if all(n in p.states for n in group)]
        if not segs:
            continue
        colors = _phase_colors(len(segs))
        if len(group) == 2:
            fig = Figure(figsize=(WIDTH_IN * 0.72, WIDTH_IN * 0.6), layout="constrained")
            ax = fig.add_subplot(1, 1, 1)
        else:
            import mpl_toolkits.mplot3d  # noqa: F401  (registers the 3d projection)
            fig = Figure(figsize=(WIDTH_IN * 0.8, WIDTH_IN * 0.7), layout="constrained")
            ax = fig.add_subplot(1, 1, 1, projection="3d")
        polar = len(group) == 2 and str(units.get(group[1], "")).lower() in ("rad", "deg", "degree", "degrees")
        if polar:   # (r, theta): height above the end point against downrange, as a paper draws it
            r_end = float(segs[-1][1][0][np.isfinite(segs[-1][1][0])][-1])
            scale = np.pi / 180 if str(units.get(group[1])).lower().startswith("deg") else 1.0
            th0 = float(segs[0][1][1][np.isfinite(segs[0][1][1])][0])
            segs = [(pn, [r_end * (xy[1] - th0) * scale, xy[0] - r_end]) for pn, xy in segs]
        for (pname, xyz), c in zip(segs, colors):
            ax.plot(*xyz, color=c, label=pname if len(segs) > 1 else "trajectory", **_marker_kw(len(xyz[0])))
        ax.plot(*[[a[0]] for a in segs[0][1]], marker="o", color="k", linestyle="none", label="start")
        ax.plot(*[[a[-1]] for a in segs[-1][1]], marker="s", color="k", linestyle="none", label="end")
        first = True
        for pname, _ in segs:
            tab = reint.get(pname, reint.get(None) if len(segs) == 1 else None)
            if tab is not None and all(n in tab for n in group) and not polar:
                ax.plot(*[tab[n] for n in group], color="#c0392b", linestyle="--", linewidth=1.0,
                        label="re-integrated" if first else None)
                first = False
        if polar:
            u = units.get(group[0])
            ax.set_xlabel(f"downrange ${tex_name(group[0])}(t_f)\\,({tex_name(group[1])} - {tex_name(group[1])}_0)$"
                          + (f" [{unit_tex(u)}]" if u else ""))
            ax.set_ylabel(f"height above the end point ${tex_name(group[0])} - {tex_name(group[0])}(t_f)$"
                          + (f" [{unit_tex(u)}]" if u else ""))
        else:
            ax.set_xlabel(axis_label(group[0], units))
            ax.set_ylabel(axis_label(group[1], units))
        if len(group) == 3:
            ax.set_zlabel(axis_label(group[2], units))
        if not polar:
            try:        # equal scales: a 3-D orbit must not look 40 times taller than it is
                ax.set_aspect("equal", adjustable="datalim" if len(group) == 2 else "box")
            except Exception:  # noqa: BLE001  (degenerate ranges)
                pass
        ax.legend(fontsize=7, frameon=False, loc="best")
        names = ", ".join(group)
        what = (f"Trajectory from ({names}): height above the end point against downrange (scales not equal)"
                if polar else f"Trajectory in the ({names}) {'plane' if len(group) == 2 else 'space'}, equal scales")
        out.append(Fig(f"positions-{gi}", f"{what}; circle: start, square: end.", fig))
    return out
