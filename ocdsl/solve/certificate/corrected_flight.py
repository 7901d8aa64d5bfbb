"""The minimum principle's control corrected to meet the final conditions, then flown.

Built from approximate costates, H's minimiser misses a condition on the final state or on an
integral (Goddard: by 0.24), and a trajectory that misses one bounds nothing. It is moved back
onto the conditions: the solution's own control plus a share ``alpha`` of the step to H's
minimiser, plus a correction in low-order Legendre polynomials of time on each control (zero
where the control holds a bound, so the box is kept) and, for the whole step, its bang
switches moved in time; a Newton iteration (finite differences, one flight per unknown) picks
the coefficients and the switch times that zero the conditions' residuals. To
first order the corrected flight gains alpha x the Hamiltonian gain the certificate predicts
(the final conditions' multipliers are in the costates), so a smaller share is tried when the
whole step's second-order cost eats the gain. Whatever control this builds, a feasible flight
is a trajectory of the problem: better than the claim by more than the tolerance, it refutes it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# shares of the step from the solution's control to H's minimiser, tried in turn
SHARES = (1.0, 0.5, 0.25)
# flights one check may spend (each is one DOP853 integration of the phase)
MAX_FLIGHTS = 40
# more final conditions than this are not corrected onto (the check passes with a note): seed
# 0's twelve took 20 flights and 1.3 s of a 5.2 s run without meeting them
MAX_CONDITIONS = 8
NEWTON_STEPS = 12


@dataclass
class Corrected:
    """A corrected flight that met the final conditions to the target."""
    flight: object          # verify.fly.Flight of the last corrected control
    share: float            # alpha
    flights: int
    switches: np.ndarray    # the times of the flown control's bang switches (moved by the correction)
    stretch: float = 1.0    # the flown phase's length over the solution's (a free final time)


def late_symbols(problem) -> set:
    """The final states' and the integrals' symbols: what a flown control changes."""
    return {s for s, bv in problem.boundary_values.items() if bv.which == "tf"} | set(problem.integrals)


def late_equalities(problem) -> list[int]:
    """Indices (in ``problem.boundary``) of the equality conditions on a final state or an
    integral: those a flown control changes. Conditions on t_f or parameters alone keep the
    solution's values (the flight keeps both)."""
    late = late_symbols(problem)
    return [i for i, c in enumerate(problem.boundary) if c.is_equality and c.expr.free_symbols & late]


def _directions(t: np.ndarray, U: np.ndarray, bounds, count: int) -> np.ndarray:
    """(n, len(t), controls): Legendre polynomials 0..count-1 of the phase's normalised time on
    each control, zero where that control is on (or within a hair of) a bound."""
    tau = 2.0 * (t - t[0]) / (t[-1] - t[0]) - 1.0
    P = np.polynomial.legendre.legvander(tau, count - 1)
    out = []
    for j, (lo, hi) in enumerate(bounds):
        span = hi - lo if math.isfinite(hi - lo) else max(1.0, float(np.max(np.abs(U[:, j]))))
        inside = (U[:, j] > lo + 1e-6 * span) & (U[:, j] < hi - 1e-6 * span)
        if inside.sum() < 2:
            continue
        for k in range(count):
            V = np.zeros_like(U)
            V[:, j] = P[:, k] * inside
            out.append(V)
    return np.array(out)


def bang_jumps(U: np.ndarray, j: int, lo: float, hi: float) -> np.ndarray:
    """Between which rows of ``U`` control ``j`` goes from one bound to the other (a bang switch)."""
    return np.abs(np.diff(U[:, j])) > 0.5 * (hi - lo)


def _switches(t: np.ndarray, U: np.ndarray, bounds) -> list[tuple[int, int]]:
    """(table index of the entry before, control) of each bang switch: ``_tabulate`` writes a
    switch as two entries a hair apart, the first on the old bound, the second on the new."""
    close = np.diff(t) <= 1e-8 * (t[-1] - t[0])
    out = []
    for j, (lo, hi) in enumerate(bounds):
        if math.isfinite(lo) and math.isfinite(hi):
            out += [(int(i), j) for i in np.flatnonzero(close & bang_jumps(U, j, lo, hi))]
    return sorted(out)


def _moved(t: np.ndarray, U: np.ndarray, jumps: list[tuple[int, int]], shifts: np.ndarray):
    """The table with switch k moved by ``shifts[k]`` x the phase's length: the arc before it
    extended (or the one after it, moving back) to the new time. Returns (t, U, cuts)."""
    span = t[-1] - t[0]
    eps = 1e-9 * span
    keep = np.ones(len(t), bool)
    for i, _ in jumps:
        keep[i] = keep[i + 1] = False
    T, V = t[keep], U[keep].copy()
    extra_t, extra_U, cuts = [], [], []
    for (i, j), d in zip(jumps, shifts):
        s, before, after = t[i], U[i, j], U[i + 1, j]
        new = min(max(s + d * span, t[0] + 2 * eps), t[-1] - 3 * eps)
        lo, hi = min(s, new), max(s, new)
        between = (T >= lo) & (T <= hi + eps)
        V[between & (T <= new), j] = before
        V[between & (T > new), j] = after
        row = np.array([np.interp(new, T, V[:, c]) for c in range(V.shape[1])])
        left, right = row.copy(), row.copy()
        left[j], right[j] = before, after
        extra_t += [new, new + eps]
        extra_U += [left, right]
        cuts.append(new)
    times = np.concatenate([T, extra_t])
    order = np.argsort(times, kind="stable")
    return times[order], np.vstack([V] + extra_U)[order], np.array(sorted(cuts))


def _misses_elsewhere(flight, r: np.ndarray, target: float) -> bool:
    """The flight's worst miss is no condition the correction moves (a state bound: Goddard's
    v by 4.7e-2 at every step): correcting on only flies the same miss again."""
    return flight.violation > 10.0 * target and float(np.max(np.abs(r), initial=0.0)) < 0.1 * flight.violation


def corrected_flight(fly, t: np.ndarray, U_own: np.ndarray, U_min: np.ndarray, cuts: np.ndarray, bounds,
                     conditions: list[int], target: float, better, gain,
                     free_final_time: bool = False) -> Corrected | None:
    """``fly(t, U, cuts)`` flies a control table (jumping at ``cuts``) and returns a Flight;
    ``U_own``, ``U_min``: the solution's control and H's minimiser at the times ``t`` of
    ``U_min``'s table, whose bang switches are at ``cuts``; ``conditions``: the residuals to zero,
    each to ``target``; ``better(flight)``: the flight refutes the claim; ``gain(flight)``: by how
    much it beats the claim (of the objective's sense). The unknowns are the
    polynomials' coefficients on the interior arcs and, for the whole step to H's minimiser,
    the times of its bang switches, and with a ``free_final_time`` the phase's length (``fly``'s
    ``stretch``: a minimum-time claim is refuted by a shorter flight that meets the conditions).
    Returns the first corrected flight that refutes the claim,
    else the last one that met the conditions, else None."""
    if len(conditions) > MAX_CONDITIONS:
        return None
    t = np.asarray(t, float)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    flights, met = 0, None
    switches = _switches(t, U_min, bounds)

    def residuals(flight) -> np.ndarray:
        return np.array([flight.residuals.get(i, math.inf) for i in conditions], float)

    for share in SHARES:
        base = np.clip(U_own + share * (U_min - U_own), lo, hi)
        V = _directions(t, base, bounds, len(conditions))
        jumps = switches if share == 1.0 else []     # a share of a jump is no bang switch to move
        n = len(V) + len(jumps) + int(free_final_time)
        if not n or flights + n + 2 > MAX_FLIGHTS:
            continue

        def control(c, base=base, V=V, jumps=jumps):
            U = np.clip(base + np.tensordot(c[:len(V)], V, axes=1), lo, hi) if len(V) else base
            table = _moved(t, U, jumps, c[len(V):len(V) + len(jumps)]) if jumps else (t, U, cuts)
            # a Newton step far out (a stretch of -75 once) is cut back to a factor of 2
            return (*table, float(np.clip(1.0 + c[-1], 0.5, 2.0)) if free_final_time else 1.0)

        coef = np.zeros(n)
        table = control(coef)
        flight = fly(*table)
        flights += 1
        r = residuals(flight)
        if not np.all(np.isfinite(r)) or _misses_elsewhere(flight, r, target):
            continue
        steps = np.concatenate([np.full(len(V), 1e-6 * max(1.0, float(np.max(np.abs(base))))),
                                np.full(len(jumps) + int(free_final_time), 1e-6)])
        jac = np.empty((len(r), n))
        for k in range(n):
            dc = np.zeros(n)
            dc[k] = steps[k]
            jac[:, k] = (residuals(fly(*control(dc))) - r) / steps[k]
            flights += 1
        if not np.all(np.isfinite(jac)):
            continue
        for _ in range(NEWTON_STEPS):
            if np.max(np.abs(r)) <= target or flights >= MAX_FLIGHTS:
                break
            if _misses_elsewhere(flight, r, target):
                break
            step = -np.linalg.lstsq(jac, r, rcond=None)[0]
            if not (np.all(np.isfinite(step)) and float(step @ step) > 0.0):
                break
            coef = coef + step
            table = control(coef)
            flight = fly(*table)
            flights += 1
            r_new = residuals(flight)
            if not np.all(np.isfinite(r_new)):
                r = r_new
                break
            # Broyden's update: the finite-difference Jacobian was taken at the start, and a
            # switch moved far changes it (the chord alone converged 4x per step)
            jac += np.outer(r_new - r - jac @ step, step) / float(step @ step)
            stalled = np.max(np.abs(r_new)) > 0.5 * np.max(np.abs(r))
            r = r_new
            if stalled and np.max(np.abs(r)) > target:
                break       # the flights' own noise, or a miss the unknowns cannot remove
            if not np.all(np.isfinite(jac)):
                break
        if np.all(np.isfinite(r)) and np.max(np.abs(r)) <= target:
            met = Corrected(flight, share, flights, t[0] + table[3] * (table[2] - t[0]), table[3])
            if better(flight):
                return met
            if not gain(flight) > 0:
                # no better than the claim at all: the costates, not the step's second-order
                # cost, are what is off, and a smaller share of the step would not help
                return met
    return met
