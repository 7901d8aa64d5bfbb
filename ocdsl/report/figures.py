"""Matplotlib figures of a run folder (Agg only, no pyplot state).

Every ``fig_*`` function takes what it draws (a :class:`~ocdsl.result.Result`, tables)
and returns a list of :class:`Fig` (possibly empty when the run folder has nothing to
draw); none of them raises for a missing optional piece. :func:`to_png_data_uri`
turns a figure into an embeddable ``data:image/png;base64`` URI.
"""
from __future__ import annotations

import base64
import io
import math
import re
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ocdsl.result import PhaseTrajectory, Result
from ocdsl.report.tables import finite_or_none

WIDTH_IN = 6.4      # fits an A4 text block (17 cm) with a little room
ROW_IN = 1.85
DPI = 150
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


PALETTE_COLORS = 128   # figures are line art: an adaptive palette keeps them sharp at ~1/2.5 the size


def to_png_data_uri(fig: Figure, dpi: int = DPI) -> str:
    buf = io.BytesIO()
    FigureCanvasAgg(fig)
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    return "data:image/png;base64," + base64.b64encode(_palette_png(buf.getvalue())).decode("ascii")


def _palette_png(data: bytes) -> bytes:
    """The PNG with an adaptive palette of :data:`PALETTE_COLORS` colours (no dithering);
    the original when Pillow is missing or the palette version is not smaller."""
    try:
        from PIL import Image
        im = Image.open(io.BytesIO(data)).convert("RGB")
        q = im.quantize(colors=PALETTE_COLORS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        out = io.BytesIO()
        q.save(out, format="PNG", optimize=True)
    except Exception:  # noqa: BLE001
        return data
    return out.getvalue() if out.tell() < len(data) else data


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
        suffix = f" ({ci + 1} of {len(chunks)})" if len(chunks) > 1 else ""
        if len(labels_all) > MAX_LEGEND:
            suffix += (f" {len(labels_all)} runs, coloured in order from the first ({labels_all[0]}, dark "
                       f"blue) to the last ({labels_all[-1]}, yellow).")
        out.append(Fig(f"{key}-{ci}", caption + suffix, fig))
    return out


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


def time_variable(res: Result) -> str | None:
    """The state that is physical time when the independent variable is not (a Sundman
    run: ``problem.time_variable``); None when the independent variable is time."""
    tv = (res.problem or {}).get("time_variable")
    return tv if tv and any(tv in p.states for p in res.phases) else None


def phase_time(res: Result, p: PhaseTrajectory) -> np.ndarray:
    """Physical time of a phase's rows: what every time axis shows."""
    tv = time_variable(res)
    return np.asarray(p.states[tv] if tv and tv in p.states else p.time, float)


def _phase_series(res: Result, attr: str, prefix: str = "") -> list[tuple[str, Series]]:
    names: list[str] = []
    skip = time_variable(res) if attr == "states" else None    # time against time says nothing
    for p in res.phases:
        for n in getattr(p, attr):
            if n not in names and n != skip:
                names.append(n)
    multi = len(res.phases) > 1
    return [(prefix + n, [(p.name if multi else "solution", phase_time(res, p), getattr(p, attr)[n])
                          for p in res.phases if n in getattr(p, attr)]) for n in names]


def _sequential(res: Result) -> bool:
    """Phases one after another in time (not alternatives over the same interval, as the
    controllers of a controller file are)."""
    ends = [(float(np.nanmin(phase_time(res, p))), float(np.nanmax(phase_time(res, p)))) for p in res.phases
            if len(p.time)]
    return all(b[0] >= a[1] - 1e-9 * max(1.0, abs(a[1])) for a, b in zip(ends, ends[1:]))


def _phase_boundaries(res: Result) -> list[float]:
    if len(res.phases) < 2 or not _sequential(res):
        return []
    return [float(np.asarray(phase_time(res, p), float)[-1]) for p in res.phases[:-1] if len(p.time)]


def _phases_note(res: Result) -> str:
    if len(res.phases) < 2:
        return ""
    return " Phases in colour, phase boundaries dotted." if _sequential(res) else " One line per phase (run)."


@_styled
def fig_states_controls(res: Result) -> list[Fig]:
    """States and controls against time; control (and state) bounds dashed."""
    units = res.problem.get("units") or {}
    out: list[Fig] = []
    note = _phases_note(res)
    st = _phase_series(res, "states")
    if st:
        out += _grid_figures("states", "State histories." + note + " Dashed: bounds.", st, units,
                             _bounds_of(res.problem, [n for n, _ in st]),
                             boundaries=_phase_boundaries(res))
    ct = _phase_series(res, "controls")
    if ct:
        out += _grid_figures("controls", "Control histories; dashed lines are the control bounds." + note,
                             ct, units, _bounds_of(res.problem, [n for n, _ in ct]),
                             boundaries=_phase_boundaries(res))
    return out


@_styled
def fig_costates(res: Result) -> list[Fig]:
    panels = _phase_series(res, "costates")
    if not panels:
        return []
    tex = {n: r"\lambda_{%s}" % tex_name(n) for n, _ in panels}
    units = _time_units(res)
    return _grid_figures("costates", "Costates (multipliers of the dynamics).", panels, units, tex=tex,
                         boundaries=_phase_boundaries(res))


def _time_units(res: Result) -> dict[str, str]:
    """Only the unit of time (panels of costates and Hamiltonian quantities have none)."""
    u = (res.problem.get("units") or {}).get("t")
    return {"t": u} if u else {}


def _expected_hamiltonian(cert: Any) -> float | None:
    """The certificate's expected H (single phase, or the same in every phase)."""
    if not isinstance(cert, dict):
        return None
    vals = [c.get("hamiltonian", {}).get("expected") for c in
            ((cert.get("phases") or {}).values() if isinstance(cert.get("phases"), dict) else [cert])
            if isinstance(c, dict) and isinstance(c.get("hamiltonian"), dict)]
    vals = [finite_or_none(v) for v in vals]
    return vals[0] if vals and vals[0] is not None and all(v == vals[0] for v in vals) else None


def _controls_of(res: Result) -> list[str]:
    names: list[str] = []
    for p in res.phases:
        names += [n for n in p.controls if n not in names]
    return names


@_styled
def fig_hamiltonian(res: Result) -> list[Fig]:
    """Hamiltonian, its control gradients ``dH_d<u>`` and switching functions ``switch_<u>``."""
    out: list[Fig] = []
    multi = len(res.phases) > 1
    units = res.problem.get("units") or {}
    def ham(p: PhaseTrajectory):
        return next((p.extra[k] for k in HAMILTONIAN_KEYS if k in p.extra), None)

    series = [(p.name if multi else "solution", phase_time(res, p), ham(p)) for p in res.phases
              if ham(p) is not None]
    if series:
        expected = _expected_hamiltonian(res.certificate)
        if expected is not None:
            expected = expected + 0.0          # -0.0 -> 0.0: the legend says what the caption says
        what = (f"the certificate expects H = {expected:g} (dashed)" if expected is not None else
                "constant where the problem is autonomous")
        hfigs = _grid_figures("hamiltonian", f"Hamiltonian H along the solution: {what}.",
                              [("H", series)], _time_units(res), tex={"H": "H"}, boundaries=_phase_boundaries(res))
        if expected is not None and hfigs and hfigs[0].figure.axes:
            ax = hfigs[0].figure.axes[0]
            ax.axhline(expected, color="#c0392b", linestyle="--", linewidth=0.9, label=f"expected H = {expected:g}")
            lo, hi = ax.get_ylim()
            ax.set_ylim(min(lo, expected - 0.05 * (hi - lo)), max(hi, expected + 0.05 * (hi - lo)))
            ax.legend(fontsize=7, loc="best", frameon=False)
        out += hfigs
    grads: list[tuple[str, Series]] = []
    names: list[str] = []
    for p in res.phases:
        names += [k for k in p.extra if k.startswith("dH_d") and k not in names]
    for k in names:
        u = k[len("dH_d"):]
        grads.append((k, [(p.name if multi else "solution", phase_time(res, p), p.extra[k]) for p in res.phases
                          if k in p.extra]))
    if grads:
        tex = {k: r"\partial H / \partial %s" % tex_name(k[len("dH_d"):]) for k, _ in grads}
        out += _grid_figures("dHdu", "Gradient of the Hamiltonian with respect to each control "
                             "(zero where the control is interior).", grads, _time_units(res), tex=tex,
                             boundaries=_phase_boundaries(res))
    sw: list[str] = []
    for p in res.phases:
        sw += [k for k in p.extra if k.startswith("switch_") and k not in sw]
    if sw:
        fig, axes = _new_figure(len(sw[:MAX_PANELS]))
        for ax, k in zip(axes, sw):
            u = k[len("switch_"):]
            for p in res.phases:
                if k in p.extra:
                    ax.plot(phase_time(res, p), p.extra[k], color="#1f4e9c", label="switching function")
            ax.axhline(0.0, color="0.4", linewidth=0.7)
            ax.set_ylabel(f"$\\sigma_{{{tex_name(u)}}}$")
            ax.set_xlabel(time_label(units))
            if any(u in p.controls for p in res.phases):
                ax2 = ax.twinx()
                for p in res.phases:
                    if u in p.controls:
                        ax2.step(phase_time(res, p), p.controls[u], where="post", color="#c0392b",
                                 linewidth=1.0, alpha=0.8, label=f"${tex_name(u)}$")
                ax2.set_ylabel(axis_label(u, units), color="#c0392b")
                ax2.grid(False)
                h1, l1 = ax.get_legend_handles_labels()
                h2, l2 = ax2.get_legend_handles_labels()
                ax.legend(h1 + h2[:1], l1 + l2[:1], fontsize=7, frameon=False, loc="best")
        out.append(Fig("switching", "Switching functions (blue) with the control they switch (red, right axis).", fig))
    return out


@_styled
def fig_other_extra(res: Result) -> list[Fig]:
    """Time histories in the trajectory that are neither states, controls, costates nor
    Hamiltonian quantities (e.g. when the problem description is missing)."""
    multi = len(res.phases) > 1
    names: list[str] = []
    for p in res.phases:
        names += [k for k in p.extra if k not in names and k not in HAMILTONIAN_KEYS
                  and k not in FLAG_COLUMNS and not k.startswith(("dH_d", "switch_"))]
    panels = [(k, [(p.name if multi else "solution", phase_time(res, p), p.extra[k]) for p in res.phases
                   if k in p.extra])
              for k in names]
    return _grid_figures("other", "Other time histories in the trajectory.", panels,
                         res.problem.get("units") or {}, boundaries=_phase_boundaries(res))


@_styled
def fig_reintegration(res: Result) -> list[Fig]:
    """Collocated states (markers) against the re-integrated trajectory (line)."""
    out: list[Fig] = []
    units = res.problem.get("units") or {}
    for tname, table in sorted(res.tables.items()):
        if not (tname == "reintegration" or tname.startswith("reintegration_")) or "t" not in table:
            continue
        phase = tname[len("reintegration_"):] if tname != "reintegration" else None
        phases = [p for p in res.phases if phase is None or p.name == phase]
        tvar = time_variable(res)
        names = [k for k in table if k not in ("t", tvar) and not k.startswith("err_") and _nonempty(table[k])]
        if not names:
            continue
        chunks = _chunks(names, MAX_PANELS)
        for ci, chunk in enumerate(chunks):
            fig, axes = _new_figure(len(chunk))
            for ax, n in zip(axes, chunk):
                ax.plot(table.get(tvar, table["t"]) if tvar else table["t"], table[n], color="#c0392b",
                        linewidth=1.2, label="re-integrated")
                first = True
                for p in phases:
                    if n in p.states:
                        ax.plot(phase_time(res, p), p.states[n], linestyle="none", marker="o", markersize=2.6,
                                markerfacecolor="none", color="#1f4e9c",
                                label="collocated" if first else None)
                        first = False
                ax.set_ylabel(axis_label(n, units))
                ax.set_xlabel(time_label(units))
                ax.legend(fontsize=7, frameon=False, loc="best")
            where = f" of phase {phase}" if phase else ""
            suffix = f" ({ci + 1} of {len(chunks)})" if len(chunks) > 1 else ""
            out.append(Fig(f"reint-{tname}-{ci}",
                           f"Re-integrated trajectory{where} (line, from the optimal control) "
                           f"over the collocated states (markers).{suffix}", fig))
    return out


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


# ------------------------------------------------------------------- closed loop
def closed_loop_tables(tables: dict[str, dict[str, np.ndarray]]) -> dict[str, dict[str, np.ndarray]]:
    return {k[len("closed_loop_"):]: v for k, v in sorted(tables.items())
            if k.startswith("closed_loop_") and "t" in v}


@_styled
def fig_closed_loop(tables: dict[str, dict[str, np.ndarray]], problem: dict, label_prefix: str = "") -> list[Fig]:
    """Closed-loop responses of each controller (one line per controller) and the
    controller's computation time per update (``timing`` column)."""
    cl = closed_loop_tables(tables)
    if not cl:
        return []
    units = problem.get("units") or {}
    states: list[str] = []
    controls: list[str] = []
    known_states, known_controls = set(), set()
    for info in (problem.get("phases") or {}).values():
        known_states |= set(info.get("states") or [])
        known_controls |= set(info.get("controls") or [])
    for tab in cl.values():
        for k in tab:
            if k in ("t", "timing"):
                continue
            if k in known_controls:
                controls += [k] if k not in controls else []
            elif k in known_states or not known_states:
                states += [k] if k not in states else []
    out: list[Fig] = []
    names = [label_prefix + c for c in cl]
    st = [(n, [(label_prefix + c, tab["t"], tab[n]) for c, tab in cl.items() if n in tab]) for n in states]
    out += _grid_figures("cl-states", "Closed-loop state responses, one line per controller.", st, units)
    ct = [(n, [(label_prefix + c, tab["t"], tab[n]) for c, tab in cl.items() if n in tab]) for n in controls]
    if ct:
        out += _grid_figures("cl-controls", "Closed-loop control histories (dashed: control bounds).",
                             ct, units, _bounds_of(problem, controls), step=True)
    timing = [(nm, np.asarray(tab["timing"], float)) for nm, tab in zip(names, cl.values()) if "timing" in tab]
    timing = [(nm, a[np.isfinite(a)] * 1e3) for nm, a in timing if _nonempty(a)]
    if timing:
        fig, axes = _new_figure(2, height=2.6)
        ax = axes[0]
        ax.boxplot([a for _, a in timing], showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(timing) + 1), [nm for nm, _ in timing], rotation=20, fontsize=7)
        ax.set_ylabel("time per update [ms]")
        ax.set_yscale("log")
        ax = axes[1]
        for (nm, a), tab, c in zip(timing, [t for t in cl.values() if "timing" in t], _run_colors(len(timing))):
            t = np.asarray(tab["t"], float)
            a_full = np.asarray(tab["timing"], float) * 1e3
            ax.plot(t, a_full, color=c, linewidth=0.8, label=nm)
        ax.set_yscale("log")
        ax.set_xlabel(time_label(units))
        ax.set_ylabel("time per update [ms]")
        if len(timing) <= MAX_LEGEND:
            ax.legend(fontsize=7, frameon=False)
        out.append(Fig("cl-timing", "Controller computation time per update: distribution (left) "
                       "and along the closed-loop run (right).", fig))
    return out


# --------------------------------------------------------------------- studies
@_styled
def fig_pareto(rows: list[dict[str, Any]], criteria: tuple[str, str], units: dict | None = None,
               flag: str = "pareto") -> list[Fig]:
    """Criteria plane: every solution (hollow, coloured by ``family`` when present), the
    Pareto-optimal ones filled and joined."""
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
    par = sorted([(x, y) for r, x, y in pts if _truthy(r.get(flag))])
    if par:
        ax.plot([p[0] for p in par], [p[1] for p in par], color="#c0392b", marker="o", markersize=5,
                linewidth=1.0, drawstyle="steps-post" if len(par) > 1 else "default", label="Pareto set")
    if len(pts) <= 40:
        lab_key = next((k for k in ("label", "solution", "name", "point") if k in pts[0][0]), None)
        if lab_key:
            for r, x, y in pts:
                ax.annotate(str(r.get(lab_key)), (x, y), fontsize=6.5, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel(axis_label(a, units or {}, r"\mathrm{%s}" % a.replace("_", r"\_")))
    ax.set_ylabel(axis_label(b, units or {}, r"\mathrm{%s}" % b.replace("_", r"\_")))
    ax.legend(fontsize=7, frameon=False, loc="best")
    return [Fig("pareto", f"Pareto front in the ({a}, {b}) criteria plane: all solutions hollow, "
                "Pareto-optimal solutions filled and joined in red.", fig)]


def _truthy(v: Any) -> bool:
    if isinstance(v, str):
        return v.strip().lower() in ("1", "1.0", "true", "yes", "y", "t")
    f = finite_or_none(v)
    return bool(f) if f is not None else False


@_styled
def fig_sweep(rows: list[dict[str, Any]], param: str, outputs: Sequence[str], units: dict | None = None,
              objective_label: str = "objective") -> list[Fig]:
    """Outputs (objective, t_f per phase) against the swept parameter; points that did not
    converge marked x."""
    outputs = [o for o in outputs if any(finite_or_none(r.get(o)) is not None for r in rows)]
    if not outputs:
        return []
    units = units or {}
    fig, axes = _new_figure(len(outputs))
    good = ("optimal", "acceptable", "feasible", "stable")
    for ax, o in zip(axes, outputs):
        pts = [(float(r[param]), float(r[o]), str(r.get("status", "optimal")) in good) for r in rows
               if finite_or_none(r.get(param)) is not None and finite_or_none(r.get(o)) is not None]
        ok = sorted((x, y) for x, y, g in pts if g)
        bad = [(x, y) for x, y, g in pts if not g]
        if ok:
            ax.plot([p[0] for p in ok], [p[1] for p in ok], marker="o", markersize=3, label="converged")
        if bad:
            ax.plot([p[0] for p in bad], [p[1] for p in bad], "x", color="#c0392b", label="not converged")
            ax.legend(fontsize=7, frameon=False)
        ax.set_xlabel(axis_label(param, units))
        if o == "objective":
            ax.set_ylabel(objective_label)
        else:
            phase = o[len("tf ("):-1] if o.startswith("tf (") else ""
            unit = units.get("t")
            ax.set_ylabel("$t_f$" + (f" ({phase})" if phase else "") + (f" [{unit_tex(unit)}]" if unit else ""))
    return [Fig("sweep", f"Study outputs against the swept parameter {param}.", fig)]


@_styled
def fig_histograms(rows: list[dict[str, Any]], outputs: Sequence[str]) -> list[Fig]:
    data = [(o, np.array([finite_or_none(r.get(o)) for r in rows if finite_or_none(r.get(o)) is not None]))
            for o in outputs]
    data = [(o, a) for o, a in data if a.size >= 2]
    if not data:
        return []
    fig, axes = _new_figure(len(data))
    for ax, (o, a) in zip(axes, data):
        ax.hist(a, bins=min(30, max(5, a.size // 3)), color="#1f4e9c", alpha=0.8)
        ax.set_xlabel(o.replace("_", " "))
        ax.set_ylabel("runs")
    return [Fig("histograms", "Distribution of the study outputs over its runs.", fig)]


@_styled
def fig_compare_runs(results: list[Result]) -> list[Fig]:
    """States and controls of several runs overlaid (one line per run)."""
    if not results or not any(r.phases for r in results):
        return []
    problem = next((r.problem for r in results if r.problem), {})
    units = problem.get("units") or {}
    out: list[Fig] = []
    for attr, what in (("states", "State"), ("controls", "Control")):
        names: list[str] = []
        for r in results:
            for p in r.phases:
                names += [n for n in getattr(p, attr) if n not in names]
        panels = [(n, [(r.name, phase_time(r, p), getattr(p, attr)[n]) for r in results for p in r.phases
                       if n in getattr(p, attr)]) for n in names]
        if panels:
            out += _grid_figures(f"cmp-{attr}", f"{what} histories of the compared runs, one colour per run.",
                                 panels, units, _bounds_of(problem, names) if attr == "controls" else None)
    return out


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
