import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from ocdsl.symbolic.model import syms
from ocdsl.symbolic.vectors import (cross, dot, hat, mrp_kinematics_matrix, mrp_shadow, mrp_to_dcm,
                                    mrp_to_quat, principal_rotation_to_mrp, quat_kinematics_matrix,
                                    quat_to_dcm, quat_to_mrp, rot1, rot2, rot3, rotation_matrix, skew,
                                    unskew, vec)

a = syms("a1 a2 a3")
b = syms("b1 b2 b3")
s = syms("s1 s2 s3")
RNG = np.random.default_rng(12345)


def num(m, subs):
    return np.array(sp.Matrix(m).xreplace(subs).evalf(), dtype=float)


def test_cross_skew_dot():
    A, B = sp.Matrix(a), sp.Matrix(b)
    assert sp.simplify(cross(a, b) - A.cross(B)) == sp.zeros(3, 1)
    assert sp.simplify(skew(a) + skew(a).T) == sp.zeros(3, 3)
    assert unskew(hat(a)) == A
    assert sp.expand(dot(a, b) - A.dot(B)) == 0
    assert sp.expand(dot(cross(a, b), a)) == 0
    with pytest.raises(ValueError):
        vec([1, 2])


@pytest.mark.parametrize("R", [rot1, rot2, rot3])
def test_rotations_orthonormal(R):
    th = sp.Symbol("th", real=True)
    M = R(th)
    assert sp.simplify(M * M.T) == sp.eye(3)
    assert sp.simplify(M.det()) == 1


def test_rotation_direction():
    th = 0.3
    # passive: the A-frame vector e1 seen from a frame rotated by +th about 3
    C = np.array(rot3(th), dtype=float)
    assert np.allclose(C @ [1, 0, 0], [np.cos(th), -np.sin(th), 0])
    Ra = np.array(rotation_matrix(3, th, active=True), dtype=float)
    assert np.allclose(Ra @ [1, 0, 0], [np.cos(th), np.sin(th), 0])
    assert np.allclose(np.array(rotation_matrix(2, th), dtype=float), np.array(rot2(th), dtype=float))
    with pytest.raises(ValueError):
        rotation_matrix(4, th)


def test_mrp_dcm_orthonormal_and_matches_quaternion():
    C = mrp_to_dcm(s)
    Cq = quat_to_dcm(mrp_to_quat(s))
    for _ in range(5):
        sig = RNG.uniform(-0.8, 0.8, 3)
        subs = dict(zip(s, sig))
        Cn = num(C, subs)
        assert np.allclose(Cn @ Cn.T, np.eye(3), atol=1e-13)
        assert np.isclose(np.linalg.det(Cn), 1.0, atol=1e-13)
        assert np.allclose(Cn, num(Cq, subs), atol=1e-13)
        # the shadow set describes the same attitude
        assert np.allclose(Cn, num(mrp_to_dcm(mrp_shadow(sig)), {}), atol=1e-12)


@pytest.mark.parametrize("axis,R", [((1, 0, 0), rot1), ((0, 1, 0), rot2), ((0, 0, 1), rot3)])
def test_principal_rotation_mrp_is_axis_rotation(axis, R):
    for ang in (np.pi / 2, 1.1, -2.0):
        sig = principal_rotation_to_mrp(axis, ang)
        assert np.allclose(num(mrp_to_dcm(sig), {}), np.array(R(ang), dtype=float), atol=1e-13)
    # 90 deg about axis 2 is tan(pi/8) = 0.41421..., not tan(pi/4)
    assert float(principal_rotation_to_mrp((0, 1, 0), sp.pi / 2)[1]) == pytest.approx(0.41421356237, abs=1e-10)


def test_quat_mrp_roundtrip():
    q = quat_to_mrp(mrp_to_quat(s))
    assert sp.simplify(q - sp.Matrix(s)) == sp.zeros(3, 1)


def test_mrp_kinematics_implies_dcm_kinematics():
    """dC/dt = -[w x] C when dsigma/dt = B(sigma) w / 4."""
    w = syms("w1 w2 w3")
    C = mrp_to_dcm(s)
    sdot = mrp_kinematics_matrix(s) * sp.Matrix(w) / 4
    Cdot = sum((C.diff(si) * sdot[i] for i, si in enumerate(s)), sp.zeros(3, 3))
    resid = Cdot + skew(w) * C
    for _ in range(3):
        subs = dict(zip(s, RNG.uniform(-0.7, 0.7, 3))) | dict(zip(w, RNG.normal(size=3)))
        assert np.abs(num(resid, subs)).max() < 1e-12


def test_mrp_and_quaternion_kinematics_agree_when_integrated():
    w = syms("w1 w2 w3")
    q = syms("q0 q1 q2 q3")
    fs = sp.lambdify((s, w), mrp_kinematics_matrix(s) * sp.Matrix(w) / 4, "numpy")
    fq = sp.lambdify((q, w), quat_kinematics_matrix(q) * sp.Matrix(w) / 2, "numpy")

    def omega(t):
        return np.array([0.3 * np.sin(t), 0.2 + 0.1 * t, -0.4 * np.cos(2 * t)])

    def rhs(t, y):
        return np.concatenate([np.ravel(fs(y[:3], omega(t))), np.ravel(fq(y[3:], omega(t)))])

    s0 = np.array([0.1, -0.2, 0.05])
    q0 = np.array(mrp_to_quat(s0), dtype=float).ravel()
    sol = solve_ivp(rhs, (0, 3), np.concatenate([s0, q0]), rtol=1e-11, atol=1e-12, dense_output=True)
    assert sol.success
    for t in np.linspace(0, 3, 7):
        y = sol.sol(t)
        qs = y[3:] / np.linalg.norm(y[3:])
        assert np.allclose(y[:3], qs[1:] / (1 + qs[0]), atol=1e-9)
    # the attitude actually moved (the test is not trivially satisfied)
    assert np.linalg.norm(sol.y[:3, -1] - s0) > 0.1
