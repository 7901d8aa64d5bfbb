"""The figures' common parts: style, :class:`Fig`, labels, vector output, and the
grid of time-history panels every time-history figure uses."""
from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ocdsl.report.tables import finite_or_none


WIDTH_IN = 6.4      # fits an A4 text block (17 cm) with a little room
ROW_IN = 1.85
MAX_PANELS = 8      # panels per figure; more are split into several figures
MAX_LEGEND = 10
HAMILTONIAN_KEYS = ("H", "hamiltonian")
FLAG_COLUMNS = ("collocated", "node", "segment", "mesh_segment")   # bookkeeping, not drawn

STYLE = {
    "font.family": "serif",
    "font.serif": ["STIXGeneral", "DejaVu Serif"],
    "mathtext.fontset": "stix",
    "font.size": 9,
    "axes.titlesize": 9,
    "axes.labelsize": 9,
    "legend.fontsize": 7.5,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "grid.linewidth": 0.5,
    "lines.linewidth": 1.3,
    "axes.prop_cycle": __import__("matplotlib").cycler(
        color=["#1f4e9c", "#c0392b", "#2a9d55", "#8e44ad", "#e67e22", "#16a0a8",
               "#7f6a00", "#d63384", "#555555", "#5d8aa8"]),
}

GREEK = ("alpha beta gamma delta epsilon zeta eta theta iota kappa lambda mu nu xi pi rho "
         "sigma tau upsilon phi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma Upsilon "
         "Phi Psi Omega").split()


@dataclass
class Fig:
    """A figure with its caption (numbered later by the report builder)."""

    key: str
    caption: str
    figure: Figure


# ---------------------------------------------------------------------------- labels
def tex_name(name: str) -> str:
    """LaTeX (mathtext) for a symbol name: ``theta_1`` -> ``\\theta_{1}``, ``q0`` -> ``q_{0}``."""
    name = str(name)
    if not re.fullmatch(r"[A-Za-z0-9_]+", name):
        return r"\mathrm{%s}" % re.sub(r"([\\{}$^_#%&~])", r"\\\1", name)
    base, sub = name, ""
    if "_" in name.strip("_"):
        base, sub = name.strip("_").split("_", 1)
    else:
        m = re.fullmatch(r"([A-Za-z]+?)(\d+)", name)
        if m:
            base, sub = m.groups()
    if base in GREEK:
        tex = "\\" + base
    elif len(base) == 1 or not base:
        tex = base
    else:
        tex = r"\mathrm{%s}" % base
    if sub:
        tex += "_{%s}" % (tex_name(sub) if sub.replace("_", "").isalpha() and sub in GREEK
                          else (r"\mathrm{%s}" % sub.replace("_", r"\_") if len(sub) > 1 and not sub.isdigit()
                                else sub))
    return tex


def axis_label(name: str, units: dict[str, str] | None, tex: str | None = None) -> str:
    unit = (units or {}).get(name)
    lab = f"${tex or tex_name(name)}$"
    return f"{lab} [{unit_tex(unit)}]" if unit else lab


def unit_tex(unit: str) -> str:
    """``m/s^2`` -> ``m/s$^{2}$`` (exponents as mathtext superscripts)."""
    return re.sub(r"\^\(?([-+]?\d+(?:\.\d+)?)\)?", r"$^{\1}$", str(unit).replace("$", ""))


def time_label(units: dict[str, str] | None) -> str:
    return axis_label("t", units)


def to_svg(fig: Figure) -> bytes:
    """The figure as SVG (vector; text as paths, so it looks the same everywhere)."""
    import matplotlib
    buf = io.BytesIO()
    FigureCanvasAgg(fig)
    with matplotlib.rc_context({"svg.hashsalt": "ocdsl", "svg.fonttype": "path"}):
        fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
    return buf.getvalue()


def to_pdf(fig: Figure) -> bytes:
    """The figure as a one-page vector PDF, for a paper."""
    buf = io.BytesIO()
    FigureCanvasAgg(fig)
    fig.savefig(buf, format="pdf", metadata={"CreationDate": None, "Creator": None, "Producer": None})
    return buf.getvalue()


def _new_figure(n_panels: int, ncols: int | None = None, height: float | None = None):
    import matplotlib
    ncols = ncols or (1 if n_panels == 1 else 2)
    nrows = math.ceil(n_panels / ncols)
    with matplotlib.rc_context(STYLE):
        fig = Figure(figsize=(WIDTH_IN, height or (0.45 + ROW_IN * nrows)), layout="constrained")
        axes = [fig.add_subplot(nrows, ncols, i + 1) for i in range(n_panels)]
    return fig, axes


def _styled(func):
    """Run a figure builder inside the report's matplotlib style."""
    def wrapper(*args, **kwargs):
        import matplotlib
        with matplotlib.rc_context(STYLE):
            return func(*args, **kwargs)
    wrapper.__name__ = func.__name__
    wrapper.__doc__ = func.__doc__
    return wrapper


def _chunks(seq: Sequence, n: int) -> list[Sequence]:
    return [seq[i:i + n] for i in range(0, len(seq), n)] or []


def _nonempty(a: Any) -> bool:
    a = np.asarray(a, float)
    return a.size > 0 and bool(np.any(np.isfinite(a)))


def _phase_colors(n: int) -> list[str]:
    cyc = STYLE["axes.prop_cycle"].by_key()["color"]
    return [cyc[i % len(cyc)] for i in range(n)]


def _run_colors(n: int) -> list:
    if n <= len(_phase_colors(10)):
        return _phase_colors(n)
    import matplotlib
    cmap = matplotlib.colormaps["viridis"]
    return [cmap(i / max(n - 1, 1)) for i in range(n)]


def _marker_kw(n_points: int) -> dict:
    return {"marker": "o", "markersize": 2.2} if n_points <= 80 else {}


# ------------------------------------------------------------------ time histories
Series = list[tuple[str, np.ndarray, np.ndarray]]   # (label, t, y)


def _grid_figures(key: str, caption: str, panels: list[tuple[str, Series]], units: dict,
                  bounds: dict[str, tuple[float | None, float | None]] | None = None,
                  tex: dict[str, str] | None = None, step: bool = False,
                  boundaries: Iterable[float] = (), colors: list | None = None,
                  linestyles: dict[str, str] | None = None) -> list[Fig]:
    """One panel per variable, one line per series label; split into figures of
    :data:`MAX_PANELS` panels."""
    panels = [(n, s) for n, s in panels if any(_nonempty(y) for _, _, y in s)]
    out: list[Fig] = []
    chunks = _chunks(panels, MAX_PANELS)
    labels_all: list[str] = []
    for _, series in panels:
        for lab, _, _ in series:
            if lab not in labels_all:
                labels_all.append(lab)
    colors_default = colors is None
    colors = colors or _run_colors(len(labels_all))
    color_of = {lab: colors[i % len(colors)] for i, lab in enumerate(labels_all)}
    for ci, chunk in enumerate(chunks):
        fig, axes = _new_figure(len(chunk))
        for ax, (name, series) in zip(axes, chunk):
            for lab, t, y in series:
                t, y = np.asarray(t, float), np.asarray(y, float)
                kw = {} if len(labels_all) > 1 else _marker_kw(len(t))
                if step:
                    ax.step(t, y, where="post", color=color_of[lab], label=lab,
                            linestyle=(linestyles or {}).get(lab, "-"), **kw)
                else:
                    ax.plot(t, y, color=color_of[lab], label=lab,
                            linestyle=(linestyles or {}).get(lab, "-"), **kw)
            lo, hi = (bounds or {}).get(name, (None, None))
            lo, hi = (b if _near(b, [y for _, _, y in series]) else None for b in (lo, hi))
            drew_bound = False
            for b in (lo, hi):
                if b is not None:
                    ax.axhline(b, color="0.35", linestyle="--", linewidth=0.9,
                               label=None if drew_bound else "bound")
                    drew_bound = True
            for tb in boundaries:
                ax.axvline(tb, color="0.6", linestyle=":", linewidth=0.9)
            _readable_y(ax, [y for _, _, y in series] + [b for b in (lo, hi) if b is not None])
            ax.set_ylabel(axis_label(name, units, (tex or {}).get(name)))
            ax.set_xlabel(time_label(units))
            if (1 < len(labels_all) <= MAX_LEGEND) or drew_bound:
                handles, labs = ax.get_legend_handles_labels()
                if len(labels_all) > MAX_LEGEND:     # too many runs to name: only the bound
                    handles, labs = [h for h, l in zip(handles, labs) if l == "bound"], ["bound"] * ("bound" in labs)
                if labs:
                    ax.legend(handles, labs, fontsize=7, loc="best", frameon=False)
        if len(labels_all) > MAX_LEGEND and colors_default:     # the colour is the run's place in order
            import matplotlib
            from matplotlib.cm import ScalarMappable
            from matplotlib.colors import Normalize
            sm = ScalarMappable(Normalize(1, len(labels_all)), matplotlib.colormaps["viridis"])
            cb = fig.colorbar(sm, ax=axes, shrink=0.8, aspect=30, pad=0.01)
            cb.set_label("run, in order", fontsize=7.5)
            cb.ax.tick_params(labelsize=7)
        suffix = f" ({ci + 1} of {len(chunks)})" if len(chunks) > 1 else ""
        if len(labels_all) > MAX_LEGEND:
            suffix += (f" {len(labels_all)} runs, coloured in order from the first ({labels_all[0]}, dark "
                       f"blue) to the last ({labels_all[-1]}, yellow; colour bar).")
        out.append(Fig(f"{key}-{ci}", caption + suffix, fig))
    return out


def in_degrees(panels: list[tuple[str, Series]], bounds: dict | None, units: dict,
               problem: dict) -> tuple[list[tuple[str, Series]], dict | None, dict]:
    """Angles the file gave in degrees (``problem.display_units``: name -> "deg", from
    inputs such as ``10deg``) drawn in degrees, with their bounds; the rest unchanged."""
    deg = [n for n, u in (problem.get("display_units") or {}).items()
           if u == "deg" and str(units.get(n, "rad")) == "rad"]
    if not deg:
        return panels, bounds, units
    k = 180.0 / math.pi
    panels = [(n, [(lab, t, np.asarray(y, float) * k) for lab, t, y in series] if n in deg else series)
              for n, series in panels]
    if bounds:
        bounds = {n: tuple(None if b is None else b * k for b in lohi) if n in deg else lohi
                  for n, lohi in bounds.items()}
    return panels, bounds, {**units, **{n: "deg" for n in deg}}


def _near(bound: float | None, ys: list, margin: float = 0.25) -> bool:
    """A bound is drawn only when it lies within ``margin`` of the data's span of the data:
    a loose bound (h <= 1e6 for a landing from 1 km) would flatten the curve."""
    if bound is None:
        return False
    vals = np.concatenate([np.ravel(np.asarray(y, float)) for y in ys]) if ys else np.array([])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return False
    lo, hi = float(vals.min()), float(vals.max())
    span = max(hi - lo, 1e-12 * max(abs(lo), abs(hi), 1.0))
    return lo - margin * span <= bound <= hi + margin * span


def _readable_y(ax, ys: list) -> None:
    """No offset notation on the y axis (``1e-12 - 9.99e-1``), and a numerically constant
    series (spread below 1e-3 of its size) drawn in a band of 2 % of its size (or +-1 at 0)
    instead of magnifying rounding noise."""
    try:
        ax.yaxis.get_major_formatter().set_useOffset(False)
    except AttributeError:
        pass
    vals = np.concatenate([np.ravel(np.asarray(y, float)) for y in ys]) if ys else np.array([])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return
    lo, hi = float(vals.min()), float(vals.max())
    size = max(abs(lo), abs(hi))
    if hi - lo <= 1e-3 * size or size == 0.0:
        mid, half = 0.5 * (lo + hi), (0.02 * size if size > 0 else 1.0)
        ax.set_ylim(mid - half, mid + half)


def _bounds_of(problem: dict, names: Iterable[str]) -> dict[str, tuple[float | None, float | None]]:
    res: dict[str, tuple[float | None, float | None]] = {}
    phases = problem.get("phases") or {}
    for info in phases.values() if isinstance(phases, dict) else []:
        for n, b in (info.get("bounds") or {}).items():
            if n in names and isinstance(b, (list, tuple)) and len(b) == 2 and n not in res:
                res[n] = (finite_or_none(b[0]), finite_or_none(b[1]))
    return res
