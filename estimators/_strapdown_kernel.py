"""Compiled inner loop of :func:`rlgsim.estimators.strapdown.navigate` (numba).

The strapdown recursion is sequential (each attitude is the previous one times the sample's
rotation), so numpy can only vectorise it with a blocked scan and many temporary (n, 3) and
(n, 4) arrays: ~65 ms for a 40-min window at 100 Hz, twice per calibration window. One pass
over the samples in compiled code does the same arithmetic in ~3 ms.

The algorithms are those of ``navigate`` (its docstring and the strapdown module docstring):
two-sample coning correction without reach-back across the commanded rate steps (Savage 2007
eq. 7.1.1.1-11), quaternion update q_k = q_{k-1} ⊗ exp(φ_k/2) with the product normalised on
output, the exact constant-rate velocity rotation correction ΔV = Δv + ½Δθ×Δv +
(1/12)Δθ×(Δθ×Δv) rotated into i0 with the attitude at the sample start and into ENU with the
Earth rotation to the sample middle (Rodrigues), gravity removed, velocity summed in sample
order. Equal to the numpy formulation to rounding (tests/test_strapdown.py). The coning vector,
the quaternion product and the rotation of a vector by a quaternion are the navigator's too
(:mod:`rlgsim.estimators._rotation_kernel`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rlgsim.estimators._rotation_kernel import coning_vector, cross, quat_mul, quat_rotate


@njit(cache=True, nogil=True, inline="always")
def _velocity_increment(tx: float, ty: float, tz: float, ux: float, uy: float,
                        uz: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """ΔV = Δv + ½Δθ×Δv + (1/12)Δθ×(Δθ×Δv) [m/s] in the body frame: the exact constant-rate
    rotation correction (``navigate``'s docstring) of one sample's increments."""
    cx, cy, cz = cross(tx, ty, tz, ux, uy, uz)
    ex, ey, ez = cross(tx, ty, tz, cx, cy, cz)
    return ux + 0.5 * cx + ex / 12.0, uy + 0.5 * cy + ey / 12.0, uz + 0.5 * cz + ez / 12.0


@njit(cache=True, nogil=True, inline="always")
def _to_enu(ix: float, iy: float, iz: float, kx: float, ky: float, kz: float,
            ang: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Rotate the i0 vector (ix, iy, iz) about the unit axis k by ``ang`` [rad] (Rodrigues)."""
    ca, sa = math.cos(ang), math.sin(ang)
    kv = ix * kx + iy * ky + iz * kz
    ox = ix * ca + (ky * iz - kz * iy) * sa + kv * kx * (1.0 - ca)
    oy = iy * ca + (kz * ix - kx * iz) * sa + kv * ky * (1.0 - ca)
    oz = iz * ca + (kx * iy - ky * ix) * sa + kv * kz * (1.0 - ca)
    return ox, oy, oz


@njit(cache=True, nogil=True)
def strapdown_loop(dtheta, dv, dt_s, q0, is_break, k_axis, rate, g):  # pragma: no cover
    """Attitude quaternions body → i0 at sample ends (n, 4) and ENU velocity (n, 3) [m/s].

    ``dtheta``, ``dv`` (n, 3) increments [rad, m/s]; ``q0`` (4,) attitude at the start of
    sample 0 (body → ENU = i0 at t = 0); ``is_break`` (n,) bool: no coning reach-back into
    sample k; ``k_axis`` (3,) unit axis and ``rate`` [rad/s] of the i0 → ENU rotation
    (−ω_ie); ``g`` gravity [m/s²] (Up component removed)."""
    n = dtheta.shape[0]
    q_out = np.empty((n, 4))
    v_out = np.empty((n, 3))
    aw, ax, ay, az = q0[0], q0[1], q0[2], q0[3]          # running product (unnormalised)
    sw, sx, sy, sz = q0[0], q0[1], q0[2], q0[3]          # attitude at the sample start
    kx, ky, kz = k_axis[0], k_axis[1], k_axis[2]
    vx = vy = vz = 0.0
    for k in range(n):
        tx, ty, tz = dtheta[k, 0], dtheta[k, 1], dtheta[k, 2]
        if k == 0 or is_break[k]:
            px, py, pz = tx, ty, tz
        else:
            px, py, pz = dtheta[k - 1, 0], dtheta[k - 1, 1], dtheta[k - 1, 2]
        fx, fy, fz = coning_vector(px, py, pz, tx, ty, tz)
        a = math.sqrt(fx * fx + fy * fy + fz * fz)
        cw = math.cos(0.5 * a)
        s = math.sin(0.5 * a) / a if a != 0.0 else 0.5     # sin(a/2)/a
        # running product ⊗ exp(φ/2)
        aw, ax, ay, az = quat_mul(aw, ax, ay, az, cw, s * fx, s * fy, s * fz)
        norm = math.sqrt(aw * aw + ax * ax + ay * ay + az * az)
        q_out[k, 0] = aw / norm
        q_out[k, 1] = ax / norm
        q_out[k, 2] = ay / norm
        q_out[k, 3] = az / norm
        Vx, Vy, Vz = _velocity_increment(tx, ty, tz, dv[k, 0], dv[k, 1], dv[k, 2])
        # into i0 with the attitude at the sample start
        ix, iy, iz = quat_rotate(sw, sx, sy, sz, Vx, Vy, Vz)
        # into ENU: rotation about k by rate × (sample middle time)
        if rate != 0.0:
            ox, oy, oz = _to_enu(ix, iy, iz, kx, ky, kz, rate * ((k + 1.0) * dt_s - 0.5 * dt_s))
        else:
            ox, oy, oz = ix, iy, iz
        vx += ox
        vy += oy
        vz += oz - g * dt_s
        v_out[k, 0] = vx
        v_out[k, 1] = vy
        v_out[k, 2] = vz
        sw, sx, sy, sz = q_out[k, 0], q_out[k, 1], q_out[k, 2], q_out[k, 3]
    return q_out, v_out


@njit(cache=True, nogil=True)
def compensate_loop(gyro_pulses, accel_pulses, inv_k_g, d_g, inv_e_g, inv_k_pos, inv_k_neg,
                    d_a, inv_e_a, dt_s):  # pragma: no cover - tested through SensorModel
    """Δθ = E_g⁻¹ (N_g / K_g − D_g Δt) and Δv = E_a⁻¹ (N_a / K_a^± − D_a Δt) per sample, K_a^±
    by the sign of the accelerometer pulse count (:meth:`SensorModel.compensate`)."""
    n = gyro_pulses.shape[0]
    dtheta = np.empty((n, 3))
    dv = np.empty((n, 3))
    # the per-axis constants as scalars (D Δt formed once: the same product every sample);
    # the three axes written out — with two 3-vectors in memory the pass took 3× as long
    g0, g1, g2 = inv_k_g[0], inv_k_g[1], inv_k_g[2]
    bg0, bg1, bg2 = d_g[0] * dt_s, d_g[1] * dt_s, d_g[2] * dt_s
    p0, p1, p2 = inv_k_pos[0], inv_k_pos[1], inv_k_pos[2]
    m0, m1, m2 = inv_k_neg[0], inv_k_neg[1], inv_k_neg[2]
    ba0, ba1, ba2 = d_a[0] * dt_s, d_a[1] * dt_s, d_a[2] * dt_s
    for k in range(n):
        y0 = gyro_pulses[k, 0] * g0 - bg0
        y1 = gyro_pulses[k, 1] * g1 - bg1
        y2 = gyro_pulses[k, 2] * g2 - bg2
        a0, a1, a2 = accel_pulses[k, 0], accel_pulses[k, 1], accel_pulses[k, 2]
        z0 = a0 * (p0 if a0 >= 0 else m0) - ba0
        z1 = a1 * (p1 if a1 >= 0 else m1) - ba1
        z2 = a2 * (p2 if a2 >= 0 else m2) - ba2
        for i in range(3):
            dtheta[k, i] = inv_e_g[i, 0] * y0 + inv_e_g[i, 1] * y1 + inv_e_g[i, 2] * y2
            dv[k, i] = inv_e_a[i, 0] * z0 + inv_e_a[i, 1] * z1 + inv_e_a[i, 2] * z2
    return dtheta, dv
