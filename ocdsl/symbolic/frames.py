"""Frame conversions for the CR3BP: synodic (barycentric rotating) Cartesian <-> the
Earth-centred rotating polar frame (ECRF) of seed 1, and revolution counting.

Every function works on SymPy expressions (pass ``lib=sympy``) and on NumPy scalars or
arrays (the default ``lib=numpy``), so the same formulas serve the symbolic models and
the numerical checks.

Conventions (digest §2.7, §7 item 12):
- The Earth is at x = -mu, the Moon at x = 1 - mu; the ECRF origin is the Earth.
- theta_E is quadrant-aware (``atan2(y, x + mu)``), never a plain arctan.
- Revolutions are counted with the paper's convention theta(tf) = 2*pi*N_rev + theta_f
  with theta_f in [0, 2*pi); the initial angle is taken in [0, 2*pi) too
  (:func:`initial_angle` with ``convention="0_2pi"``), which the digest argues is the
  natural reading, or as the raw atan2 value in (-pi, pi] (``"atan2"``).
"""
from __future__ import annotations

import math

import numpy as np


def _lib(lib):
    return np if lib is None else lib


def synodic_to_ecrf(x, y, z, vx, vy, vz, mu, lib=None):
    """Synodic Cartesian state -> ECRF polar (r, theta, z, rdot, thetadot, zdot).

    theta is atan2(y, x + mu) in (-pi, pi]; use :func:`wrap_2pi` or
    :func:`unwrap_angle` for other conventions.
    """
    L = _lib(lib)
    xe = x + mu
    r = L.sqrt(xe**2 + y**2)
    theta = L.arctan2(y, xe) if L is np else L.atan2(y, xe)
    rdot = (vx * xe + vy * y) / r
    thetadot = (vy * xe - vx * y) / r**2
    return r, theta, z, rdot, thetadot, vz


def ecrf_to_synodic(r, theta, z, rdot, thetadot, zdot, mu, lib=None):
    """ECRF polar state -> synodic Cartesian (x, y, z, vx, vy, vz)."""
    L = _lib(lib)
    c, s = L.cos(theta), L.sin(theta)
    x = r * c - mu
    y = r * s
    vx = rdot * c - r * thetadot * s
    vy = rdot * s + r * thetadot * c
    return x, y, z, vx, vy, zdot


def polar_direction_to_cartesian(delta, phi, theta, lib=None):
    """Thrust direction from the paper's angles (eq. 28) to synodic Cartesian components.

    alpha = sin(delta) sin(phi) r_hat + cos(delta) sin(phi) theta_hat + cos(phi) z_hat:
    delta is measured from the transverse direction toward the radial one, phi from +z.
    """
    L = _lib(lib)
    ar = L.sin(delta) * L.sin(phi)
    at = L.cos(delta) * L.sin(phi)
    az = L.cos(phi)
    c, s = L.cos(theta), L.sin(theta)
    return ar * c - at * s, ar * s + at * c, az


def cartesian_direction_to_polar(ax, ay, az, theta, lib=None):
    """Synodic thrust direction (unit vector) -> the paper's angles (delta, phi)."""
    L = _lib(lib)
    c, s = L.cos(theta), L.sin(theta)
    ar = ax * c + ay * s
    at = -ax * s + ay * c
    if L is np:
        return np.arctan2(ar, at), np.arccos(np.clip(az, -1.0, 1.0))
    return L.atan2(ar, at), L.acos(az)


def wrap_2pi(theta):
    """Angle in [0, 2*pi) (NumPy or float)."""
    return np.mod(theta, 2.0 * math.pi)


def target_angle(theta_f, n_rev, lib=None):
    """The paper's unwrapped final angle theta(tf) = 2*pi*N_rev + theta_f (eq. 26)."""
    L = _lib(lib)
    return 2 * L.pi * n_rev + theta_f


def initial_angle(theta_atan2, convention: str = "0_2pi"):
    """Initial ECRF angle under a revolution-counting convention ("0_2pi" or "atan2")."""
    if convention == "0_2pi":
        return float(wrap_2pi(theta_atan2))
    if convention == "atan2":
        return float(theta_atan2)
    raise ValueError(f"unknown angle convention {convention!r}; use '0_2pi' or 'atan2'")


def unwrap_angle(theta_samples):
    """Continuous angle history from wrapped samples (revolutions counted by unwrapping)."""
    return np.unwrap(np.asarray(theta_samples, float))


def revolutions(theta_unwrapped_final, theta_f_wrapped=None):
    """N_rev such that theta(tf) = 2*pi*N_rev + theta_f with theta_f in [0, 2*pi).

    Given only the unwrapped final angle, theta_f is its [0, 2*pi) residue.
    """
    th = float(theta_unwrapped_final)
    thf = float(wrap_2pi(th)) if theta_f_wrapped is None else float(theta_f_wrapped)
    return int(round((th - thf) / (2.0 * math.pi)))


def jacobi_constant(x, y, z, vx, vy, vz, mu):
    """CR3BP Jacobi constant C = 2U - v^2, U = (x^2+y^2)/2 + (1-mu)/r1 + mu/r2."""
    r1 = np.sqrt((x + mu) ** 2 + y**2 + z**2)
    r2 = np.sqrt((x - 1 + mu) ** 2 + y**2 + z**2)
    return x**2 + y**2 + 2 * (1 - mu) / r1 + 2 * mu / r2 - (vx**2 + vy**2 + vz**2)
