"""Compiled inner loop of the strapdown navigator (:mod:`rlgsim.estimators.ins.mechanization`).

The recursion is sequential (each sample's attitude, velocity and position start from the
previous ones), so it runs as one pass in numba; numpy could only vectorise it with many
(n, 3) temporaries and still needs a loop for the position-dependent terms. The algorithm and
its sources are in the mechanization module's docstring; this file holds only the arithmetic,
one inlined helper per step (frame rates, specific force, position, attitude) and the rotation
algebra shared with the calibration's strapdown loop (:mod:`rlgsim.estimators._rotation_kernel`).
The WGS-84 constants and the Earth rate come from :mod:`rlgsim.ground.earth` and
:mod:`rlgsim.ground.units` (numba freezes them at compile time).

State vector (float64, :data:`STATE_SIZE`): q_b^n [w, x, y, z] (0–3), v^n ENU [m/s] (4–6),
latitude [rad] (7), longitude [rad] (8), height [m] (9), the previous sample's Δθ (10–12) and
Δv (13–15), the velocity one sample before the current one (16–18), and a flag (19) that the
three "previous" slots hold data (0 at the start of a run: no coning/sculling reach-back),
and the latitude [rad] and height [m] at which the Earth quantities were last evaluated
(20–21), so that a run continued from the state equals one long run bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rlgsim.estimators._rotation_kernel import coning_vector, cross, quat_mul, quat_rotate
from rlgsim.ground.earth import (WGS84_A, WGS84_E2, WGS84_F, WGS84_GAMMA_E, WGS84_K,
                                 WGS84_M)
from rlgsim.ground.units import EARTH_RATE

STATE_SIZE = 22
#: the Earth quantities (radii, gravity, Earth rate, tan L) are re-evaluated when the latitude
#: has moved by more than this since their last evaluation (1e-9 rad ≈ 6 mm: the Earth rate
#: then differs by Ω·1e-9 = 7e-14 rad/s, gravity by 5e-11 m/s² — far below any IMU's errors)
EARTH_REFRESH_RAD = 1e-9
EARTH_REFRESH_M = 1e-3


@njit(cache=True, nogil=True, inline="always")
def _gravity(s2, h):  # pragma: no cover - compiled; tested through the navigator
    """Normal gravity γ(L, h) [m/s²] from sin²L (Somigliana + free air, NIMA TR8350.2 4-1, 4-3)."""
    g0 = WGS84_GAMMA_E * (1.0 + WGS84_K * s2) / math.sqrt(1.0 - WGS84_E2 * s2)
    return g0 * (1.0 - 2.0 / WGS84_A * (1.0 + WGS84_F + WGS84_M - 2.0 * WGS84_F * s2) * h
                 + 3.0 * h * h / (WGS84_A * WGS84_A))


@njit(cache=True, nogil=True)
def _earth(lat, h):  # pragma: no cover - compiled
    """sin L, cos L, 1/(R_M + h), 1/(R_E + h), tan L/(R_E + h), γ(L, h) (Groves eqs.
    2.105–2.106; NIMA TR8350.2 4-1, 4-3)."""
    sl, cl = math.sin(lat), math.cos(lat)
    s2 = sl * sl
    d = 1.0 - WGS84_E2 * s2
    sd = math.sqrt(d)
    rm_i = 1.0 / (WGS84_A * (1.0 - WGS84_E2) / (d * sd) + h)
    re_i = 1.0 / (WGS84_A / sd + h)
    return sl, cl, rm_i, re_i, sl / cl * re_i, _gravity(s2, h)


@njit(cache=True, nogil=True, inline="always")
def _half_exp(a2):  # pragma: no cover - compiled
    """cos(a/2) and sin(a/2)/a for a² = ``a2`` (series below 1e-4 rad², exact to 1e-19)."""
    if a2 < 1e-4:
        return (1.0 - a2 / 8.0 + a2 * a2 / 384.0,
                0.5 - a2 / 48.0 + a2 * a2 / 3840.0)
    a = math.sqrt(a2)
    return math.cos(0.5 * a), math.sin(0.5 * a) / a


@njit(cache=True, nogil=True, inline="always")
def _frame_rates(me: float, mn: float, sl: float, cl: float, rm_i: float, re_i: float,
                 tl_re: float) -> tuple[float, float, float, float, float]:  # pragma: no cover
    """Earth rate ω_ie^n (North, Up) and transport rate ω_en^n (E, N, U) [rad/s] in ENU at the
    velocity (me, mn) [m/s] (Groves eqs. 2.123, 5.44; T&W eq. 3.87)."""
    wie_n, wie_u = EARTH_RATE * cl, EARTH_RATE * sl
    return wie_n, wie_u, -mn * rm_i, me * re_i, me * tl_re


@njit(cache=True, nogil=True, inline="always")
def _specific_force_increment(tx: float, ty: float, tz: float, ux: float, uy: float, uz: float,
                              ptx: float, pty: float, ptz: float, pvx: float, pvy: float,
                              pvz: float, qw: float, qx: float, qy: float, qz: float, zx: float,
                              zy: float, zz: float
                              ) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """The sample's specific-force velocity increment [m/s] in the navigation frame at the
    middle of the frame's turn: Δv + ½Δθ×Δv + two-sample sculling (Savage 2007 §7.2.2.2) in
    the body frame, rotated by q (the attitude at the sample start), then by (I − ½[ζ×])."""
    cx, cy, cz = cross(tx, ty, tz, ux, uy, uz)
    s1x = pty * uz - ptz * uy + pvy * tz - pvz * ty
    s1y = ptz * ux - ptx * uz + pvz * tx - pvx * tz
    s1z = ptx * uy - pty * ux + pvx * ty - pvy * tx
    bx = ux + 0.5 * cx + s1x / 12.0
    by = uy + 0.5 * cy + s1y / 12.0
    bz = uz + 0.5 * cz + s1z / 12.0
    # into the navigation frame at the sample start: C_b^n(k-1) ΔV
    fx, fy, fz = quat_rotate(qw, qx, qy, qz, bx, by, bz)
    # ... then to the middle of the frame's turn: (I − ½[ζ×])
    rx, ry, rz = cross(zx, zy, zz, fx, fy, fz)
    return fx - 0.5 * rx, fy - 0.5 * ry, fz - 0.5 * rz


@njit(cache=True, nogil=True, inline="always")
def _attitude_step(qw: float, qx: float, qy: float, qz: float, tx: float, ty: float, tz: float,
                   ptx: float, pty: float, ptz: float, zx: float, zy: float, zz: float
                   ) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """q ← exp(−ζ/2) ⊗ q ⊗ exp(φ/2), φ with two-sample coning (Savage 2007 §7.1.1.1), then
    renormalised: 1/√s ≈ (3 − s)/2 near s = 1, error O((s − 1)²) ~ 1e-30."""
    px, py, pz = coning_vector(ptx, pty, ptz, tx, ty, tz)
    cw, sc = _half_exp(px * px + py * py + pz * pz)
    nw, nx, ny, nz = quat_mul(qw, qx, qy, qz, cw, sc * px, sc * py, sc * pz)
    cw, sc = _half_exp(zx * zx + zy * zy + zz * zz)
    qw, qx, qy, qz = quat_mul(cw, -sc * zx, -sc * zy, -sc * zz, nw, nx, ny, nz)
    norm = 0.5 * (3.0 - (qw * qw + qx * qx + qy * qy + qz * qz))
    return qw * norm, qx * norm, qy * norm, qz * norm


@njit(cache=True, nogil=True, inline="always")
def _position_step(lat: float, lon: float, oe: float, on: float, ve: float, vn: float, sl: float,
                   cl: float, rm_i: float, re_i: float,
                   dt: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """Latitude and longitude [rad] after one sample: trapezoidal velocity (previous o, new v
    [m/s]), radii at the sample start, 1/cos of the mid latitude as 1/cos L (1 + tan L · ΔL/2),
    exact to O(ΔL²)."""
    lat_new = lat + 0.5 * (on + vn) * rm_i * dt
    lon = lon + 0.5 * (oe + ve) * re_i / cl * (1.0 + sl / cl * 0.5 * (lat_new - lat)) * dt
    return lat_new, lon


@njit(cache=True, nogil=True)
def ins_loop(dtheta, dv, dt, state, href, hold, every):  # pragma: no cover - compiled
    """Navigate ``n`` samples; returns (q (m, 4), v (m, 3), pos (m, 3) [lat rad, lon rad, h m])
    at the ends of samples every−1, 2·every−1, … (m = n // every); ``state`` is updated in
    place to the end of the last sample. ``href`` (n,) heights [m] used when ``hold`` is 1
    (vertical channel held), ignored otherwise (free vertical channel)."""
    n = dtheta.shape[0]
    m = n // every
    q_out = np.empty((m, 4))
    v_out = np.empty((m, 3))
    p_out = np.empty((m, 3))
    qw, qx, qy, qz = state[0], state[1], state[2], state[3]
    ve, vn, vu = state[4], state[5], state[6]
    lat, lon, h = state[7], state[8], state[9]
    ptx, pty, ptz = state[10], state[11], state[12]
    pvx, pvy, pvz = state[13], state[14], state[15]
    oe, on, ou = state[16], state[17], state[18]
    have = state[19] != 0.0
    if not have:
        oe, on, ou = ve, vn, vu
    j = 0
    count = 0
    if have:
        lat_c, h_c = state[20], state[21]
    else:
        lat_c, h_c = lat, h
    sl, cl, rm_i, re_i, tl_re, grav = _earth(lat_c, h_c)
    for k in range(n):
        tx, ty, tz = dtheta[k, 0], dtheta[k, 1], dtheta[k, 2]
        ux, uy, uz = dv[k, 0], dv[k, 1], dv[k, 2]
        if not have:
            ptx, pty, ptz, pvx, pvy, pvz = tx, ty, tz, ux, uy, uz
            have = True
        # --- Earth quantities (Groves eqs. 2.105-2.106, T&W 3.87), refreshed when the position
        # has moved by more than EARTH_REFRESH_RAD / EARTH_REFRESH_M since the last evaluation
        if abs(lat - lat_c) > EARTH_REFRESH_RAD or abs(h - h_c) > EARTH_REFRESH_M:
            lat_c, h_c = lat, h
            sl, cl, rm_i, re_i, tl_re, grav = _earth(lat, h)
        # velocity extrapolated to the sample middle for Coriolis and the frame rotation
        me, mn, mu = 1.5 * ve - 0.5 * oe, 1.5 * vn - 0.5 * on, 1.5 * vu - 0.5 * ou
        wie_n, wie_u, wen_e, wen_n, wen_u = _frame_rates(me, mn, sl, cl, rm_i, re_i, tl_re)
        zx, zy, zz = wen_e * dt, (wie_n + wen_n) * dt, (wie_u + wen_u) * dt   # ζ = ω_in Δt
        gx, gy, gz = _specific_force_increment(tx, ty, tz, ux, uy, uz, ptx, pty, ptz,
                                               pvx, pvy, pvz, qw, qx, qy, qz, zx, zy, zz)
        # --- velocity: + (g − (2ω_ie + ω_en) × v) Δt   (T&W eq. 3.73, ENU)
        cor_e, cor_n, cor_u = cross(wen_e, 2.0 * wie_n + wen_n, 2.0 * wie_u + wen_u,
                                    me, mn, mu)
        oe, on, ou = ve, vn, vu
        ve = ve + gx - cor_e * dt
        vn = vn + gy - cor_n * dt
        vu = vu + gz - (grav + cor_u) * dt
        # --- position: trapezoidal velocity, radii at the sample start
        lat, lon = _position_step(lat, lon, oe, on, ve, vn, sl, cl, rm_i, re_i, dt)
        if hold:
            hn = href[k]
            vu = (hn - h) / dt
            h = hn
        else:
            h = h + 0.5 * (ou + vu) * dt
        # --- attitude
        qw, qx, qy, qz = _attitude_step(qw, qx, qy, qz, tx, ty, tz, ptx, pty, ptz, zx, zy, zz)
        ptx, pty, ptz, pvx, pvy, pvz = tx, ty, tz, ux, uy, uz
        count += 1
        if count == every and j < m:
            count = 0
            q_out[j, 0], q_out[j, 1], q_out[j, 2], q_out[j, 3] = qw, qx, qy, qz
            v_out[j, 0], v_out[j, 1], v_out[j, 2] = ve, vn, vu
            p_out[j, 0], p_out[j, 1], p_out[j, 2] = lat, lon, h
            j += 1
    state[0], state[1], state[2], state[3] = qw, qx, qy, qz
    state[4], state[5], state[6] = ve, vn, vu
    state[7], state[8], state[9] = lat, lon, h
    state[10], state[11], state[12] = ptx, pty, ptz
    state[13], state[14], state[15] = pvx, pvy, pvz
    state[16], state[17], state[18] = oe, on, ou
    state[19] = 1.0 if have else 0.0
    state[20], state[21] = lat_c, h_c
    return q_out, v_out, p_out
