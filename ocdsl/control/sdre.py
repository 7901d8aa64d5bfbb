"""State-dependent Riccati equation (SDRE) controller.

At every control update: A(x), B(x) from the SDC factorisation, P(x) from SciPy's
algebraic Riccati solver, u = -R^-1 B(x)^T P(x) x. When the Riccati equation has no
stabilising solution at some state (SciPy fails, or its solution leaves a mode Q does not
see unstable), the last good P is kept and the event counted
(``failures``); with ``strict=True`` a :class:`ControlError` is raised instead.
"""
from __future__ import annotations

import numpy as np

from ocdsl.symbolic.sdc import NumericSDC

from .lqr import ControlError, lqr


class SDREController:
    kind = "sdre"

    def __init__(self, num: NumericSDC, Q, R, strict: bool = False):
        self.num = num
        self.Q = np.asarray(Q, float)
        self.R = np.asarray(R, float)
        self.Rinv = np.linalg.inv(self.R)
        self.idx = np.asarray(num.index)
        self.strict = strict
        self.reset()

    def reset(self) -> None:
        self.failures = 0
        self.last_P = None

    def riccati(self, z: np.ndarray) -> np.ndarray:
        """P(x) at the full plant state z."""
        return lqr(self.num.A(z), self.num.B(z), self.Q, self.R, "SDRE")[1]

    def __call__(self, t: float, z: np.ndarray) -> np.ndarray:
        A, B = self.num.A(z), self.num.B(z)
        try:
            # a solution that does not stabilise (Q blind to a mode of A(x)) is a failure, as
            # for LQR: it was used and counted as none (unseen46 F4)
            P = lqr(A, B, self.Q, self.R, "SDRE")[1]
            self.last_P = P
        except ControlError:
            self.failures += 1
            if self.strict or self.last_P is None:
                raise
            P = self.last_P
        return -self.Rinv @ (B.T @ (P @ z[self.idx]))

    def info(self) -> dict:
        return {"riccati_failures": self.failures}
