"""Controls between a trajectory's rows, as the run folder documents them.

A :class:`~ocdsl.result.PhaseTrajectory` carries ``control_interpolation``:

* ``{"kind": "lagrange-segments", "breakpoints": [t_0, ..., t_K]}``: inside each segment
  the Lagrange polynomial through that segment's collocated rows (pseudospectral
  collocation: the NLP's own control representation);
* ``{"kind": "cubic"}``: a not-a-knot cubic spline through the rows (dense exports of
  smooth controls); with ``"breakpoints": [t_0, ..., t_K]`` one such cubic per span between
  them, through the rows of that span (its ends included): a control smooth inside the spans
  and only continuous at their ends (the flat route's controls at the spline's knots);
* ``{"kind": "linear"}``, ``{"kind": "previous"}`` (zero-order hold);
* ``{"kind": "series", "layout": {"kinds": [...], "orders": [...]}, "coefficients": [...],
  "horizon": T}``: the control law itself, a Fourier/polynomial series per control over
  ``[t0, t0 + T]`` (parametric methods: ``ocdsl.simulate.ControlLayout``).

Every interpolated control is clipped to its box bounds: between rows the control takes
the bound-respecting value, never an overshoot that the solution did not have. The
verification also projects it onto what control-affine path constraints allow at the flown
state (:mod:`ocdsl.verify.admissible`).
"""
from __future__ import annotations

import math

import numpy as np

KINDS = ("lagrange-segments", "cubic", "linear", "previous", "series")


def segment_of_nodes(t, segments, later: bool = False) -> np.ndarray:
    """The segment owning each node: ``segments[k] < t <= segments[k+1]`` (the first segment
    also owns ``t == segments[0]``).

    A node on an interior boundary is the **end** of the segment before it, never the start
    of the one after it: that is where a collocated value sitting on a boundary comes from
    (the flipped-LGR end node; for LGL the shared node, reported with the earlier segment's
    control). Fitting the later segment's polynomial through it as well would mix the two
    segments' controls, which for a bang-bang control switching on a boundary puts a
    polynomial through both bounds (the double integrator's 2e-2 "re-integration error").
    With ``later`` it is the start of the segment after it (LGR-start, whose segments
    collocate at their start only: the row there is the later segment's own node).
    """
    t = np.asarray(t, float)
    seg = np.asarray(segments, float)
    # a node computed as a + (tau + 1) (b - a) / 2 with tau = 1 may land an ulp past b
    eps = 1e-9 * max(float(seg[-1] - seg[0]), 1e-300)
    if later:       # LGR-start: a node on an interior boundary is the start of the segment after it
        k = np.searchsorted(seg, t + eps, side="right") - 1
    else:
        k = np.searchsorted(seg, t - eps, side="left") - 1
    return np.clip(k, 0, len(seg) - 2)


def _inside(times, a: float, b: float) -> list[float]:
    """``times`` sorted, without repeats and without those within 1e-12 of the span of a or b."""
    eps = 1e-12 * max(abs(b - a), 1e-300)
    out: list[float] = []
    for t in sorted(times):
        if a + eps < t < b - eps and (not out or t - out[-1] > eps):
            out.append(t)
    return out


def _sampled_crossings(raw, a: float, b: float, lo, hi, samples: int = 65) -> list[float]:
    """Where the unclipped controls ``raw(tt) -> (P, m)`` cross a finite bound inside [a, b]:
    sign changes on ``samples`` points, each refined by bisection (a crossing and its return
    closer together than the sample spacing is not seen)."""
    tt = np.linspace(a, b, samples)
    U = raw(tt)
    out = []
    for j in range(U.shape[1]):
        for bound in (lo[j], hi[j]):
            if not math.isfinite(bound):
                continue
            d = U[:, j] - bound
            for k in np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0):
                left, right, dl = tt[k], tt[k + 1], d[k]
                for _ in range(60):
                    mid = 0.5 * (left + right)
                    dm = raw(np.array([mid]))[0, j] - bound
                    if dm == 0 or mid in (left, right):
                        break
                    if np.sign(dm) == np.sign(dl):
                        left, dl = mid, dm
                    else:
                        right = mid
                out.append(float(0.5 * (left + right)))
    return _inside(out, a, b)


_TEMPLATES: dict[tuple, object] = {}


def _control_template(degree_terms: int, lo_finite: tuple, hi_finite: tuple):
    """A factory ``(c, hw, coefficients control by control, finite lower bounds, finite upper
    bounds) -> control(s)`` for controls of ``degree_terms`` power-basis coefficients each."""
    key = (degree_terms, lo_finite, hi_finite)
    made = _TEMPLATES.get(key)
    if made is not None:
        return made
    m = len(lo_finite)
    coef = [f"a{j}_{k}" for j in range(m) for k in range(degree_terms)]
    lows = [f"lo{j}" for j in range(m) if lo_finite[j]]
    highs = [f"hi{j}" for j in range(m) if hi_finite[j]]
    body = ["    def control(s):", "        z = (s - c) / hw"]
    for j in range(m):
        horner = "0.0"
        for k in range(degree_terms):
            horner = f"({horner} * z + a{j}_{k})"
        body.append(f"        u{j} = {horner}")
        # max(u, lo) then min(., hi), as np.minimum(np.maximum(...)): a NaN stays NaN
        if lo_finite[j]:
            body.append(f"        u{j} = u{j} if u{j} >= lo{j} or u{j} != u{j} else lo{j}")
        if hi_finite[j]:
            body.append(f"        u{j} = u{j} if u{j} <= hi{j} or u{j} != u{j} else hi{j}")
    body.append(f"        return [{', '.join(f'u{j}' for j in range(m))}]")
    src = "\n".join([f"def factory(c, hw, {', '.join(coef + lows + highs)}):", *body, "    return control"])
    scope: dict = {}
    exec(compile(src, f"<control template {key}>", "exec"), scope)
    _TEMPLATES[key] = scope["factory"]
    return scope["factory"]


def _power_basis(a: float, b: float, t, U):
    """(centre, half-width, power-basis coefficients) of the polynomial through the nodes
    ``t`` (values ``U``) of the segment [a, b], in z = (time - centre) / half-width."""
    c, hw = 0.5 * (a + b), 0.5 * (b - a)
    return c, hw, np.linalg.solve(np.vander((t - c) / hw, len(t)), U)


class SegmentPolynomials:
    """Control as a function of time: piecewise linear through the nodes, or, with segment
    boundaries, the Lagrange polynomial through each segment's nodes; clipped to bounds."""

    state_dependent = False

    def __init__(self, t, U, bounds, segments=None, starts=None, later: bool = False):
        """``starts``: per segment, the control collocated at its own start where that start is
        a node shared with the segment before (LGL, LGR-start; ``segment_starts`` of the
        interpolation spec), else None: the shared row carries the earlier segment's value.
        ``later``: a row on a breakpoint is the later segment's (``breakpoint_rows: later``,
        LGR-start, whose segments collocate at their start and not at their end)."""
        self.t, self.U = t, U
        self.lo = np.array([b[0] for b in bounds])
        self.hi = np.array([b[1] for b in bounds])
        self.segments = None if segments is None else np.asarray(segments, float)
        self._pieces: dict[int, object] = {}
        if self.segments is not None:
            self.coef = []   # per segment: (centre, half-width, power-basis coefficients)
            owner = segment_of_nodes(t, self.segments, later)
            for k, (a, b) in enumerate(zip(self.segments[:-1], self.segments[1:])):
                sel = np.flatnonzero(owner == k)
                tk, Uk = t[sel], U[sel]
                own = None if starts is None or k >= len(starts) else starts[k]
                if own is not None:
                    tk = np.concatenate([[a], tk])
                    Uk = np.vstack([np.asarray(own, float).reshape(1, -1), Uk])
                if len(tk) == 0:
                    raise ValueError("control interpolation: a segment holds no collocated row")
                self.coef.append(_power_basis(a, b, tk, Uk))

    @classmethod
    def of_segments(cls, breaks, times, values, bounds) -> "SegmentPolynomials":
        """The same from each segment's own nodes (``times[k]``, ``values[k]``: (N_k,), (N_k, m)),
        where which segment a node belongs to is known (mesh refinement: an LGR end node is
        also the next segment's start)."""
        self = cls.__new__(cls)
        self.t, self.U = np.concatenate(times), np.concatenate(values)
        self.lo = np.array([b[0] for b in bounds])
        self.hi = np.array([b[1] for b in bounds])
        self.segments = np.asarray(breaks, float)
        self._pieces = {}
        self.coef = []
        for a, b, t, U in zip(self.segments[:-1], self.segments[1:], times, values):
            if not b > a:      # a segment of zero duration: its mean value
                self.coef.append((0.5 * (a + b), 1.0, np.mean(np.atleast_2d(U), axis=0, keepdims=True)))
                continue
            self.coef.append(_power_basis(a, b, np.asarray(t, float), U))
        return self

    def piece(self, tt: float):
        """The control on the piece holding ``tt``, as a function of one time returning a
        list (plain floats: what an integrator calls thousands of times)."""
        if self.segments is None:
            return lambda s: self(s).tolist()
        i = int(np.clip(np.searchsorted(self.segments, tt, side="right") - 1, 0, len(self.coef) - 1))
        made = self._pieces.get(i)
        if made is None:
            made = self._pieces[i] = self._straight_line(i)
        return made

    def kinks(self, a: float, b: float) -> list[float]:
        """Where, strictly inside [a, b] (one piece: one segment), a control's polynomial
        crosses a finite bound, so the clipped control has a kink: the times an integrator
        must step to. Across a kink inside a step DOP853's error estimate misses the error:
        at rtol 1e-10 the mass of a Goddard flight, a plain quadrature of the clipped
        control, came out 2.4e-5 off."""
        if self.segments is None:      # linear between rows within the bounds: never clipped
            return []
        i = int(np.clip(np.searchsorted(self.segments, 0.5 * (a + b), side="right") - 1, 0, len(self.coef) - 1))
        c, hw, coef = self.coef[i]
        D = len(coef)
        if D < 2:                      # a constant: clipped once, no kink
            return []
        za, zb = (a - c) / hw, (b - c) / hw
        # which bounds the polynomial can reach on [za, zb]: its values on a grid, and a
        # bound on its slope there (|z| <= max(|za|, |zb|)), rule out most without roots
        zs = np.linspace(za, zb, 2 * D + 1)
        vals = np.zeros((len(zs), coef.shape[1]))
        for row in coef:
            vals = vals * zs[:, None] + row
        zmax = max(abs(za), abs(zb), 1e-300)
        k = np.arange(D - 1, 0, -1)
        slope = (np.abs(coef[:-1]) * (k * zmax ** (k - 1))[:, None]).sum(axis=0)
        reach = slope * (zs[1] - zs[0]) / 2
        out = []
        for j in range(coef.shape[1]):
            for bound in (self.lo[j], self.hi[j]):
                if not math.isfinite(bound) or np.min(np.abs(vals[:, j] - bound)) > reach[j]:
                    continue
                p = coef[:, j].copy()
                p[-1] -= bound
                for r in np.roots(p):
                    if abs(r.imag) <= 1e-9 * max(1.0, abs(r.real)) and za < r.real < zb:
                        out.append(float(c + hw * r.real))
        return _inside(out, a, b)

    def _straight_line(self, i: int):
        """Segment ``i``'s control as straight-line Python: Horner in the power basis, then
        the clip to each finite bound (the same operations in the same order as a loop over
        the coefficients, without its interpreter overhead: the control was 40 % of the
        verification of a 4-control problem). The code is one template per shape (degree,
        which bounds are finite), compiled once; each segment binds its numbers to it."""
        c, hw, coef = self.coef[i]
        lo_finite = tuple(bool(math.isfinite(v)) for v in self.lo)
        hi_finite = tuple(bool(math.isfinite(v)) for v in self.hi)
        factory = _control_template(len(coef), lo_finite, hi_finite)
        bounds = [v for v, keep in zip(self.lo.tolist(), lo_finite) if keep] + \
                 [v for v, keep in zip(self.hi.tolist(), hi_finite) if keep]
        return factory(float(c), float(hw), *coef.T.ravel().tolist(), *bounds)

    def __call__(self, tt: float) -> np.ndarray:
        """The control at one time (the reference path, kept for the comparison test)."""
        if self.segments is None:
            k = int(np.clip(np.searchsorted(self.t, tt) - 1, 0, len(self.t) - 2))
            w = (tt - self.t[k]) / (self.t[k + 1] - self.t[k])
            w = min(max(w, 0.0), 1.0)
            u = (1 - w) * self.U[k] + w * self.U[k + 1]
        else:
            i = int(np.clip(np.searchsorted(self.segments, tt, side="right") - 1, 0, len(self.coef) - 1))
            c, hw, coef = self.coef[i]
            z = (tt - c) / hw
            u = coef[0].copy()
            for row in coef[1:]:
                u = u * z + row
        return np.minimum(np.maximum(u, self.lo), self.hi)

    def at(self, tt, X=None) -> np.ndarray:
        """The control at the times ``tt`` (P,) -> (P, m), as ``__call__`` at each time
        (the same segment choice and Horner evaluation, vectorised). ``X``, the states there,
        is for a projected control (verify/admissible.py); this one does not depend on them."""
        tt = np.asarray(tt, float)
        if self.segments is None:
            k = np.clip(np.searchsorted(self.t, tt) - 1, 0, len(self.t) - 2)
            w = np.clip((tt - self.t[k]) / (self.t[k + 1] - self.t[k]), 0.0, 1.0)[:, None]
            u = (1 - w) * self.U[k] + w * self.U[k + 1]
        else:
            if not hasattr(self, "_stack"):   # coefficients padded to one degree (leading 0)
                D = max(len(cf) for _, _, cf in self.coef)
                stack = np.zeros((len(self.coef), D, self.U.shape[1]))
                for i, (_, _, cf) in enumerate(self.coef):
                    stack[i, D - len(cf):] = cf
                self._stack = stack
                self._c = np.array([c for c, _, _ in self.coef])
                self._hw = np.array([hw for _, hw, _ in self.coef])
            i = np.clip(np.searchsorted(self.segments, tt, side="right") - 1, 0, len(self.coef) - 1)
            z = ((tt - self._c[i]) / self._hw[i])[:, None]
            cf = self._stack[i]                                   # (P, D, m)
            u = cf[:, 0].copy()
            for r in range(1, cf.shape[1]):
                u = u * z + cf[:, r]
        return np.minimum(np.maximum(u, self.lo), self.hi)




class _Clipped:
    """A control given unclipped by ``_raw(tt) -> (P, m)``, clipped to ``lo``/``hi``, and
    evaluated the same way on every piece."""

    lo: np.ndarray
    hi: np.ndarray
    state_dependent = False

    def _raw(self, tt) -> np.ndarray:
        raise NotImplementedError

    def at(self, tt, X=None) -> np.ndarray:
        return np.minimum(np.maximum(self._raw(tt), self.lo), self.hi)

    def kinks(self, a: float, b: float) -> list[float]:
        """Where the clipped control has a kink inside [a, b] (see SegmentPolynomials.kinks)."""
        return _sampled_crossings(self._raw, a, b, self.lo, self.hi)

    def __call__(self, tt: float) -> np.ndarray:
        return self.at(np.array([tt]))[0]

    def piece(self, tt: float):
        """The control as a function of one time (any piece: these interpolants are
        evaluated the same way everywhere)."""
        return lambda s: self(s).tolist()


class _Tabulated(_Clipped):
    """Cubic, linear or zero-order-hold controls through the rows, clipped to bounds."""

    def __init__(self, t, U, bounds, kind: str):
        self.t, self.U, self.kind = t, U, kind
        self.lo = np.array([b[0] for b in bounds])
        self.hi = np.array([b[1] for b in bounds])
        self._spline = None
        if kind == "cubic" and len(t) >= 4:
            from scipy.interpolate import CubicSpline

            self._spline = CubicSpline(t, U, axis=0)

    def _raw(self, tt) -> np.ndarray:
        tt = np.asarray(tt, float)
        if self.U.shape[1] == 0:
            return np.zeros((len(tt), 0))
        if self._spline is not None:
            return self._spline(np.clip(tt, self.t[0], self.t[-1]))
        if self.kind == "previous":
            k = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, len(self.t) - 1)
            return self.U[k]
        return np.column_stack([np.interp(tt, self.t, self.U[:, j]) for j in range(self.U.shape[1])])


class _SpanCubics(_Clipped):
    """A not-a-knot cubic per span between ``breaks``, through the rows of the span (a row on
    a breakpoint belongs to both spans). One cubic through every row smears a control's kink
    at a flat spline's knot over its neighbours: on a planar quadrotor whose torque is only
    continuous at the knots, 2.9e-3 of "dynamics" error at 201 rows where the trajectory has
    none (unseen49 F3)."""

    def __init__(self, t, U, bounds, breaks):
        from scipy.interpolate import CubicSpline

        self.lo = np.array([b[0] for b in bounds])
        self.hi = np.array([b[1] for b in bounds])
        breaks = np.asarray(breaks, float)
        self.breaks = breaks
        eps = 1e-9 * max(float(breaks[-1] - breaks[0]), 1e-300)
        self._pieces = []
        for a, b in zip(breaks[:-1], breaks[1:]):
            inside = (t >= a - eps) & (t <= b + eps)
            ts, Us = t[inside], U[inside]
            if len(ts) >= 4:
                self._pieces.append(CubicSpline(ts, Us, axis=0))
            elif len(ts) >= 2:       # too few rows for a cubic: the line through them
                self._pieces.append(lambda tt, ts=ts, Us=Us: np.column_stack(
                    [np.interp(tt, ts, Us[:, j]) for j in range(Us.shape[1])]))
            else:
                raise ValueError(f"the span [{a:.6g}, {b:.6g}] holds {len(ts)} row(s): a cubic per span needs "
                                 "at least two")

    def _raw(self, tt) -> np.ndarray:
        tt = np.clip(np.asarray(tt, float), self.breaks[0], self.breaks[-1])
        k = np.clip(np.searchsorted(self.breaks, tt, side="right") - 1, 0, len(self._pieces) - 1)
        out = np.empty((len(tt), self.lo.size))
        for i in np.unique(k):
            out[k == i] = self._pieces[i](tt[k == i])
        return out


class _Series(_Clipped):
    """A parametric control law evaluated exactly (clipped to bounds)."""

    def __init__(self, spec: dict, t0: float, bounds):
        from ..simulate.integrate import ControlLayout

        lay = spec["layout"]
        self.layout = ControlLayout(tuple(lay["kinds"]), tuple(int(o) for o in lay["orders"]))
        self.coefficients = np.asarray(spec["coefficients"], float)
        self.horizon, self.t0 = float(spec["horizon"]), float(t0)
        self.lo = np.array([b[0] for b in bounds])
        self.hi = np.array([b[1] for b in bounds])

    def _raw(self, tt) -> np.ndarray:
        from ..simulate.integrate import evaluate_controls

        return evaluate_controls(self.layout, self.coefficients, np.asarray(tt, float) - self.t0, self.horizon)


def control_rows(traj, control_names) -> tuple[np.ndarray, np.ndarray]:
    """Times and control values (N, m) of the rows that hold solution values: collocated
    rows (``extra["collocated"]``) with every control finite."""
    t = np.asarray(traj.time, float)
    U = np.column_stack([np.asarray(traj.controls[c], float) for c in control_names]) \
        if control_names else np.zeros((len(t), 0))
    keep = np.isfinite(t) & np.isfinite(U).all(axis=1)
    col = traj.extra.get("collocated")
    if col is not None:
        keep &= np.asarray(col, float) > 0
    return t[keep], U[keep]


def declared_interpolation(traj, method: dict | None = None) -> dict:
    """The phase's control interpolation: as recorded with it; else, for a run folder written
    before it was recorded, the one its pseudospectral mesh implies (segments in physical
    time); else linear."""
    if traj.control_interpolation:
        return dict(traj.control_interpolation)
    mesh = ((method or {}).get("meshes") or {}).get(traj.name)
    t = np.asarray(traj.time, float)
    if isinstance(mesh, dict) and mesh.get("breakpoints") and len(t) > 1:
        s = np.asarray(mesh["breakpoints"], float)
        return {"kind": "lagrange-segments", "breakpoints": (t[0] + (t[-1] - t[0]) * s).tolist()}
    return {"kind": "linear"}


def control_interpolant(traj, control_names, bounds, spec: dict | None = None):
    """The control of ``traj`` as a function of time, ``.at(times) -> (P, m)``, by ``spec``
    (default: the trajectory's recorded ``control_interpolation``, see
    :func:`declared_interpolation`); ``bounds`` a (lo, hi) per control."""
    spec = spec or traj.control_interpolation or {"kind": "linear"}
    kind = spec.get("kind", "linear")
    if kind not in KINDS:
        raise ValueError(f"unknown control interpolation {kind!r}; known: {', '.join(KINDS)}")
    t, U = control_rows(traj, control_names)
    if kind == "series":
        return _Series(spec, float(np.asarray(traj.time, float)[0]), bounds)
    if not control_names:
        return _Tabulated(np.asarray(traj.time, float), np.zeros((len(traj.time), 0)), [], "linear")
    if len(t) == 0:
        raise ValueError("no row holds a value of every control")
    if len(t) == 1:   # one collocated value (a one-node phase): a constant control
        t, U = np.array([t[0], t[0] + 1.0]), np.vstack([U, U])
    if kind == "lagrange-segments":
        starts = spec.get("segment_starts")
        if starts is not None:      # in the order of control_names, as the rows
            order = [list(traj.controls).index(c) for c in control_names]
            starts = [None if v is None else [v[i] for i in order] for v in starts]
        return SegmentPolynomials(t, U, bounds, spec["breakpoints"], starts,
                                  later=spec.get("breakpoint_rows") == "later")
    if kind == "cubic" and spec.get("breakpoints"):
        return _SpanCubics(t, U, bounds, spec["breakpoints"])
    return _Tabulated(t, U, bounds, kind)


def breakpoints(traj, spec: dict | None = None) -> np.ndarray:
    """Where the interpolated control may be non-smooth: the segment boundaries of
    ``lagrange-segments`` (and of a ``cubic`` with breakpoints), every row for
    ``linear``/``previous``, the ends for ``cubic``."""
    t = np.asarray(traj.time, float)
    t = t[np.isfinite(t)]
    spec = spec or traj.control_interpolation or {"kind": "linear"}
    kind = spec.get("kind", "linear")
    if kind == "lagrange-segments" or (kind == "cubic" and spec.get("breakpoints")):
        return np.asarray(spec["breakpoints"], float)
    if kind in ("cubic", "series"):
        return np.array([t[0], t[-1]])
    return np.unique(t)


def bounds_of(phase, names, which: str) -> list[tuple[float, float]]:
    """(lo, hi) of each named state or control of ``phase`` (infinite where unbounded)."""
    table = phase.control_bounds if which == "controls" else phase.state_bounds
    by_name = {s.name: b for s, b in table.items()}
    out = []
    for n in names:
        lo, hi = by_name.get(n, (-math.inf, math.inf))
        out.append((float(lo), float(hi)))
    return out
