"""Rotations and the turntable's gimbal convention, written once for both sides.

Frames: navigation frame ENU at the site (x East, y North, z Up); body frame = the IMU
measurement frame. Direction cosine matrices C map body components to navigation (or
inertial) components, v^n = C v^b. Quaternions are Hamilton quaternions stored scalar first,
[w, x, y, z] (scipy's :class:`~scipy.spatial.transform.Rotation` stores them scalar last).

**The turntable (gimbal) convention** — the one convention of the dataset (docs/dataset.md):
the outer axis is horizontal along East, the inner axis is carried by it and is the body z
axis, and the body frame coincides with ENU at zero angles. The attitude is

    C_b^n = R_x(outer) R_z(inner)

(:func:`body_to_enu`); the outer axis in body coordinates is C_n^b e_East = (cos i, −sin i, 0)
and the inner axis is body z (:func:`body_axis`). The simulator's kinematics
(:mod:`rlgsim.sim.motion.kinematics`) and the calibration's strapdown navigation
(:mod:`rlgsim.estimators.strapdown`) both use these functions.

Rotation algebra (Titterton & Weston 2004 §3.6, §11.2; Savage, *Strapdown Analytics* 2nd ed.
2007, §7.1): Rodrigues' formula for the rotation vector → matrix, the quaternion exponential,
Hamilton product, quaternion ↔ matrix (Shepperd's method), and a blocked prefix product of a
quaternion sequence. They are hand-written rather than taken from
:class:`scipy.spatial.transform.Rotation` because the navigation needs what Rotation does not
offer: broadcasting over arbitrary leading axes, the exact small-angle (sinc) forms, and a
vectorised prefix product of a quaternion sequence. tests/test_frames.py checks every one of
them against Rotation.
"""

from __future__ import annotations

import math

import numpy as np

from rlgsim.ground.units import DEG


# ---------------------------------------------------------------------- gimbal convention

def body_to_enu(outer_deg: np.ndarray, inner_deg: np.ndarray) -> np.ndarray:
    """Attitude of the table's body frame C_b^n = R_x(outer) R_z(inner) for table angles [°]
    (outer axis horizontal along East, inner axis = body z, body = ENU at zero angles).
    Broadcasts, (…, 3, 3)."""
    o = np.asarray(outer_deg, dtype=float) * DEG
    i = np.asarray(inner_deg, dtype=float) * DEG
    co, so, ci, si = np.cos(o), np.sin(o), np.cos(i), np.sin(i)
    zero = np.zeros_like(co * ci)
    return np.stack([np.stack([ci + zero, -si + zero, zero], -1),
                     np.stack([co * si, co * ci, -so + zero], -1),
                     np.stack([so * si, so * ci, co + zero], -1)], -2)


def body_axis(axis: str | None, inner_deg: float) -> np.ndarray:
    """Unit vector of a table axis in body coordinates at inner angle ``inner_deg`` [°]:
    ``"outer"`` → (cos i, −sin i, 0), ``"inner"`` → (0, 0, 1), anything else (a static
    table) → zeros."""
    if axis == "outer":
        i = inner_deg * DEG
        return np.array([math.cos(i), -math.sin(i), 0.0])
    if axis == "inner":
        return np.array([0.0, 0.0, 1.0])
    return np.zeros(3)


# ------------------------------------------------------------------------------ rotations

def skew(v: np.ndarray) -> np.ndarray:
    """[v×] for v (…, 3) → (…, 3, 3)."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: exp([r×]) for rotation vectors r (…, 3) → (…, 3, 3)."""
    r = np.asarray(rotvec, dtype=float)
    a = np.linalg.norm(r, axis=-1)[..., None, None]
    k = skew(r)
    s = np.sinc(a / np.pi)                                  # sin a / a
    c = 0.5 * np.sinc(a / (2 * np.pi)) ** 2                 # (1 − cos a)/a²
    return np.eye(3) + s * k + c * (k @ k)


def quat_from_rotvec(r: np.ndarray) -> np.ndarray:
    """exp(r/2) as quaternions [w, x, y, z] (…, 4); exact for small angles (sinc form)."""
    a = np.linalg.norm(r, axis=-1)
    return np.concatenate([np.cos(0.5 * a)[..., None],
                           (0.5 * np.sinc(a / (2 * np.pi)))[..., None] * r], axis=-1)


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q, broadcasting over leading axes."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of unit quaternions (…, 4) → (…, 3, 3) (v^i = C v^b)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def dcm_to_quat(c: np.ndarray) -> np.ndarray:
    """Unit quaternion of one rotation matrix (Shepperd's method)."""
    c = np.asarray(c, dtype=float)
    tr = np.trace(c)
    k = int(np.argmax([tr, c[0, 0], c[1, 1], c[2, 2]]))
    if k == 0:
        w = 0.5 * math.sqrt(1 + tr)
        q = [w, (c[2, 1] - c[1, 2]) / (4 * w), (c[0, 2] - c[2, 0]) / (4 * w),
             (c[1, 0] - c[0, 1]) / (4 * w)]
    elif k == 1:
        x = 0.5 * math.sqrt(1 + 2 * c[0, 0] - tr)
        q = [(c[2, 1] - c[1, 2]) / (4 * x), x, (c[0, 1] + c[1, 0]) / (4 * x),
             (c[0, 2] + c[2, 0]) / (4 * x)]
    elif k == 2:
        y = 0.5 * math.sqrt(1 + 2 * c[1, 1] - tr)
        q = [(c[0, 2] - c[2, 0]) / (4 * y), (c[0, 1] + c[1, 0]) / (4 * y), y,
             (c[1, 2] + c[2, 1]) / (4 * y)]
    else:
        z = 0.5 * math.sqrt(1 + 2 * c[2, 2] - tr)
        q = [(c[1, 0] - c[0, 1]) / (4 * z), (c[0, 2] + c[2, 0]) / (4 * z),
             (c[1, 2] + c[2, 1]) / (4 * z), z]
    q = np.array(q)
    return q / np.linalg.norm(q)


def quat_cumprod(q: np.ndarray) -> np.ndarray:
    """Prefix products P_k = q_0 ⊗ q_1 ⊗ … ⊗ q_k of quaternions q (n, 4).

    Blocked scan: the sequence is cut into ~√n blocks, the products inside all blocks advance
    together (one vectorised multiply per position in a block), the block totals are prefixed
    recursively, and one vectorised multiply joins them. Same multiplications as the
    sequential loop up to association, so rounding stays at the eps·√n level.
    """
    q = np.asarray(q, dtype=float)
    n = q.shape[0]
    if n <= 64:
        out = np.empty_like(q)
        acc = q[0]
        out[0] = acc
        for k in range(1, n):
            acc = quat_mul(acc, q[k])
            out[k] = acc
        return out
    b = int(math.ceil(math.sqrt(n)))
    nb = -(-n // b)
    pad = np.zeros((nb * b, 4))
    pad[:, 0] = 1.0
    pad[:n] = q
    blocks = pad.reshape(nb, b, 4)
    local = np.empty_like(blocks)
    acc = blocks[:, 0]
    local[:, 0] = acc
    for j in range(1, b):
        acc = quat_mul(acc, blocks[:, j])
        local[:, j] = acc
    totals = quat_cumprod(local[:, -1])                     # inclusive prefix of block totals
    prefix = np.concatenate([[[1.0, 0.0, 0.0, 0.0]], totals[:-1]])
    out = quat_mul(prefix[:, None, :], local).reshape(nb * b, 4)[:n]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (faster than np.cross for tall arrays)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """q ⊗ v ⊗ q* for unit quaternions (n, 4) and vectors (n, 3)."""
    u = q[..., 1:]
    t = 2.0 * cross_rows(u, v)
    return v + q[..., :1] * t + cross_rows(u, t)


def rotate_about(axis_angle_rate: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (n, 3) by the rotation vector ``axis_angle_rate`` × t (n,) (a fixed
    axis, Rodrigues on vectors)."""
    w = np.asarray(axis_angle_rate, float)
    rate = float(np.linalg.norm(w))
    if rate == 0.0:
        return np.array(v, dtype=float)
    k = w / rate
    a = (rate * np.asarray(t, float))[:, None]
    kv = np.einsum("nj,j->n", v, k)
    return v * np.cos(a) + cross_rows(np.broadcast_to(k, v.shape), v) * np.sin(a) \
        + np.outer(kv, k) * (1.0 - np.cos(a))
