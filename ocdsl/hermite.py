"""The cubic Hermite basis on [0, 1]: the value at s of the cubic with values y0, y1 and
slopes d0, d1 (per unit s) at its ends is h00 y0 + h10 d0 + h01 y1 + h11 d1. Shared by the
certificate's PCHIP (solve/pchip.py) and the verification's between-node states
(verify/functions.py), which may not import each other's packages."""
from __future__ import annotations


def hermite_basis(s):
    """(h00, h10, h01, h11) at ``s`` (array or scalar)."""
    s2, s3 = s * s, s * s * s
    return 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
