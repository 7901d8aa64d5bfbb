"""The minimum principle's control corrected to meet the final conditions, then flown.

Built from approximate costates, H's minimiser misses a condition on the final state or on an
integral (Goddard: by 0.24), and a trajectory that misses one bounds nothing. It is moved back
onto the conditions: the solution's own control plus a share ``alpha`` of the step to H's
minimiser, plus a correction in low-order Legendre polynomials of time on each control (zero
where the control holds a bound, so the box is kept), whose coefficients a Newton iteration
(finite differences, one flight per coefficient) picks to zero the conditions' residuals. To
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
NEWTON_STEPS = 6


@dataclass
class Corrected:
    flight: object          # verify.fly.Flight of the last corrected control
    share: float            # alpha
    flights: int
    met: bool               # the final conditions met to the target


def late_equalities(problem) -> list[int]:
    """Indices (in ``problem.boundary``) of the equality conditions on a final state or an
    integral: those a flown control changes. Conditions on t_f or parameters alone keep the
    solution's values (the flight keeps both)."""
    late = {s for s, bv in problem.boundary_values.items() if bv.which == "tf"} | set(problem.integrals)
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


def corrected_flight(fly, t: np.ndarray, U_own: np.ndarray, U_min: np.ndarray, bounds, conditions: list[int],
                     target: float, better) -> Corrected | None:
    """``fly(U)`` flies a control table at times ``t`` (those of ``U_own``, ``U_min``) and returns a
    Flight; ``conditions``: the residuals to zero, each to ``target``; ``better(flight)``: the
    flight refutes the claim. Returns the first corrected flight that refutes it, else the last
    one that met the conditions, else None."""
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    flights, met = 0, None

    def residuals(flight) -> np.ndarray:
        return np.array([flight.residuals.get(i, math.inf) for i in conditions], float)

    for share in SHARES:
        base = np.clip(U_own + share * (U_min - U_own), lo, hi)
        V = _directions(np.asarray(t, float), base, bounds, len(conditions))
        if not len(V) or flights + len(V) + 2 > MAX_FLIGHTS:
            break
        coef = np.zeros(len(V))

        def control(c):
            return np.clip(base + np.tensordot(c, V, axes=1), lo, hi)

        flight = fly(control(coef))
        flights += 1
        r = residuals(flight)
        if not np.all(np.isfinite(r)):
            continue
        step = 1e-6 * max(1.0, float(np.max(np.abs(base))))
        jac = np.empty((len(r), len(V)))
        for k in range(len(V)):
            dc = np.zeros(len(V))
            dc[k] = step
            jac[:, k] = (residuals(fly(control(dc))) - r) / step
            flights += 1
        if not np.all(np.isfinite(jac)):
            continue
        for _ in range(NEWTON_STEPS):
            if np.max(np.abs(r)) <= target or flights >= MAX_FLIGHTS:
                break
            coef = coef - np.linalg.lstsq(jac, r, rcond=None)[0]
            flight = fly(control(coef))
            flights += 1
            r = residuals(flight)
            if not np.all(np.isfinite(r)):
                break
        if np.all(np.isfinite(r)) and np.max(np.abs(r)) <= target:
            met = Corrected(flight, share, flights, True)
            if better(flight):
                return met
    return met
