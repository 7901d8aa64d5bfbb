"""Theta-D controller (Xin & Balakrishnan 2005), as used in seed 3 (eqs. 16-30).

Split the SDC form as A(x) = A0 + dA(x), B(x) = g0 + g(x) with (A0, g0) stabilisable,
expand dV/dx = sum_i T_i(x) x (theta cancels; theta = 1), and add the perturbation
D_i = k_i exp(-a_i t) RHS_i to the cost. Then

    offline:  T0 A0 + A0^T T0 - T0 S T0 + Q = 0        (one algebraic Riccati equation)
              Ac = A0 - S T0,  S = g0 R^-1 g0^T          (and a real Schur form of Ac)
    online:   Ac^T T_n + T_n Ac = (1 - k_n e^{-a_n t}) RHS_n,   n = 1..N
              RHS_n = -(T_{n-1} dA + dA^T T_{n-1})
                      + sum_{j=0}^{n-1} T_j (g0 R^-1 g^T + g R^-1 g0^T) T_{n-1-j}
                      + sum_{j=0}^{n-2} T_j g R^-1 g^T T_{n-2-j}
                      + sum_{j=1}^{n-1} T_j S T_{n-j}
              u = -R^-1 B(x)^T (T0 + ... + T_N) x

``terms`` = N + 1 (T0..TN). The online step solves only Lyapunov (Sylvester) equations
with the constant operator L(T) = Ac^T T + T Ac: with ``lyapunov="schur"`` (default) the
real Schur form Ac = U S U^T is computed offline and each online solve is one
triangular Sylvester solve (LAPACK ``trsyl`` via ``scipy.linalg.lapack``) plus four
matrix products; ``lyapunov="scipy"`` calls :func:`scipy.linalg.solve_continuous_lyapunov`
every time (it redoes the Schur form). Both give the same T_i.

k_i = 1 switches the higher terms off at t = 0 (u(0) = u_LQR(0)); k_i = 0 is the
"theta-approximation" without perturbation. ``A0``: ``"origin"`` (A(0) with zero
auxiliary states = the Jacobian at the origin; the default) or a given matrix.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dtrsyl

from ocdsl.symbolic.sdc import NumericSDC, controllability_rank, pbh_unstabilisable

from .lqr import ControlError, lqr


class ThetaDController:
    kind = "theta-d"

    def __init__(self, num: NumericSDC, Q, R, terms: int = 3, k=None, a=None, A0="origin",
                 lyapunov: str = "schur", origin: np.ndarray | None = None):
        if terms < 1:
            raise ControlError("Theta-D: terms must be >= 1 (T0 only is LQR)")
        N = terms - 1
        self.k = np.broadcast_to(np.asarray(1.0 if k is None else k, float), (N,)).copy() if N else np.zeros(0)
        self.a = np.broadcast_to(np.asarray(0.5 if a is None else a, float), (N,)).copy() if N else np.zeros(0)
        if np.any(self.a < 0):
            raise ControlError("Theta-D: a_i must be >= 0")
        if lyapunov not in ("schur", "scipy"):
            raise ControlError(f"Theta-D: lyapunov={lyapunov!r}; use schur or scipy")
        self.num = num
        self.terms = terms
        self.lyapunov = lyapunov
        self.Q = np.asarray(Q, float)
        self.R = np.asarray(R, float)
        self.Rinv = np.linalg.inv(self.R)
        self.idx = np.asarray(num.index)
        z0 = np.zeros(len(num.sdc.model.states)) if origin is None else np.asarray(origin, float)
        self.B0 = num.B(z0)
        if isinstance(A0, str):
            if A0 not in ("origin", "jacobian_at_origin"):
                raise ControlError(f"Theta-D: A0={A0!r}; use origin (jacobian_at_origin) or a matrix")
            self.A0 = num.A(z0)
        else:
            self.A0 = np.asarray(A0, float)
            if self.A0.shape != (num.sdc.n, num.sdc.n):
                raise ControlError(f"Theta-D: A0 has shape {self.A0.shape}, expected {(num.sdc.n,) * 2}")
        if pbh_unstabilisable(self.A0, self.B0):
            raise ControlError(
                f"Theta-D: (A0, g0) is not stabilisable: controllability rank "
                f"{controllability_rank(self.A0, self.B0)} of {self.A0.shape[0]}")
        # ---- offline: one Riccati equation and the Schur form of Ac
        self.S = self.B0 @ self.Rinv @ self.B0.T
        # T0 is A0's LQR solution, refused like LQR's where it does not stabilise (its Lyapunov
        # series needs a Hurwitz A0 - B0 R^-1 B0^T T0; unseen46 F4 ran on eigenvalue 0)
        self.T0 = lqr(self.A0, self.B0, self.Q, self.R, "Theta-D T0")[1]
        self.Ac = self.A0 - self.S @ self.T0
        self.Tschur, self.U = sla.schur(self.Ac, output="real")
        self.B_constant = num.B_constant
        self.reset()

    def reset(self) -> None:
        self.steps = 0

    # ---- Lyapunov solve with the constant operator L(T) = Ac^T T + T Ac
    def solve_L(self, C: np.ndarray) -> np.ndarray:
        if self.lyapunov == "scipy":
            X = sla.solve_continuous_lyapunov(self.Ac.T, C)
        else:
            U = self.U
            Y, scale, info = dtrsyl(self.Tschur, self.Tschur, U.T @ C @ U, trana="T", tranb="N")
            if info < 0:  # pragma: no cover
                raise ControlError(f"Theta-D: trsyl failed (info={info})")
            X = U @ (Y / scale) @ U.T
        return 0.5 * (X + X.T)

    def series(self, t: float, z: np.ndarray) -> list[np.ndarray]:
        """[T0, T1, ..., TN] at time t and full plant state z."""
        dA = self.num.A(z) - self.A0
        T = [self.T0]
        if self.B_constant:
            g = None
        else:
            g = self.num.B(z) - self.B0
            G1 = self.B0 @ self.Rinv @ g.T + g @ self.Rinv @ self.B0.T
            G2 = g @ self.Rinv @ g.T
        for n in range(1, self.terms):
            Tp = T[n - 1]
            M = Tp @ dA
            rhs = -(M + M.T)
            for j in range(1, n):
                rhs += T[j] @ self.S @ T[n - j]
            if g is not None:
                for j in range(n):
                    rhs += T[j] @ G1 @ T[n - 1 - j]
                for j in range(n - 1):
                    rhs += T[j] @ G2 @ T[n - 2 - j]
            factor = 1.0 - self.k[n - 1] * np.exp(-self.a[n - 1] * t)
            if factor == 0.0:
                T.append(np.zeros_like(self.T0))
            else:
                T.append(self.solve_L(factor * rhs))
        return T

    def gain_matrix(self, t: float, z: np.ndarray) -> np.ndarray:
        return sum(self.series(t, z))

    def __call__(self, t: float, z: np.ndarray) -> np.ndarray:
        self.steps += 1
        P = self.gain_matrix(t, z)
        B = self.B0 if self.B_constant else self.num.B(z)
        return -self.Rinv @ (B.T @ (P @ z[self.idx]))

    def info(self) -> dict:
        return {"T0": self.T0, "terms": self.terms, "k": self.k.tolist(), "a": self.a.tolist(),
                "lyapunov": self.lyapunov,
                "Ac_eigenvalues": [[float(e.real), float(e.imag)] for e in np.linalg.eigvals(self.Ac)]}
