"""A solution between its rows: states and controls at any time of a phase.

The controls follow the documented interpolation of the run (``PhaseTrajectory.
control_interpolation``, the verification contract): ``lagrange-segments`` (inside each
segment the Lagrange polynomial through that segment's collocated rows), ``cubic``,
``linear`` or ``previous`` (zero-order hold), clipped to their box bounds. States are the
Lagrange polynomial through each segment's rows for ``lagrange-segments`` (a pseudospectral
state is that polynomial), else a cubic spline through all rows.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline, interp1d

KINDS = ("lagrange-segments", "cubic", "linear", "previous")


def interpolation_of(phase, method: dict[str, Any] | None) -> dict[str, Any]:
    """The phase's control interpolation: as recorded with it, else the one its method implies
    (the pseudospectral mesh's segments, in physical time), else linear."""
    given = getattr(phase, "control_interpolation", None)
    if given:
        return dict(given)
    mesh = ((method or {}).get("meshes") or {}).get(phase.name)
    t = np.asarray(phase.time, float)
    if mesh and len(t) > 1:
        s = np.asarray(mesh["breakpoints"], float)
        return {"kind": "lagrange-segments", "breakpoints": (t[0] + (t[-1] - t[0]) * s).tolist()}
    return {"kind": "linear"}


def sample_phase(phase, t, interpolation: dict[str, Any], bounds: dict[str, list] | None = None
                 ) -> dict[str, np.ndarray]:
    """``{"t": t, state: ..., control: ...}`` at the times ``t`` (inside the phase's span;
    outside it, the nearest segment's polynomial is extended)."""
    t = np.atleast_1d(np.asarray(t, float))
    rows = np.asarray(phase.time, float)
    collocated = np.asarray(phase.extra.get("collocated", np.ones(len(rows))), float) > 0.5
    kind = interpolation.get("kind", "linear")
    if kind not in KINDS:
        raise ValueError(f"unknown control interpolation {kind!r}; known: {', '.join(KINDS)}")
    out: dict[str, np.ndarray] = {"t": t}
    if kind == "lagrange-segments":
        breaks = np.asarray(interpolation["breakpoints"], float)
        for name, values in phase.states.items():
            out[name] = _lagrange_segments(rows, np.asarray(values, float), np.ones(len(rows), bool), breaks, t)
        for name, values in phase.controls.items():
            out[name] = _lagrange_segments(rows, np.asarray(values, float), collocated, breaks, t)
    else:
        for name, values in phase.states.items():
            out[name] = _through_rows(rows, np.asarray(values, float), "cubic", t)
        for name, values in phase.controls.items():
            out[name] = _through_rows(rows, np.asarray(values, float), kind, t)
    for name in phase.controls:
        lo, hi = (bounds or {}).get(name) or (None, None)
        out[name] = np.clip(out[name], -math.inf if lo is None else lo, math.inf if hi is None else hi)
    return out


def _through_rows(rows, values, kind, t):
    keep = np.concatenate([[True], np.diff(rows) > 0]) & np.isfinite(values)
    x, y = rows[keep], values[keep]
    if len(x) == 1:
        return np.full(len(t), y[0])
    if kind == "cubic" and len(x) > 2:
        return CubicSpline(x, y)(t)
    return interp1d(x, y, kind="previous" if kind == "previous" else "linear", bounds_error=False,
                    fill_value=(y[0], y[-1]), assume_sorted=True)(t)


def _lagrange_segments(rows, values, use, breaks, t):
    out = np.full(len(t), np.nan)
    # a time on a breakpoint belongs to the segment that ends there (the first one starts there)
    seg = np.clip(np.searchsorted(breaks, t, side="left") - 1, 0, len(breaks) - 2)
    tol = 1e-12 * max(1.0, abs(breaks[-1] - breaks[0]))
    for k in np.unique(seg):
        inside = use & (rows >= breaks[k] - tol) & (rows <= breaks[k + 1] + tol) & np.isfinite(values)
        x, y = rows[inside], values[inside]
        x, first = np.unique(x, return_index=True)
        y = y[first]
        sel = seg == k
        out[sel] = _lagrange(x, y, t[sel]) if len(x) else np.nan
    return out


def _lagrange(x, y, t):
    """Barycentric Lagrange interpolation through (x, y), evaluated at t."""
    if len(x) == 1:
        return np.full(len(t), y[0])
    w = np.array([1.0 / np.prod(x[j] - np.delete(x, j)) for j in range(len(x))])
    d = t[:, None] - x[None, :]
    exact = d == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        c = w / d
        vals = (c @ y) / c.sum(axis=1)
    hit = exact.any(axis=1)
    vals[hit] = y[np.argmax(exact[hit], axis=1)]
    return vals
