"""SymPy vector and attitude helpers any model can use.

Conventions (Schaub & Junkins):

* vectors are 3x1 SymPy column matrices; every function also accepts a plain sequence;
* a direction-cosine matrix (DCM) ``C = [BA]`` maps components in frame A to components
  in frame B: ``[v]^B = C [v]^A`` (a *passive* rotation);
* :func:`rot1`/:func:`rot2`/:func:`rot3` are the DCMs of a frame rotated by ``angle``
  about its axis 1/2/3 (Schaub's M1, M2, M3);
* quaternions are ``(q0, q1, q2, q3)`` with the scalar part first;
* modified Rodrigues parameters (MRPs) are ``sigma = e tan(Phi/4)`` with ``e`` the
  principal axis and ``Phi`` the principal angle.

Everything is symbolic; lambdify the results for numbers.
"""
from __future__ import annotations

from typing import Sequence

import sympy as sp

__all__ = [
    "vec", "cross", "dot", "skew", "hat", "unskew", "rot1", "rot2", "rot3", "rotation_matrix",
    "mrp_to_dcm", "mrp_kinematics_matrix", "mrp_shadow", "quat_to_mrp", "mrp_to_quat",
    "quat_to_dcm", "quat_kinematics_matrix", "principal_rotation_to_mrp",
]


def vec(v: Sequence | sp.MatrixBase) -> sp.Matrix:
    """A 3x1 column matrix from any 3-sequence or matrix with 3 entries."""
    m = sp.Matrix(v)
    if m.shape == (1, 3):
        m = m.T
    if m.shape != (3, 1):
        raise ValueError(f"expected a 3-vector, got shape {m.shape}")
    return m


def dot(a, b) -> sp.Expr:
    """Scalar product a . b."""
    return (vec(a).T * vec(b))[0, 0]


def skew(v) -> sp.Matrix:
    """The skew-symmetric (hat, cross-product) matrix [v x], with [v x] w = v x w."""
    a, b, c = vec(v)
    return sp.Matrix([[0, -c, b], [c, 0, -a], [-b, a, 0]])


hat = skew


def unskew(m: sp.MatrixBase) -> sp.Matrix:
    """Inverse of :func:`skew`: the vector of a skew-symmetric 3x3 matrix."""
    m = sp.Matrix(m)
    return sp.Matrix([m[2, 1], m[0, 2], m[1, 0]])


def cross(a, b) -> sp.Matrix:
    """Vector product a x b as a 3x1 column."""
    return skew(a) * vec(b)


def rot1(angle) -> sp.Matrix:
    """DCM of a frame rotated by ``angle`` about axis 1 (passive; Schaub's M1)."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[1, 0, 0], [0, c, s], [0, -s, c]])


def rot2(angle) -> sp.Matrix:
    """DCM of a frame rotated by ``angle`` about axis 2 (passive; Schaub's M2)."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[c, 0, -s], [0, 1, 0], [s, 0, c]])


def rot3(angle) -> sp.Matrix:
    """DCM of a frame rotated by ``angle`` about axis 3 (passive; Schaub's M3)."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[c, s, 0], [-s, c, 0], [0, 0, 1]])


def rotation_matrix(axis: int, angle, active: bool = False) -> sp.Matrix:
    """Rotation about body axis ``axis`` (1, 2 or 3).

    ``active=False`` (default) gives the passive DCM (frame rotation, :func:`rot1` ...);
    ``active=True`` its transpose, the matrix that rotates a vector by ``angle``.
    """
    try:
        m = {1: rot1, 2: rot2, 3: rot3}[int(axis)](angle)
    except KeyError:
        raise ValueError(f"axis must be 1, 2 or 3, got {axis!r}") from None
    return m.T if active else m


def mrp_to_dcm(sigma) -> sp.Matrix:
    """DCM ``C(sigma) = [BA]`` of the MRP ``sigma`` of B relative to A.

    C = I + (8 [s x]^2 - 4 (1 - s^2) [s x]) / (1 + s^2)^2.
    """
    s = vec(sigma)
    s2 = dot(s, s)
    S = skew(s)
    return sp.eye(3) + (8 * S * S - 4 * (1 - s2) * S) / (1 + s2) ** 2


def mrp_kinematics_matrix(sigma) -> sp.Matrix:
    """B(sigma) with d(sigma)/dt = B(sigma) omega / 4, omega = angular velocity of B
    relative to A in B components.

    B = (1 - s^2) I + 2 [s x] + 2 s s^T.
    """
    s = vec(sigma)
    s2 = dot(s, s)
    return (1 - s2) * sp.eye(3) + 2 * skew(s) + 2 * s * s.T


def mrp_shadow(sigma) -> sp.Matrix:
    """The shadow set -sigma / |sigma|^2 (same attitude, other branch)."""
    s = vec(sigma)
    return -s / dot(s, s)


def principal_rotation_to_mrp(axis, angle) -> sp.Matrix:
    """MRP of a rotation by ``angle`` about the unit vector ``axis``: e tan(angle/4)."""
    return vec(axis) * sp.tan(sp.sympify(angle) / 4)


def quat_to_mrp(q) -> sp.Matrix:
    """MRP from a unit quaternion (q0 scalar first): sigma = q_v / (1 + q0)."""
    q0, q1, q2, q3 = sp.Matrix(q)
    return sp.Matrix([q1, q2, q3]) / (1 + q0)


def mrp_to_quat(sigma) -> sp.Matrix:
    """Unit quaternion (q0 first, q0 >= 0 for |sigma| <= 1) from an MRP."""
    s = vec(sigma)
    s2 = dot(s, s)
    return sp.Matrix([(1 - s2) / (1 + s2), *(2 * s / (1 + s2))])


def quat_to_dcm(q) -> sp.Matrix:
    """DCM ``[BA]`` of the unit quaternion (q0 first) of B relative to A."""
    q0, q1, q2, q3 = sp.Matrix(q)
    return sp.Matrix([
        [q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2)],
        [2 * (q1 * q2 - q0 * q3), q0**2 - q1**2 + q2**2 - q3**2, 2 * (q2 * q3 + q0 * q1)],
        [2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1), q0**2 - q1**2 - q2**2 + q3**2],
    ])


def quat_kinematics_matrix(q) -> sp.Matrix:
    """4x3 matrix with dq/dt = (1/2) M(q) omega (omega in B components)."""
    q0, q1, q2, q3 = sp.Matrix(q)
    return sp.Matrix([[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]])
