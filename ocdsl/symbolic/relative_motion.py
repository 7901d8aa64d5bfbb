"""Linearised relative motion on a circular orbit: HCW, secular/periodic variables, closed forms.

Notation and every formula follow the seed-4 digest (``../shared/seeds/seed_004.md``), whose
§2 reconstructs the lost equations of Ishkov, Filippov, Zhou & Wang (JNWPU 41(3), 2023):

* dimensional in-plane HCW state ``x = (dr, dL, dVr, dVu)`` (radial offset, along-track arc
  ``r1*du``, radial and transversal velocity differences), thrust accelerations ``aS, aT``,
  orbital rate ``omega`` (§2.3);
* secular/periodic variables ``(r_av, L_av, l_x, l_y)`` = (mean radial offset, mean
  along-track offset, Cartesian semi-minor axis of the 2:1 ellipse) (§2.5);
* dimensionless variables: time ``tau = omega*t``, lengths divided by ``K = 2a/omega**2``,
  transversal switch ``delta = aT/a`` (§2.6), for which
  ``r_av' = delta, L_av' = -3/2 r_av, l_x' = -l_y - delta, l_y' = l_x``.

Every function here is pure NumPy (or generic arithmetic that works on SymPy symbols too);
nothing imports Pyomo or SciPy.  State vectors of the dimensionless model are ordered
``(r_av, L_av, l_x, l_y)``.
"""
from __future__ import annotations

import math
from typing import Iterable, Sequence

import numpy as np
import sympy as sp

__all__ = [
    "hcw_matrices", "fundamental_matrix", "fundamental_matrix_lateral", "forced_response_aT",
    "scale_length", "to_secular", "from_secular", "to_dimensionless", "from_dimensionless",
    "tau_of_t", "t_of_tau", "dimensionless_rhs", "segment", "multi_burn", "two_burn_segments",
    "semi_axis_after_burn", "burn_durations", "two_burn_final_state", "periodic_residual",
    "boundary_tp", "boundary_t_sum", "right_end", "same_sign_bound", "criteria",
]


# ---------------------------------------------------------------------------------------
# Dimensional HCW (§2.3, §2.4)
# ---------------------------------------------------------------------------------------
def hcw_matrices(omega):
    """A, B of the in-plane model (4) ``x' = A x + B (aS, aT)``; SymPy if omega is symbolic."""
    mod = sp if isinstance(omega, sp.Basic) else None
    A = [[0, 0, 1, 0],
         [-omega, 0, 0, 1],
         [omega**2, 0, 0, 2 * omega],
         [0, 0, -omega, 0]]
    B = [[0, 0], [0, 0], [1, 0], [0, 1]]
    if mod is sp:
        return sp.Matrix(A), sp.Matrix(B)
    return np.array(A, float), np.array(B, float)


def fundamental_matrix(t, omega):
    """Φ(t) of the in-plane HCW block (digest eq. (6), §2.4); columns = initial state.

    Works on floats (NumPy array) or SymPy expressions (SymPy Matrix).
    """
    if isinstance(t, sp.Basic) or isinstance(omega, sp.Basic):
        s, c, M = sp.sin(omega * t), sp.cos(omega * t), sp.Matrix
    else:
        s, c, M = math.sin(omega * t), math.cos(omega * t), (lambda rows: np.array(rows, float))
    w = omega
    return M([[2 - c, 0, s / w, 2 * (1 - c) / w],
              [2 * s - 3 * w * t, 1, 2 * (c - 1) / w, 4 * s / w - 3 * t],
              [w * s, 0, c, 2 * s],
              [-w * (1 - c), 0, -s, 2 * c - 1]])


def fundamental_matrix_lateral(t, omega):
    """Φ_z(t) of the lateral block (dz, dVz)."""
    s, c = math.sin(omega * t), math.cos(omega * t)
    return np.array([[c, s / omega], [-omega * s, c]])


def forced_response_aT(t, omega, aT):
    """Response from rest to a constant transversal acceleration over [0, t] (eq. (7))."""
    s, c = math.sin(omega * t), math.cos(omega * t)
    return np.array([2 * aT * (t - s / omega) / omega,
                     aT * (4 * (1 - c) / omega**2 - 1.5 * t**2),
                     2 * aT * (1 - c) / omega,
                     aT * (2 * s / omega - t)])


# ---------------------------------------------------------------------------------------
# Secular/periodic map and the dimensionless scaling (§2.5, §2.6)
# ---------------------------------------------------------------------------------------
def scale_length(a, omega):
    """K = 2 a / omega**2, the length unit of the dimensionless model."""
    return 2 * a / omega**2


def tau_of_t(t, omega):
    return omega * t


def t_of_tau(tau, omega):
    return tau / omega


def to_secular(x: Sequence, omega) -> tuple:
    """(dr, dL, dVr, dVu) -> dimensional (r_av, L_av, l_x, l_y) (eq. (8), (10))."""
    dr, dL, dVr, dVu = x
    return (2 * dr + 2 * dVu / omega,
            dL - 2 * dVr / omega,
            -(dr + 2 * dVu / omega),
            -dVr / omega)


def from_secular(y: Sequence, omega) -> tuple:
    """Inverse of :func:`to_secular`."""
    r_av, L_av, lx, ly = y
    return (r_av + lx,
            L_av - 2 * ly,
            -omega * ly,
            -omega * (r_av / 2 + lx))


def to_dimensionless(x: Sequence, omega, a) -> tuple:
    """Dimensional HCW state -> dimensionless (r_av, L_av, l_x, l_y): secular map, then /K."""
    K = scale_length(a, omega)
    return tuple(v / K for v in to_secular(x, omega))


def from_dimensionless(y: Sequence, omega, a) -> tuple:
    """Dimensionless (r_av, L_av, l_x, l_y) -> dimensional HCW state (dr, dL, dVr, dVu)."""
    K = scale_length(a, omega)
    return from_secular(tuple(K * v for v in y), omega)


def dimensionless_rhs(y: Sequence, delta, delta_s=0):
    """Right-hand side of the dimensionless model (15), with an optional radial switch.

    ``delta`` = aT/a, ``delta_s`` = aS/a (the paper's problem has ``delta_s = 0``).
    """
    r_av, _L_av, lx, ly = y
    return (delta, -1.5 * r_av - delta_s, -ly - delta, lx - delta_s / 2)


# ---------------------------------------------------------------------------------------
# Closed forms of the dimensionless model (§2.6)
# ---------------------------------------------------------------------------------------
def segment(y0: Sequence[float], delta: float, tau: float) -> np.ndarray:
    """State after a segment of length ``tau`` with constant ``delta`` (eq. (16))."""
    r0, L0, lx0, ly0 = (float(v) for v in y0)
    s, c = math.sin(tau), math.cos(tau)
    return np.array([r0 + delta * tau,
                     L0 - 1.5 * r0 * tau - 0.75 * delta * tau**2,
                     lx0 * c - ly0 * s - delta * s,
                     lx0 * s + ly0 * c - delta * (1 - c)])


def multi_burn(y0: Sequence[float], burns: Iterable[tuple[float, float, float]], T: float) -> np.ndarray:
    """State at ``T`` after burns ``(delta_k, start_k, end_k)`` from ``y0`` at 0 (eq. (17)).

    Uses the sums C, D, A, B of §2.6 with ``u = T - tau`` the time left to the end.
    """
    r0, L0, lx0, ly0 = (float(v) for v in y0)
    A = B = C = D = 0.0
    for delta, ts, te in burns:
        us, ue = T - ts, T - te
        C += delta * (te - ts)
        D += delta * (us**2 - ue**2)
        A += delta * (math.cos(ue) - math.cos(us))
        B += delta * (math.sin(us) - math.sin(ue))
    s, c = math.sin(T), math.cos(T)
    return np.array([r0 + C,
                     L0 - 1.5 * r0 * T - 0.75 * D,
                     lx0 * c - ly0 * s - B,
                     lx0 * s + ly0 * c - A])


def two_burn_segments(t0, t1, tp, t2, d1, d2) -> tuple[list[tuple[float, float, float]], float]:
    """Burns ``(delta, start, end)`` and final time of the programme wait/burn/coast/burn."""
    T = t0 + t1 + tp + t2
    return [(d1, t0, t0 + t1), (d2, t0 + t1 + tp, T)], T


def semi_axis_after_burn(l0: float, phi0: float, delta: float, tau: float) -> float:
    """l after a segment of length ``tau`` with switch ``delta`` from (l0, phi0), l_x = l cos φ.

    Eq. (18) of the digest, written with delta**2 for the middle term so that a coast
    (delta = 0) keeps l (the digest's form assumes |delta| = 1).
    """
    h = math.sin(tau / 2)
    val = l0**2 + 4 * delta**2 * h**2 - 4 * delta * l0 * h * math.cos(phi0 + tau / 2)
    return math.sqrt(max(val, 0.0))


def same_sign_bound(delta_r: float) -> float:
    """Largest initial semi-axis a same-sign two-burn programme can cancel: 4 sin(|Δ|/4) (§2.9)."""
    return 4 * math.sin(abs(delta_r) / 4)


# ---------------------------------------------------------------------------------------
# Burn durations from the secular conditions (§2.8) and the periodic conditions (§2.9)
# ---------------------------------------------------------------------------------------
def burn_durations(y0: Sequence[float], t0: float, tp: float, d1: int, d2: int,
                   final: Sequence[float] = (0.0, 0.0)) -> tuple[float, float]:
    """(t1, t2) meeting r_av(T) = r_k and L_av(T) = L_k for given (t0, tp) and signs.

    Same sign (d1 == d2 == d): t1 + t2 = d*Δ and the L_av condition is linear in t1.
    Opposite signs (d1 = d = -d2): t1 - t2 = d*Δ and the L_av condition is the quadratic
    of eq. (22) in t2; the larger root is returned (the only non-negative one when
    tp + 2 d r_k >= 0, e.g. for a zero final state). Returns (nan, nan) when the quadratic
    has no real root or, in the same-sign case, tp == 0.
    The durations may come out negative: callers keep only roots with t1, t2 >= 0.
    """
    r0, L0 = float(y0[0]), float(y0[1])
    rk, Lk = float(final[0]), float(final[1])
    dr = rk - r0
    if d1 == d2:
        d = d1
        S = d * dr                                   # t1 + t2
        if tp == 0:
            return math.nan, math.nan
        # L_k = L0 - 1.5 r0 T - 0.75 d (S**2 + 2 t1 tp), T = t0 + S + tp
        t1 = ((L0 - Lk - 1.5 * r0 * (t0 + S + tp)) / (0.75 * d) - S**2) / (2 * tp)
        return t1, S - t1
    d = d1
    m = d * dr                                       # t1 - t2
    # 0.75 d [2 t2^2 + (4m + 2tp) t2 + m^2 + 2 m tp] + 1.5 r0 (t0 + 2 t2 + m + tp) + Lk - L0 = 0
    a = 1.5 * d
    b = 0.75 * d * (4 * m + 2 * tp) + 3 * r0
    c = 0.75 * d * (m * m + 2 * m * tp) + 1.5 * r0 * (t0 + m + tp) + Lk - L0
    disc = b * b - 4 * a * c
    if disc < 0:
        return math.nan, math.nan
    # divide by a (sign d): t2^2 + (b/a) t2 + c/a = 0, larger root
    t2 = 0.5 * (-b / a + math.sqrt(disc) / abs(a))
    return t2 + m, t2


def two_burn_final_state(y0, t0, t1, tp, t2, d1, d2) -> np.ndarray:
    """Closed-form final state of the programme (wait t0, burn t1, coast tp, burn t2)."""
    burns, T = two_burn_segments(t0, t1, tp, t2, d1, d2)
    return multi_burn(y0, burns, T)


def periodic_residual(y0, t0: float, tp: float, d1: int, d2: int,
                      final: Sequence[float] = (0.0, 0.0, 0.0, 0.0)) -> np.ndarray:
    """(l_x(T) - l_xk, l_y(T) - l_yk) with (t1, t2) from the secular conditions (eq. (29), R1)."""
    t1, t2 = burn_durations(y0, t0, tp, d1, d2, final[:2])
    if math.isnan(t1):
        return np.array([math.nan, math.nan])
    x = two_burn_final_state(y0, t0, t1, tp, t2, d1, d2)
    return x[2:] - np.asarray(final[2:], float)


def criteria(t0, t1, tp, t2) -> tuple[float, float]:
    """(t_mot, t_sum) = (t1 + t2, t0 + t1 + tp + t2) (eq. (20))."""
    return t1 + t2, t0 + t1 + tp + t2


# ---------------------------------------------------------------------------------------
# Analytic Pareto boundary of the opposite-sign family, zero final state (§2.8)
# ---------------------------------------------------------------------------------------
def boundary_tp(t_mot: float, t0: float, y0: Sequence[float], delta: int) -> float:
    """Coast time on the boundary (24) for given motor time and wait (first burn sign ``delta``)."""
    r0, L0 = float(y0[0]), float(y0[1])
    num = 4 / 3 * L0 - 2 * r0 * t0 - r0 * t_mot - delta / 2 * (t_mot**2 - r0**2)
    return num / (r0 + delta * t_mot)


def boundary_t_sum(t_mot: float, t0: float, y0: Sequence[float], delta: int) -> float:
    """t_sum on the boundary (26): t0 + t_mot + tp(t_mot; t0)."""
    return t0 + t_mot + boundary_tp(t_mot, t0, y0, delta)


def right_end(t0: float, y0: Sequence[float], delta: int) -> tuple[float, float]:
    """(t_mot, t_sum) at tp = 0 (eq. (27)); nan if no real solution."""
    r0, L0 = float(y0[0]), float(y0[1])
    val = r0**2 / 2 + delta * (2 / 3 * L0 - r0 * t0)
    if val < 0:
        return math.nan, math.nan
    t2 = math.sqrt(val)
    t1 = t2 - r0 / delta
    return t1 + t2, t0 + t1 + t2
