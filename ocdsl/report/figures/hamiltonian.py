"""The Hamiltonian, its control gradients and the switching functions."""
from __future__ import annotations

from typing import Any

from ocdsl.result import PhaseTrajectory, Result
from ocdsl.report.tables import finite_or_none
from ocdsl.report.figures.base import (
    Fig, HAMILTONIAN_KEYS, MAX_PANELS, Series, _grid_figures, _new_figure, _styled, axis_label, tex_name,
    time_label)
from ocdsl.report.figures.time import _phase_boundaries, _time_units, phase_time


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
