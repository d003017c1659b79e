"""Rotations and the turntable's gimbal convention (src/rlgsim/ground/frames.py).

Reference: scipy.spatial.transform.Rotation (intrinsic Euler angles, rotation vectors,
quaternions stored scalar last), and a sequential loop for the blocked quaternion product.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rlgsim.ground.frames import (body_axis, body_to_enu, cross_rows, dcm_to_quat, quat_cumprod,
                                  quat_from_rotvec, quat_mul, quat_rotate, quat_to_dcm,
                                  rotate_about, rotation_matrix, skew)

RNG = np.random.default_rng(13)


def wxyz(r: Rotation) -> np.ndarray:
    """scipy's scalar-last quaternions as [w, x, y, z]."""
    return np.roll(r.as_quat(), 1, axis=-1)


def test_gimbal_convention_is_rx_outer_then_rz_inner():
    outer = RNG.uniform(-360, 360, 40)
    inner = RNG.uniform(-360, 360, 40)
    ref = Rotation.from_euler("XZ", np.c_[outer, inner], degrees=True).as_matrix()
    np.testing.assert_allclose(body_to_enu(outer, inner), ref, atol=1e-15)
    # broadcasting: scalars, and a grid of angles
    np.testing.assert_allclose(body_to_enu(outer[0], inner[0]), ref[0], atol=1e-15)
    assert body_to_enu(outer[:, None], inner[None, :5]).shape == (40, 5, 3, 3)
    # zero angles: body = ENU
    np.testing.assert_array_equal(body_to_enu(0.0, 0.0), np.eye(3))


def test_table_axes_in_body_coordinates():
    for o, i in zip(RNG.uniform(0, 360, 10), RNG.uniform(0, 360, 10)):
        c = body_to_enu(o, i)
        # the outer axis is East, carried into body axes; the inner axis is body z
        np.testing.assert_allclose(body_axis("outer", i), c.T @ [1.0, 0.0, 0.0], atol=1e-15)
        np.testing.assert_array_equal(body_axis("inner", i), [0.0, 0.0, 1.0])
        # turning the outer gimbal by a small angle rotates about that axis (body frame)
        d = 1e-4
        rel = Rotation.from_matrix(c.T @ body_to_enu(o + d, i)).as_rotvec()
        np.testing.assert_allclose(rel / np.radians(d), body_axis("outer", i), atol=1e-9)
    np.testing.assert_array_equal(body_axis(None, 10.0), np.zeros(3))


def test_rotation_matrix_and_quaternions_against_scipy():
    r = RNG.normal(size=(60, 3)) * np.logspace(-9, 0.5, 60)[:, None]
    ref = Rotation.from_rotvec(r)
    np.testing.assert_allclose(rotation_matrix(r), ref.as_matrix(), atol=1e-15)
    q = quat_from_rotvec(r)
    np.testing.assert_allclose(q * np.sign(q[:, :1]), wxyz(ref) * np.sign(wxyz(ref)[:, :1]),
                               atol=1e-15)
    np.testing.assert_allclose(quat_to_dcm(q), ref.as_matrix(), atol=1e-15)
    for m, qr in zip(ref.as_matrix()[::3], wxyz(ref)[::3]):
        qm = dcm_to_quat(m)
        np.testing.assert_allclose(qm * np.sign(qm[0]), qr * np.sign(qr[0]), atol=1e-15)
    # Hamilton product = composition of rotations (p ⊗ q acts as P·Q)
    p, s = Rotation.random(20, random_state=1), Rotation.random(20, random_state=2)
    np.testing.assert_allclose(quat_to_dcm(quat_mul(wxyz(p), wxyz(s))), (p * s).as_matrix(),
                               atol=1e-15)
    v = RNG.normal(size=(20, 3))
    np.testing.assert_allclose(quat_rotate(wxyz(p), v), p.apply(v), atol=1e-14)


def test_skew_cross_and_rotation_about_a_fixed_axis():
    a, b = RNG.normal(size=(30, 3)), RNG.normal(size=(30, 3))
    np.testing.assert_allclose(cross_rows(a, b), np.cross(a, b), atol=1e-15)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", skew(a), b), np.cross(a, b), atol=1e-15)
    w = np.array([0.0, 4.0e-5, 6.0e-5])
    t = np.linspace(0.0, 3.0e4, 30)
    np.testing.assert_allclose(rotate_about(w, t, b), Rotation.from_rotvec(np.outer(t, w))
                               .apply(b), atol=1e-14)
    np.testing.assert_array_equal(rotate_about(np.zeros(3), t, b), b)


@pytest.mark.parametrize("n", [1, 5, 64, 65, 1000, 4097])
def test_blocked_quaternion_prefix_product_equals_the_loop(n):
    rng = np.random.default_rng(n)
    q = quat_from_rotvec(rng.normal(size=(n, 3)) * 0.1)
    seq = np.empty_like(q)
    acc = q[0]
    for k in range(n):
        acc = quat_mul(acc, q[k]) if k else q[0]
        seq[k] = acc
    np.testing.assert_allclose(quat_cumprod(q), seq, atol=1e-13)
