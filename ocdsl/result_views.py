"""The notebook face of a Result: a short repr, ``summary()``, ``sample(t)``, ``to_pandas()``
and ``plot()``. Everything here reads only what the run folder holds, so a result read back
with ``ocdsl.read(run_dir)`` answers exactly as the one the solve returned.

>>> import ocdsl
>>> res = ocdsl.load("configs/brachistochrone.yaml").solve()
>>> res                                                   # doctest: +ELLIPSIS
<Result 'Brachistochrone with named expressions': optimal, objective 1.80160..., tf 1.80160..., 1 phase, 41 rows, expect 1/1 passed, verification verified>
>>> again = ocdsl.read(res.write(tmp / "run"))           # the run folder, read back
>>> at = again.sample([0.0, again.tf])                   # states and controls at any times
>>> [round(float(v), 6) + 0.0 for v in at["x"]]   # + 0.0: a solved -1e-12 prints as 0.0
[0.0, 10.0]
>>> df = again.to_pandas()
>>> list(df.columns[:5]), df.attrs["units"]["v"]
(['t', 'x', 'y', 'v', 'theta'], 'm/s')
>>> fig = again.plot()                                    # a matplotlib Figure
>>> len(fig.axes)
6
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np


class ResultViews:
    """Mixed into :class:`ocdsl.result.Result`."""

    # ---- text ------------------------------------------------------------------------
    def __repr__(self) -> str:
        parts = [self.status]
        if self.objective is not None:
            parts.append(f"objective {self.objective:.8g}")
        if isinstance(self.tf, dict):
            parts.append("tf " + ", ".join(f"{k} {v:.6g}" for k, v in self.tf.items()))
        elif self.tf is not None:
            parts.append(f"tf {self.tf:.8g}")
        if self.phases:
            rows = sum(len(p.time) for p in self.phases)
            parts.append(f"{len(self.phases)} phase{'s' * (len(self.phases) > 1)}, {rows} rows")
        if self.expect:
            passed = sum(bool(c.get("passed")) for c in self.expect)
            parts.append(f"expect {passed}/{len(self.expect)} passed")
        verification = getattr(self, "verification", None)
        if isinstance(verification, dict) and verification.get("status"):
            parts.append(f"verification {verification['status']}")
        return f"<Result {self.name!r}: {', '.join(parts)}>"

    def summary(self) -> str:
        """A few lines: status, objective, final times, NLP, time, each expect check.

        >>> from ocdsl.result import Result
        >>> print(Result("demo", "optimal", objective=2.0, tf=2.0, iterations=12,
        ...              expect=[{"name": "tf", "value": 2.00001, "reference": 2.0, "rtol": 1e-4,
        ...                       "atol": None, "error": 1e-5, "relative_error": 5e-6,
        ...                       "passed": True}]).summary())
        demo: optimal
          objective    2
          final time   2
          iterations   12
          expect tf: 2.00001 vs 2 (relative error 5.00e-06, rtol 1.0e-04) pass
        """
        lines = [f"{self.name}: {self.status}"]
        verification = getattr(self, "verification", None)
        if isinstance(verification, dict) and verification.get("status"):
            lines[0] += f", verification {verification['status']}"
            if verification.get("summary"):
                lines.append(f"  {verification['summary']}")
        if self.status not in ("optimal", "stable", "feasible") and self.message:
            lines.append(f"  {self.message.splitlines()[0]}")
        rows = []
        note = numbers_note(self)
        if self.objective is not None:
            rows.append(("objective", f"{self.objective:.10g}{note}"))
        t0 = getattr(self, "t0", None)
        if isinstance(t0, dict):
            rows.append(("initial times", ", ".join(f"{k} {v:.8g}" for k, v in t0.items())))
        elif t0 is not None:
            rows.append(("initial time", f"{t0:.10g}"))
        if isinstance(self.tf, dict):
            rows.append(("final times", ", ".join(f"{k} {v:.8g}" for k, v in self.tf.items()) + note))
        elif self.tf is not None:
            rows.append(("final time", f"{self.tf:.10g}{note}"))
        if self.nlp:
            rows.append(("NLP", f"{self.nlp.get('variables')} variables, {self.nlp.get('constraints')} constraints"))
        if self.iterations is not None:
            rows.append(("iterations", str(self.iterations)))
        if self.wall_time_s.get("total") is not None:
            rows.append(("wall time", f"{self.wall_time_s['total']:.3f} s"))
        lines += [f"  {k:<12} {v}" for k, v in rows]
        for c in self.expect:
            lines.append(f"  expect {expect_comparison(c, note)} {'pass' if c.get('passed') else 'FAIL'}")
        return "\n".join(lines)

    # ---- values between the rows ---------------------------------------------------------
    def sample(self, t, phase: str | None = None) -> dict[str, np.ndarray]:
        """States and controls at the times ``t`` (a number or an array) of ``phase`` (default:
        the first), inside its span (a time outside it is a ValueError naming the phase that
        holds it: it extrapolated, 183 m on a 10 m track, unseen52 F1). Controls follow the
        run's documented interpolation, clipped to their bounds,
        exactly as the verification reads them (:mod:`ocdsl.verify.interpolate`); states are
        each segment's polynomial through its rows (``lagrange-segments``: a pseudospectral
        state is that polynomial), else a cubic spline through the rows.

        >>> import numpy as np
        >>> from ocdsl.result import Result, PhaseTrajectory
        >>> ph = PhaseTrajectory("main", np.array([0.0, 1.0, 2.0]), states={"x": np.array([0.0, 1.0, 4.0])},
        ...                      controls={"u": np.array([0.0, 2.0, 4.0])})
        >>> Result("demo", "optimal", phases=[ph]).sample([0.5, 1.5])["u"]
        array([1., 3.])
        """
        from .verify.interpolate import control_interpolant, declared_interpolation

        traj = self.phase(phase)
        tt = np.atleast_1d(np.asarray(t, float))
        _within_span(self, traj, tt)
        bounds = ((self.problem.get("phases") or {}).get(traj.name, {}).get("bounds")) or {}
        spec = declared_interpolation(traj, self.method)
        out: dict[str, np.ndarray] = {"t": tt}
        out.update(_states_at(traj, tt, spec))
        names = list(traj.controls)
        if names:
            lim = [tuple(math.inf * (-1 if i == 0 else 1) if b is None else float(b)
                         for i, b in enumerate(bounds.get(n) or (None, None))) for n in names]
            values = control_interpolant(traj, names, lim, spec).at(tt)
            out.update({n: values[:, j] for j, n in enumerate(names)})
        return out

    # ---- pandas and plots -------------------------------------------------------------
    def to_pandas(self, phase: str | None = None):
        """The trajectory as a pandas DataFrame (every column of the run folder's CSV); with
        several phases and no ``phase`` named, all of them with a ``phase`` column.
        ``df.attrs["units"]`` maps column -> unit where the problem declares one.
        Needs pandas (``pip install 'ocdsl[notebook]'``)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Result.to_pandas() needs pandas: pip install 'ocdsl[notebook]' "
                              "(or pip install pandas)") from None
        chosen = [self.phase(phase)] if phase is not None or len(self.phases) == 1 else self.phases
        frames = []
        for traj in chosen:
            df = pd.DataFrame({k: np.asarray(v, float) for k, v in traj.columns().items()})
            if len(chosen) > 1:
                df.insert(0, "phase", traj.name)
            frames.append(df)
        df = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
        units = self.problem.get("units") or {}
        df.attrs["units"] = {c: units[c] for c in df.columns if c in units}
        if "t" in df.columns and units.get("t"):
            df.attrs["units"]["t"] = units["t"]
        df.attrs["name"] = self.name
        return df

    def plot(self, phase: str | None = None, samples: int = 400):
        """A matplotlib Figure: each state and control against time (every phase unless one is
        named); rows as dots, the interpolated solution as lines. Returns the Figure."""
        import matplotlib.pyplot as plt

        chosen = [self.phase(phase)] if phase is not None else self.phases
        names = list(dict.fromkeys(n for p in chosen for n in list(p.states) + list(p.controls)))
        if not names:
            raise ValueError("this result has no trajectory to plot")
        cols = min(3, len(names))
        rows = math.ceil(len(names) / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 2.6 * rows), squeeze=False)
        units = self.problem.get("units") or {}
        for traj in chosen:
            t0, tf = float(traj.time[0]), float(traj.time[-1])
            dense = self.sample(np.linspace(t0, tf, samples), traj.name)
            for i, name in enumerate(names):
                if name not in dense:
                    continue
                ax = axes[i // cols][i % cols]
                line, = ax.plot(dense["t"], dense[name], lw=1.2, label=traj.name if len(chosen) > 1 else None)
                values = traj.states.get(name, traj.controls.get(name))
                ax.plot(traj.time, values, ".", ms=3, color=line.get_color())
                ax.set_title(f"{name} [{units[name]}]" if name in units else name, fontsize=9)
                ax.set_xlabel("t")
        for j in range(len(names), rows * cols):
            axes[j // cols][j % cols].axis("off")
        if len(chosen) > 1:
            axes[0][0].legend(fontsize=7)
        fig.suptitle(self.name, fontsize=10)
        fig.tight_layout()
        return fig


def completed_solution(result) -> str | None:
    """What a run cut short by its time limit or an interrupt reports when one of its solves
    completed: a refinement's best completed mesh, or the best of the starts solved before the
    limit cut the others and the checks (``extra.cut_short``, unseen42 F3); None otherwise."""
    if result.status not in ("time_limit", "interrupted"):
        return None
    mesh = result.extra.get("mesh") or {}
    if mesh.get("chosen_status") in ("optimal", "acceptable"):
        return (f"best completed mesh (mesh iteration {mesh.get('chosen_iteration')}, Ipopt "
                f"{mesh['chosen_status']}; refinement cut short, so not a converged result)")
    cut = result.extra.get("cut_short") or {}
    if cut.get("solution_status") in ("optimal", "acceptable"):
        return (f"best solution before the time limit (Ipopt {cut['solution_status']}; {cut.get('solves_cut')} "
                "later solves, starts or checks, cut, so not a checked result)")
    return None


def shows_a_solution(result) -> bool:
    """Whether the run's numbers and rows are a solution's: its own, or the completed solve a
    cut-short run kept (``completed_solution``), not a last iterate or a guess."""
    return result.has_solution or completed_solution(result) is not None


def numbers_note(result) -> str:
    """What a run's objective and times are when they are not a solution's: the last iterate
    of a failed solve, or the guess of one that never started (unseen12 F9: "final time
    5.05" and "expect tf: 5.05 vs 2" for the guess of a solve Ipopt refused to start)."""
    if result.has_solution:
        return ""
    if completed_solution(result):
        return " (best completed solve; the run was cut short)"
    return " (last iterate, not a solution)" if result.iterations else " (the guess: the solve did not start)"


def value_and_reference(value: float, reference: float) -> tuple[str, str]:
    """Both at 10 digits, or at full precision where those read alike ("2 >= 2 (at_least)
    FAIL" for 1.9999999999999996 against 2 with rtol 0, unseen54 F3)."""
    shown, ref = f"{value:.10g}", f"{reference:.10g}"
    if shown == ref and value != reference:
        shown, ref = repr(float(value)), repr(float(reference))
    return shown, ref


def expect_comparison(check: dict[str, Any], note: str = "") -> str:
    """``NAME: VALUE vs REFERENCE (error)``, without the verdict; a run that ended before it had
    the value (interrupted before the first iterate) says so instead of printing nan; ``note``
    (``numbers_note``) says what a value is that is not a solution's."""
    value = check.get("value")
    if value is None or not math.isfinite(value):
        return f"{check['name']}: no value vs {check['reference']:.10g} (the run ended before it had one)"
    bound = {"at_most": "<=", "at_least": ">="}.get(check.get("compare"))
    if bound:
        # a bound, not a target: "12 vs 12.5 (relative error 4e-02, rtol 1e-06) pass" read as a
        # miss that passed (unseen22 m09)
        slack = max((check.get("rtol") or 0.0) * abs(check["reference"]), check.get("atol") or 0.0)
        within = f" + {slack:.2g}" if bound == "<=" and slack else f" - {slack:.2g}" if slack else ""
        shown, ref = value_and_reference(value, check["reference"])
        return f"{check['name']}: {shown} {bound} {ref}{within} ({check['compare']}){note}"
    shown, ref = value_and_reference(value, check["reference"])
    return f"{check['name']}: {shown} vs {ref} ({expect_error_text(check)}){note}"


def expect_error_text(check: dict[str, Any]) -> str:
    """An expect check's error in its own terms: relative when it has an rtol, else absolute."""
    # against a reference of zero a relative error means nothing ("relative error inf ... pass"
    # for an exact 0, unseen19 e1): the absolute one is shown
    if check.get("rtol") is not None and check.get("relative_error") is not None and check.get("reference"):
        if check.get("atol") is not None:
            # either allowance passes it: both shown (unseen54 F4: "relative error 1.26e-03,
            # rtol 1.0e-04 pass", the atol 1e-3 that passed it unsaid)
            return (f"error {check['error']:.2e}, relative {check['relative_error']:.2e}; atol {check['atol']:.1e} "
                    f"or rtol {check['rtol']:.1e}")
        return f"relative error {check['relative_error']:.2e}, rtol {check['rtol']:.1e}"
    limit = f", atol {check['atol']:.1e}" if check.get("atol") is not None else ""
    return f"error {check['error']:.2e}{limit}"


def _within_span(result, traj, tt: np.ndarray) -> None:
    """A ValueError for times outside ``traj``'s span (to 1e-9 of it), naming the phase whose
    span holds them where one does."""
    time = np.asarray(traj.time, float)
    time = time[np.isfinite(time)]
    if not len(time):
        return
    lo, hi = float(time[0]), float(time[-1])
    slack = 1e-9 * max(1.0, abs(hi - lo), abs(lo), abs(hi))
    out = tt[(tt < lo - slack) | (tt > hi + slack)]
    if not len(out):
        return
    first = float(out[0])
    holder = next((p.name for p in result.phases if p is not traj and len(p.time)
                   and float(np.nanmin(p.time)) - slack <= first <= float(np.nanmax(p.time)) + slack), None)
    raise ValueError(f"t = {first:g} is outside phase {traj.name!r}'s span [{lo:g}, {hi:g}]: sample() does not "
                     "extrapolate" + (f"; phase {holder!r} holds it: sample(t, phase={holder!r})" if holder else ""))


def _states_at(traj, tt: np.ndarray, spec: dict) -> dict[str, np.ndarray]:
    """States between the rows (Result.sample): per segment the polynomial through that
    segment's rows, both ends included; else a cubic spline through all rows."""
    from .verify.interpolate import SegmentPolynomials, _Tabulated

    names = list(traj.states)
    if not names:
        return {}
    rows = np.asarray(traj.time, float)
    X = np.column_stack([np.asarray(traj.states[n], float) for n in names])
    free = [(-math.inf, math.inf)] * len(names)
    keep = np.isfinite(rows) & np.isfinite(X).all(axis=1)
    rows, X = rows[keep], X[keep]
    if spec.get("kind") != "lagrange-segments":
        rows, first = np.unique(rows, return_index=True)
        values = _Tabulated(rows, X[first], free, "cubic").at(tt)
    else:
        breaks = np.asarray(spec["breakpoints"], float)
        tol = 1e-12 * max(1.0, abs(breaks[-1] - breaks[0]))
        seg = np.clip(np.searchsorted(breaks, tt, side="left") - 1, 0, len(breaks) - 2)
        values = np.full((len(tt), len(names)), np.nan)
        for k in np.unique(seg):
            a, b = breaks[k], breaks[k + 1]
            inside = (rows >= a - tol) & (rows <= b + tol)
            r, first = np.unique(rows[inside], return_index=True)
            sel = seg == k
            if len(r):
                values[sel] = SegmentPolynomials(r, X[inside][first], free, [r[0], r[-1]]).at(tt[sel])
    return {n: values[:, j] for j, n in enumerate(names)}
