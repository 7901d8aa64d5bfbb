"""Linear-quadratic regulator on SciPy's algebraic Riccati solver.

:func:`care` wraps :func:`scipy.linalg.solve_continuous_are` with a clear error (and a
stabilisability diagnosis) when no stabilising solution exists. :class:`LQRController`
designs K = R^-1 B0^T P on the SDC matrices at the origin, A0 = A(0) (= the Jacobian of f
at the origin for any continuous SDC factorisation) and B0 = B(0), and applies u = -K x.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ocdsl.symbolic.sdc import NumericSDC, SDCError, controllability_rank, pbh_unstabilisable


class ControlError(RuntimeError):
    """A controller cannot be designed or evaluated (no stabilising Riccati solution...)."""


def care(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, what: str = "") -> np.ndarray:
    """Stabilising solution P of A^T P + P A - P B R^-1 B^T P + Q = 0 (SciPy)."""
    try:
        P = sla.solve_continuous_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        bad = pbh_unstabilisable(A, B)
        why = (f"(A, B) is not stabilisable: controllability rank {controllability_rank(A, B)} "
               f"of {A.shape[0]}" if bad else str(exc))
        raise ControlError(f"{what + ': ' if what else ''}no stabilising Riccati solution: {why}") from exc
    if not np.all(np.isfinite(P)):
        raise ControlError(f"{what + ': ' if what else ''}Riccati solution is not finite")
    return 0.5 * (P + P.T)


def lqr(A, B, Q, R, what: str = "LQR"):
    """(K, P, closed-loop eigenvalues) of the infinite-horizon LQR; a ControlError when the
    gain does not stabilise A - B K because Q does not see a mode of A that is not stable
    ((A, Q) not detectable: SciPy then returns a Riccati solution all the same, and the run
    ended 'unstable' as if the horizon were too short; unseen19 c4, Q = diag(0, 1) on a double
    integrator)."""
    P = care(A, B, Q, R, what)
    K = np.linalg.solve(R, B.T @ P)
    eig = np.linalg.eigvals(A - B @ K)
    scale = max(1.0, float(np.max(np.abs(np.linalg.eigvals(A)))))
    if np.max(eig.real) >= -1e-9 * scale:
        # a nearly free control leaves poles near the axis on purpose (Q 1e-12, R 1e6: -5e-7 +- 1i);
        # only a mode Q cannot see (PBH) is a design error
        n = A.shape[0]
        seen = np.asarray(Q, float) * (scale / max(float(np.max(np.abs(Q))), 1e-300))    # Q's pattern, A's size
        blind = [complex(lam) for lam in np.linalg.eigvals(A) if lam.real >= -1e-9 * scale
                 and np.linalg.matrix_rank(np.vstack([A - lam * np.eye(n), seen]), tol=1e-9 * scale) < n]
        if blind:
            shown = ", ".join(f"{lam.real:.3g}" + (f"{lam.imag:+.3g}j" if lam.imag else "") for lam in blind)
            raise ControlError(f"{what + ': ' if what else ''}the Riccati solution does not stabilise: (A, Q) "
                               f"is not detectable: Q gives no weight to the mode(s) of A with eigenvalue {shown} "
                               "(weight the states that mode moves)")
    return K, P, eig


class LQRController:
    """u = -K x with K designed once on (A(0), B(0))."""

    kind = "lqr"

    def __init__(self, num: NumericSDC, Q, R, origin: np.ndarray | None = None):
        self.num = num
        self.Q = np.asarray(Q, float)
        self.R = np.asarray(R, float)
        self.idx = np.asarray(num.index)
        z0 = np.zeros(len(num.sdc.model.states)) if origin is None else np.asarray(origin, float)
        self.A0, self.B0 = num.A(z0), num.B(z0)
        if pbh_unstabilisable(self.A0, self.B0):
            raise ControlError(
                f"LQR: (A0, B0) at the origin is not stabilisable: controllability rank "
                f"{controllability_rank(self.A0, self.B0)} of {self.A0.shape[0]}")
        self.K, self.P, self.eig = lqr(self.A0, self.B0, self.Q, self.R)

    def reset(self) -> None:
        pass

    def __call__(self, t: float, z: np.ndarray) -> np.ndarray:
        return -self.K @ z[self.idx]

    def info(self) -> dict:
        return {"K": self.K, "P": self.P, "closed_loop_eigenvalues":
                [[float(e.real), float(e.imag)] for e in self.eig]}


__all__ = ["ControlError", "care", "lqr", "LQRController", "SDCError"]
