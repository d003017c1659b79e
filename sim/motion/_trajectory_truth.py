"""Compiled truth of a trajectory (numba): the position, velocity and attitude at run times,
in SI (:meth:`rlgsim.sim.motion.trajectory.Trajectory.truth`) or as the dataset's
``trajectory`` rows (:meth:`~rlgsim.sim.motion.trajectory.Trajectory.truth_rows`: latitude,
longitude and the angles in degrees, the heading in [0, 360), the leg's GNSS flag) — one loop
over the samples, no NumPy pass afterwards.

The formulas are those of :meth:`~rlgsim.sim.motion.trajectory.Trajectory.states` (the NumPy
form the tests compare with): the legs' channels, the DOP853 dense position
(:func:`rlgsim.sim.motion._trajectory_kernel._position`) and q_b^n = q_z(−ψ) q_x(θ) q_y(φ).

**Walking, not searching.** A block's times are sorted, so the leg holding a time and the
DOP853 step holding its leg time are found by stepping forward from the previous sample's
(a time before the previous one searches afresh). Either way they are the binary searches'
answers — the first leg start ≥ t and the first step start ≥ τ (side "left", as
``np.searchsorted`` and scipy's ``OdeSolution``) — so the same numbers. The degrees are
``x · (180/π)`` and the heading's ``% 360`` Python's floor modulo: NumPy's ``np.degrees`` and
``%`` on float64, operation for operation (tests/test_trajectory_runs.py compares the file's
rows with the NumPy form). No ``fastmath``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rlgsim.sim.motion._trajectory_kernel import (LF_DUR, LF_T0, LF_Y0, LI_GEO, LI_LEVEL,
                                                  LI_NSEG, LI_POS, LI_SEG, POS_FIXED, W_X,
                                                  _dense_at, _qmul, _state, _state_geodetic,
                                                  first_step_from)

#: degrees per radian, as NumPy's ``np.degrees`` multiplies
R2D = 180.0 / math.pi


@njit(cache=True, nogil=True, inline="always")
def _attitude_quaternion(w):  # pragma: no cover - compiled
    """q_b^n of the Euler channels in ``w`` (heading, pitch, roll at ``W_X``)."""
    hz, hx, hy = 0.5 * w[W_X], 0.5 * w[W_X + 1], 0.5 * w[W_X + 2]
    q0, q1, q2, q3 = _qmul(math.cos(hz), 0.0, 0.0, -math.sin(hz),
                           math.cos(hx), math.sin(hx), 0.0, 0.0)
    return _qmul(q0, q1, q2, q3, math.cos(hy), 0.0, math.sin(hy), 0.0)


@njit(cache=True, nogil=True)
def states_at(t, coef, dcoef, d2coef, legs_i, legs_f, dense, earth, flags, degrees, out_p,
              out_v, out_q, out_e, out_g):  # pragma: no cover - compiled
    """The truth at run times ``t`` (k,) (a leg start belongs to the leg ending there):
    (L, λ, h) ``out_p`` (3, k), ENU velocity ``out_v`` (k, 3), q_b^n ``out_q`` (k, 4),
    heading, pitch, roll ``out_e`` (3, k) and the leg's GNSS flag (``flags`` (m,) int8)
    ``out_g`` (k,); ``degrees``: L, λ and the angles in degrees, the heading in [0, 360) (the
    dataset's rows), else radians. In a leg of constant attitude C_b^n, q_b^n and the angles
    (in degrees too) are computed once, and so is v^n where the body velocity is constant too
    (the same numbers: those channels' Horner sums are their constant terms whatever τ ≥ 0)."""
    a_axis, e2 = earth[0], earth[1]
    w = np.empty(32)
    m = legs_i.shape[0]
    c_leg = -1
    q0 = q1 = q2 = q3 = e0 = e1 = e2d = 0.0
    a = 0                                        # leg starts < t[k]
    s_leg, s_cnt, s_tau = -1, 0, 0.0             # the step walk: leg, step starts < τ, τ
    for k in range(t.size):
        tk = t[k]
        if k > 0 and tk >= t[k - 1]:             # walk forward (module docstring)
            while a < m and legs_f[a, LF_T0] < tk:
                a += 1
        else:                                    # first start >= t (side "left")
            a, b = 0, m
            while a < b:
                mid = (a + b) // 2
                if legs_f[mid, LF_T0] < tk:
                    a = mid + 1
                else:
                    b = mid
        j = min(max(a - 1, 0), m - 1)
        tau = tk - legs_f[j, LF_T0]
        held = False                             # the angles of the previous sample
        if legs_i[j, LI_GEO] == 1:
            _state_geodetic(coef, dcoef, d2coef, j, tau, w, e2, a_axis)
            p0, p1, p2 = w[W_X + 3], w[W_X + 4], w[W_X + 5]
            c_leg = -1
            q0, q1, q2, q3 = _attitude_quaternion(w)
        else:
            if j == c_leg and legs_i[j, LI_LEVEL] == 2:
                held = True                      # constant attitude and velocity: both held
            elif j == c_leg:                     # constant attitude: the velocity only
                held = True
                for ch in range(3, 6):
                    v = coef[j, ch, 5]
                    for i in range(4, -1, -1):
                        v = v * tau + coef[j, ch, i]
                    w[W_X + ch] = v
                for i in range(3):
                    w[12 + i] = (w[3 * i] * w[W_X + 3] + w[3 * i + 1] * w[W_X + 4]
                                 + w[3 * i + 2] * w[W_X + 5])
            else:
                _state(coef, dcoef, j, tau, w)
                q0, q1, q2, q3 = _attitude_quaternion(w)
                c_leg = j if legs_i[j, LI_LEVEL] != 0 else -1
            if legs_i[j, LI_POS] == POS_FIXED:
                p0, p1, p2 = legs_f[j, LF_Y0], legs_f[j, LF_Y0 + 1], legs_f[j, LF_Y0 + 2]
            else:                                # the dense position, its step walked to
                tc = tau                         # clipped to the leg, as _position
                if tc < 0.0:
                    tc = 0.0
                elif tc > legs_f[j, LF_DUR]:
                    tc = legs_f[j, LF_DUR]
                lo, ns = legs_i[j, LI_SEG], legs_i[j, LI_NSEG]
                if j == s_leg and tc >= s_tau:
                    while s_cnt < ns and dense[lo + s_cnt, 0] < tc:
                        s_cnt += 1
                else:
                    s_cnt = first_step_from(dense, lo, 0, ns, tc)
                s_leg, s_tau = j, tc
                p0, p1, p2 = _dense_at(dense, lo + min(max(s_cnt - 1, 0), ns - 1), tc)
        out_v[k, 0], out_v[k, 1], out_v[k, 2] = w[12], w[13], w[14]
        out_q[k, 0], out_q[k, 1], out_q[k, 2], out_q[k, 3] = q0, q1, q2, q3
        out_g[k] = flags[j]
        out_p[2, k] = p2
        if degrees:
            out_p[0, k], out_p[1, k] = p0 * R2D, p1 * R2D
            if not held:                         # else the same angles as the last sample's
                e0, e1, e2d = (w[W_X] * R2D) % 360.0, w[W_X + 1] * R2D, w[W_X + 2] * R2D
        else:
            out_p[0, k], out_p[1, k] = p0, p1
            if not held:
                e0, e1, e2d = w[W_X], w[W_X + 1], w[W_X + 2]
        out_e[0, k], out_e[1, k], out_e[2, k] = e0, e1, e2d
