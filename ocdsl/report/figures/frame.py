"""Trajectories in a declared frame (``problem.frame``, e.g. the Earth-Moon synodic frame):
the path with the frame's bodies and points (Earth, Moon, L1) marked, in 3-D and in
projections, every view with equal scales."""
from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from ocdsl.result import Result
from ocdsl.report.figures.base import Fig, WIDTH_IN, _phase_colors, _styled, unit_tex

BODY_COLORS = {"Earth": "#1f77b4", "Moon": "#7f7f7f"}


def declared_frame(problem: dict) -> dict | None:
    """The run folder's frame of its three position states, or None."""
    frame = problem.get("frame")
    pos = problem.get("positions") or []
    if not isinstance(frame, dict) or len(pos) != 3 or not all(isinstance(p, str) for p in pos):
        return None
    return frame


def frame_xyz(frame: dict, cols: dict, names: list[str], units: dict) -> list[np.ndarray] | None:
    """The frame's Cartesian (x, y, z) of rows holding the position states ``names``
    (``cylindrical``: (r, theta, z) with theta in rad or deg)."""
    if not all(n in cols for n in names):
        return None
    a, b, c = (np.asarray(cols[n], float) for n in names)
    if frame.get("coordinates") == "cylindrical":
        scale = math.pi / 180 if str(units.get(names[1], "rad")).lower().startswith("deg") else 1.0
        return [a * np.cos(b * scale), a * np.sin(b * scale), c]
    return [a, b, c]


def _limits(arrays: list[np.ndarray], pad: float = 0.04) -> tuple[float, float]:
    v = np.concatenate([np.ravel(x) for x in arrays])
    v = v[np.isfinite(v)]
    lo, hi = float(v.min()), float(v.max())
    span = max(hi - lo, 1e-9)
    return lo - pad * span, hi + pad * span


def _mark(ax, frame: dict, dims: tuple[int, ...], label: bool) -> None:
    """Bodies as discs of their radius (2-D) or dots (3-D), points as crosses, each named."""
    from matplotlib.patches import Circle

    for b in frame.get("bodies") or []:
        at = [float(x) for x in b["at"]]
        col = BODY_COLORS.get(b["name"], "#555555")
        if len(dims) == 2:
            r = float(b.get("radius") or 0.0)
            if r > 0:
                ax.add_patch(Circle((at[dims[0]], at[dims[1]]), r, color=col, alpha=0.85, zorder=3))
            ax.plot(at[dims[0]], at[dims[1]], marker="o", markersize=3, color=col, linestyle="none", zorder=4,
                    label=b["name"] if label else None)
        else:
            ax.plot([at[0]], [at[1]], [at[2]], marker="o", markersize=5, color=col, linestyle="none",
                    label=b["name"] if label else None)
        if label or len(dims) == 2:
            pt = [at[d] for d in dims]
            ax.text(*pt, "  " + b["name"], fontsize=7, color=col, va="bottom") if len(dims) == 3 else \
                ax.annotate(b["name"], pt, xytext=(3, 4), textcoords="offset points", fontsize=7, color=col)
    for p in frame.get("points") or []:
        at = [float(x) for x in p["at"]]
        pt = [at[d] for d in dims]
        ax.plot(*[[v] for v in pt], marker="x", markersize=6, color="#8e44ad", linestyle="none",
                label=p["name"] if label else None)
        if len(dims) == 2:
            ax.annotate(p["name"], pt, xytext=(3, -9), textcoords="offset points", fontsize=7, color="#8e44ad")


@_styled
def fig_frame(res: Result) -> list[Fig]:
    """The trajectory in the declared frame: a 3-D view and the (x, y) and (x, z)
    projections, equal scales, with the frame's bodies and points."""
    problem = res.problem or {}
    frame = declared_frame(problem)
    if frame is None:
        return []
    names = list(problem["positions"])
    units = problem.get("units") or {}
    segs = [(p.name, frame_xyz(frame, p.states, names, units)) for p in res.phases]
    segs = [(n, xyz) for n, xyz in segs if xyz is not None and len(xyz[0])]
    if not segs:
        return []
    reint = [frame_xyz(frame, tab, names, units) for k, tab in sorted(res.tables.items())
             if k == "reintegration" or k.startswith("reintegration_")]
    reint = [x for x in reint if x is not None]
    unit = unit_tex(units.get(names[0], "")) if units.get(names[0]) else ""
    axis = [f"${c}$" + (f" [{unit}]" if unit else "") for c in ("x", "y", "z")]
    colors = _phase_colors(len(segs))
    everything = [xyz for _, xyz in segs]
    marks = [[float(x) for x in m["at"]] for m in (frame.get("bodies") or []) + (frame.get("points") or [])]
    lims = [_limits([xyz[i] for xyz in everything] + [np.array([m[i] for m in marks])]) for i in range(3)]
    out: list[Fig] = []

    # 3-D view: the box has the data's proportions, so z is not stretched
    import mpl_toolkits.mplot3d  # noqa: F401  (registers the 3d projection)
    fig = Figure(figsize=(WIDTH_IN, WIDTH_IN * 0.62), layout="constrained")
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    for (pname, xyz), c in zip(segs, colors):
        ax.plot(*xyz, color=c, linewidth=0.8, label=pname if len(segs) > 1 else "trajectory")
    ax.plot(*[[a[0]] for a in segs[0][1]], marker="o", color="k", linestyle="none", label="start")
    ax.plot(*[[a[-1]] for a in segs[-1][1]], marker="s", color="k", linestyle="none", label="end")
    _mark(ax, frame, (0, 1, 2), label=True)
    for i, setlim in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
        setlim(*lims[i])
    spans = [hi - lo for lo, hi in lims]
    ax.set_box_aspect([s / max(spans) for s in spans])
    from matplotlib.ticker import MaxNLocator
    if spans[2] < 0.15 * max(spans):      # a flat box: two ticks, not a smear of labels
        ax.zaxis.set_major_locator(MaxNLocator(2))
    ax.set_xlabel(axis[0])
    ax.set_ylabel(axis[1])
    ax.set_zlabel(axis[2])
    ax.legend(fontsize=7, frameon=False, loc="upper left", ncol=2)
    ax.view_init(elev=28, azim=-60)
    out.append(Fig("frame-3d", f"Trajectory in the {frame.get('name', 'declared frame')}, equal scales on all "
                   "three axes; circle: start, square: end, dots: the bodies, cross: "
                   + ", ".join(p["name"] for p in frame.get("points") or []) + ".", fig))

    # projections (x, y) and (x, z): equal scales (a flat z range is widened to the panel,
    # never stretched), heights from the data's proportions
    ratios = [max(spans[1], 1e-9) / spans[0], max(spans[2], 1e-9) / spans[0]]
    h = [max(1.3, min(4.2, WIDTH_IN * 0.9 * r)) for r in ratios]
    fig = Figure(figsize=(WIDTH_IN, sum(h) + 0.9), layout="constrained")
    gs = fig.add_gridspec(2, 1, height_ratios=h)
    for row, (j, lab) in enumerate(((1, "y"), (2, "z"))):
        ax = fig.add_subplot(gs[row])
        for (pname, xyz), c in zip(segs, colors):
            ax.plot(xyz[0], xyz[j], color=c, linewidth=0.7, label=(pname if len(segs) > 1 else "trajectory")
                    if row == 0 else None)
        for k, x in enumerate(reint):
            ax.plot(x[0], x[j], color="#c0392b", linestyle="--", linewidth=0.7,
                    label="re-integrated" if row == 0 and k == 0 else None)
        ax.plot(segs[0][1][0][0], segs[0][1][j][0], marker="o", color="k", linestyle="none",
                label="start" if row == 0 else None)
        ax.plot(segs[-1][1][0][-1], segs[-1][1][j][-1], marker="s", color="k", linestyle="none",
                label="end" if row == 0 else None)
        _mark(ax, frame, (0, j), label=False)
        ax.set_xlim(*lims[0])
        lo, hi = lims[j]
        want = spans[0] * (h[row] - 0.45) / (WIDTH_IN - 0.7)     # the panel's own proportions
        if hi - lo < want:          # a flat range widened about its middle, not stretched
            mid = 0.5 * (lo + hi)
            lo, hi = mid - 0.5 * want, mid + 0.5 * want
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel(axis[0])
        ax.set_ylabel(axis[j])
        if row == 0:
            ax.legend(fontsize=7, frameon=False, loc="best")
    out.append(Fig("frame-projections", f"Projections of the trajectory on the (x, y) and (x, z) planes of the "
                   f"{frame.get('name', 'declared frame')}, equal scales; discs: the bodies at their radii, "
                   "cross: " + ", ".join(p["name"] for p in frame.get("points") or [])
                   + (", dashed: the re-integrated trajectory" if reint else "") + ".", fig))
    return out
