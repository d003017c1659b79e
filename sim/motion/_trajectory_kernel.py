"""Compiled formulas of a trajectory at one time (numba): the legs' states, the position from
the DOP853 dense output, the Earth's terms, and the range check's peaks over a route
(:func:`peak_inputs`); the block loops that use them are in
:mod:`rlgsim.sim.motion._trajectory_block`.

The formulas are those of the module docstring of :mod:`rlgsim.sim.motion.trajectory` (and of
its NumPy :meth:`~rlgsim.sim.motion.trajectory.Trajectory.rates`, which tests/test_trajectory.py
compares with the increments). Where a leg's attitude turns, the geodetic position at a
quadrature node is the cubic Hermite interpolant of the positions at the ends of its
sub-interval (the DOP853 solution) and their exact rates (L̇ = v_N/(R_M + h),
λ̇ = v_E/((R_N + h) cos L), ḣ = v_U). Its error on a sub-interval of length Δ ≤ 0.02 s is
≤ Δ⁴/384 · |p⁗| ≤ 4e-10 s⁴ · |p⁗|: for a vertical jerk rate of 1 m/s⁴, 4e-10 m, which moves γ
by 1e-15 m/s² (1e-16 of γ) and the Earth and transport rates by less — at the float64
resolution of the inputs. The position enters only through those slowly varying terms.

**Layout** (few arrays per call: numba counts the references of every array handed to a
function that it does not inline, ~10 ns each): a leg's integers ``legs_i`` (m, 6) = (position
kind, first dense step, number of steps, quadrature level, standing still, geodetic), its floats
``legs_f`` (m, 5) = (start [s], duration [s], start L, λ [rad], h [m]); the small helpers are
inlined where they are called (``inline="always"``: no such bookkeeping; the larger ones not, to
keep the first compilation short); the dense steps
``dense`` (S, 26) = (t_old, h, the seven rows F_0 … F_6 of three components, y_old); one work
array ``w`` (32,) = the state (0..19), the channels (20..25) and their rates (26..31).

The Earth model's constants come from :mod:`rlgsim.ground.earth` (passed in, never re-typed).
numba's on-disk cache keys each kernel on its own file: a change here must also edit the
kernels' files that compile these helpers in (``HELPERS_REVISION`` of
:mod:`~rlgsim.sim.motion._trajectory_block`; _trajectory_cheb.py, _trajectory_truth.py,
_trajectory_route.py),
or a warm cache keeps the old helpers.
No ``fastmath``: the same IEEE operations in the same order for a piece whatever block holds it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: ``legs_i`` columns
LI_POS, LI_SEG, LI_NSEG, LI_LEVEL, LI_STILL, LI_GEO = range(6)
#: ``legs_f`` columns
LF_T0, LF_DUR, LF_Y0 = 0, 1, 2
#: how a leg's position is found: the DOP853 dense output, the leg's own channels (a table of
#: positions), or its start (a leg of no duration)
POS_DENSE, POS_GEODETIC, POS_FIXED = 0, 1, 2
#: offsets in the work array: state, channels, channel rates
W_X, W_XD = 20, 26


@njit(cache=True, nogil=True)
def _state(coef, dcoef, j, tau, w):  # pragma: no cover - compiled
    """Channels of leg ``j`` at leg time ``tau`` → ``w``: C_b^n (0..8 row-major), ω_nb^b
    (9..11), v^n (12..14), v̇^n (15..17), the channels (20..25) and their rates (26..31)."""
    for c in range(6):
        v = coef[j, c, 5]
        for k in range(4, -1, -1):
            v = v * tau + coef[j, c, k]
        w[W_X + c] = v
        d = dcoef[j, c, 4]
        for k in range(3, -1, -1):
            d = d * tau + dcoef[j, c, k]
        w[W_XD + c] = d
    _attitude_velocity(w)


@njit(cache=True, nogil=True)
def _attitude_velocity(out):  # pragma: no cover - compiled
    """C_b^n, ω_nb^b, v^n, v̇^n (``out[0:18]``) from the channels and rates in ``out``."""
    x0, x1, x2 = out[W_X], out[W_X + 1], out[W_X + 2]
    xd0, xd1, xd2 = out[W_XD], out[W_XD + 1], out[W_XD + 2]
    cp, sp = math.cos(x0), math.sin(x0)
    ct, st = math.cos(x1), math.sin(x1)
    cr, sr = math.cos(x2), math.sin(x2)
    # C = Rz(−ψ) Rx(θ) Ry(φ)
    # Rx Ry = [[cr, 0, sr], [st sr, ct, −st cr], [−ct sr, st, ct cr]]
    m00, m01, m02 = cr, 0.0, sr
    m10, m11, m12 = st * sr, ct, -st * cr
    m20, m21, m22 = -ct * sr, st, ct * cr
    out[0] = cp * m00 + sp * m10
    out[1] = cp * m01 + sp * m11
    out[2] = cp * m02 + sp * m12
    out[3] = -sp * m00 + cp * m10
    out[4] = -sp * m01 + cp * m11
    out[5] = -sp * m02 + cp * m12
    out[6] = m20
    out[7] = m21
    out[8] = m22
    # ω_nb^b = Ryᵀ [Rxᵀ (0, 0, −ψ̇) + (θ̇, 0, 0)] + (0, φ̇, 0)
    y0 = xd1
    y1 = st * (-xd0)
    y2 = ct * (-xd0)
    w0 = cr * y0 - sr * y2
    w1 = y1 + xd2
    w2 = sr * y0 + cr * y2
    out[9], out[10], out[11] = w0, w1, w2
    vb0, vb1, vb2 = out[W_X + 3], out[W_X + 4], out[W_X + 5]
    a0 = out[W_XD + 3] + (w1 * vb2 - w2 * vb1)
    a1 = out[W_XD + 4] + (w2 * vb0 - w0 * vb2)
    a2 = out[W_XD + 5] + (w0 * vb1 - w1 * vb0)
    for i in range(3):
        out[12 + i] = out[3 * i] * vb0 + out[3 * i + 1] * vb1 + out[3 * i + 2] * vb2
        out[15 + i] = out[3 * i] * a0 + out[3 * i + 1] * a1 + out[3 * i + 2] * a2


@njit(cache=True, nogil=True)
def _state_geodetic(coef, dcoef, d2coef, j, tau, w, e2, a_axis):  # pragma: no cover
    """:func:`_state` of a leg whose channels 3-5 are the geodetic position (L, λ, h): the
    attitude part as there, v^n and v̇^n from the position's rates (the NumPy
    ``Trajectory._table_velocity``), and L, h into w[18], w[19]."""
    _state(coef, dcoef, j, tau, w)             # attitude, ω_nb^b; channels and their rates
    xdd0 = xdd1 = xdd2 = 0.0
    for c in range(3):
        v = d2coef[j, 3 + c, 3]
        for k in range(2, -1, -1):
            v = v * tau + d2coef[j, 3 + c, k]
        if c == 0:
            xdd0 = v
        elif c == 1:
            xdd1 = v
        else:
            xdd2 = v
    lat, h = w[W_X + 3], w[W_X + 5]
    ld, od, hd = w[W_XD + 3], w[W_XD + 4], w[W_XD + 5]
    sl, cl = math.sin(lat), math.cos(lat)
    wgt = 1.0 - e2 * sl * sl
    rn = a_axis / math.sqrt(wgt)
    rm = rn * (1.0 - e2) / wgt
    drn = rn * e2 * sl * cl / wgt
    drm = 3.0 * rm * e2 * sl * cl / wgt
    w[12] = (rn + h) * cl * od
    w[13] = (rm + h) * ld
    w[14] = hd
    w[15] = (drn * ld + hd) * cl * od - (rn + h) * sl * ld * od + (rn + h) * cl * xdd1
    w[16] = (drm * ld + hd) * ld + (rm + h) * xdd0
    w[17] = xdd2
    w[18] = lat
    w[19] = h


@njit(cache=True, nogil=True, inline="always")
def _position_rate(p0, p2, ve, vn, vu, e2, a_axis):  # pragma: no cover - compiled
    """(L̇, λ̇, ḣ) at latitude ``p0`` [rad], height ``p2`` [m] and ENU velocity."""
    s = math.sin(p0)
    w = 1.0 - e2 * s * s
    rn = a_axis / math.sqrt(w)
    rm = rn * (1.0 - e2) / w
    return vn / (rm + p2), ve / ((rn + p2) * math.cos(p0)), vu


@njit(cache=True, nogil=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):  # pragma: no cover - compiled
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True, nogil=True, inline="always")
def _position(legs_i, legs_f, dense, j, tau):  # pragma: no cover - compiled
    """(L, λ, h) [rad, rad, m] of leg ``j`` (dense or fixed) at leg time ``tau``.

    scipy's DOP853 dense output of a step from ``t_old`` over ``h`` is, with
    x = (τ − t_old)/h, y(τ) = y_old + ((…((F_6·x + F_5)(1 − x) + F_4)x + …) (scipy.integrate's
    ``Dop853DenseOutput``), evaluated here in the same order of operations, so the same
    numbers; the step is the first whose end is ≥ τ (``OdeSolution``'s ``searchsorted``,
    side "left"), τ clipped to the leg."""
    if legs_i[j, LI_POS] == POS_FIXED:
        return legs_f[j, LF_Y0], legs_f[j, LF_Y0 + 1], legs_f[j, LF_Y0 + 2]
    if tau < 0.0:
        tau = 0.0
    elif tau > legs_f[j, LF_DUR]:
        tau = legs_f[j, LF_DUR]
    lo, ns = legs_i[j, LI_SEG], legs_i[j, LI_NSEG]
    a = first_step_from(dense, lo, 0, ns, tau)
    return _dense_at(dense, lo + min(max(a - 1, 0), ns - 1), tau)


@njit(cache=True, nogil=True, inline="always")
def first_step_from(dense, lo, a, b, tau):  # pragma: no cover - compiled
    """The first of a leg's steps ``a`` … ``b − 1`` (rows ``lo + i`` of ``dense``) that starts at or
    after ``tau`` [s], ``b`` if none does (bisection, as numpy's searchsorted side "left")."""
    while a < b:
        mid = (a + b) // 2
        if dense[lo + mid, 0] < tau:
            a = mid + 1
        else:
            b = mid
    return a


@njit(cache=True, nogil=True, inline="always")
def chunk_bounds(dur, t_ch, tau):  # pragma: no cover - compiled
    """Start and end [s of leg time] of the fitted chunk that holds leg time ``tau`` on a leg of
    ``dur`` seconds cut into chunks of ``t_ch``: chunk i holds i T ≤ τ < (i + 1) T, the last one
    runs to the leg's end — a pure function of τ (the division's guess made exact to the rule)."""
    n_ch = max(1, int(dur / t_ch))
    i = min(int(tau / t_ch), n_ch - 1)
    while i > 0 and tau < i * t_ch:
        i -= 1
    while i < n_ch - 1 and tau >= (i + 1) * t_ch:
        i += 1
    return i * t_ch, (dur if i == n_ch - 1 else (i + 1) * t_ch)


@njit(cache=True, nogil=True, inline="always")
def _dense_at(dense, s, tau):  # pragma: no cover - compiled
    """(L, λ, h) of DOP853 step ``s`` of ``dense`` at leg time ``tau`` (:func:`_position`)."""
    x = (tau - dense[s, 0]) / dense[s, 1]
    y0 = y1 = y2 = 0.0
    for i in range(7):
        r = 2 + 3 * (6 - i)
        y0 += dense[s, r]
        y1 += dense[s, r + 1]
        y2 += dense[s, r + 2]
        if i % 2 == 0:
            y0 *= x
            y1 *= x
            y2 *= x
        else:
            y0 *= 1 - x
            y1 *= 1 - x
            y2 *= 1 - x
    return y0 + dense[s, 23], y1 + dense[s, 24], y2 + dense[s, 25]


@njit(cache=True, nogil=True, inline="always")
def _earth_terms(lat, hgt, ve, vn, vu, earth):  # pragma: no cover - compiled
    """ω_ie^n + ω_en^n, (2ω_ie^n + ω_en^n) × v^n and γ (ENU) at latitude ``lat`` [rad],
    height ``hgt`` [m] and ground velocity (ve, vn, vu) [m/s] (the formulas of
    rlgsim.ground.earth): (ω0, ω1, ω2, c0, c1, c2, γ)."""
    a_axis, e2, omega, ge, kk, ff, mm = (earth[0], earth[1], earth[2], earth[3], earth[4],
                                         earth[5], earth[6])
    sl, cl = math.sin(lat), math.cos(lat)
    w = 1.0 - e2 * sl * sl
    rn = a_axis / math.sqrt(w)
    rm = rn * (1.0 - e2) / w
    wie1, wie2 = omega * cl, omega * sl
    wen0 = -vn / (rm + hgt)
    wen1 = ve / (rn + hgt)
    wen2 = ve * (sl / cl) / (rn + hgt)
    s2 = sl * sl
    g0 = ge * (1.0 + kk * s2) / math.sqrt(1.0 - e2 * s2)
    gam = g0 * (1.0 - 2.0 / a_axis * (1.0 + ff + mm - 2.0 * ff * s2) * hgt
                + 3.0 * hgt * hgt / (a_axis * a_axis))
    c1 = 2.0 * wie1 + wen1
    c2 = 2.0 * wie2 + wen2
    return (wen0, wie1 + wen1, wie2 + wen2, c1 * vu - c2 * vn, c2 * ve - wen0 * vu,
            wen0 * vn - c1 * ve, gam)


@njit(cache=True, nogil=True)
def position_rate_at(coef, dcoef, j, tau, lat, hgt, e2, a_axis):  # pragma: no cover - compiled
    """(L̇, λ̇, ḣ) [rad/s, rad/s, m/s] of leg ``j`` (body-velocity channels) at leg time
    ``tau``, latitude ``lat`` [rad] and height ``hgt`` [m]: the right-hand side of the
    position's DOP853 integration (Titterton & Weston eqs. 3.85–3.87, ENU)."""
    w = np.empty(32)
    _state(coef, dcoef, j, tau, w)
    return _position_rate(lat, hgt, w[12], w[13], w[14], e2, a_axis)


@njit(cache=True, nogil=True)
def peak_inputs(coef, dcoef, d2coef, legs_i, legs_f, dense, earth, step_s, skip,
                out):  # pragma: no cover - compiled
    """Largest |ω_ib^b| and |f^b| component and the time of the largest rate → ``out`` (3,),
    on each leg's grid of :meth:`rlgsim.sim.motion.trajectory.Trajectory.peak_inputs` (m =
    max(3, ⌈duration/``step_s``⌉ + 1), made odd, points k·duration/(m − 1), the last one the
    duration — the middle, where a smooth leg's rates peak, always on it):
    the sensor inputs of :func:`_piece_hermite`'s formulas at each point, the first largest;
    the legs whose entry of ``skip`` (one per leg) is ≠ 0 left out."""
    a_axis, e2 = earth[0], earth[1]
    w = np.empty(32)
    best_w = best_f = at = 0.0
    for j in range(legs_i.shape[0]):
        if skip[j] != 0:
            continue
        dur = legs_f[j, LF_DUR]
        m = max(3, int(np.ceil(dur / step_s)) + 1)
        m += 1 - m % 2                          # odd: the leg's middle (a smooth leg's peak)
        step = dur / (m - 1)
        for k in range(m):
            tau = dur if k == m - 1 else float(k) * step
            if legs_i[j, LI_GEO] == 1:
                _state_geodetic(coef, dcoef, d2coef, j, tau, w, e2, a_axis)
                lat, hgt = w[18], w[19]
            else:
                _state(coef, dcoef, j, tau, w)
                lat, lon, hgt = _position(legs_i, legs_f, dense, j, tau)
            i0, i1, i2, e0, e1, e2f, gam = _earth_terms(lat, hgt, w[12], w[13], w[14], earth)
            fn0, fn1, fn2 = w[15] + e0, w[16] + e1, w[17] + e2f + gam
            mw = mf = 0.0
            for r in range(3):
                mw = max(mw, abs(w[9 + r] + w[r] * i0 + w[3 + r] * i1 + w[6 + r] * i2))
                mf = max(mf, abs(w[r] * fn0 + w[3 + r] * fn1 + w[6 + r] * fn2))
            if mw > best_w:
                best_w, at = mw, legs_f[j, LF_T0] + tau
            best_f = max(best_f, mf)
    out[0], out[1], out[2] = best_w, best_f, at
