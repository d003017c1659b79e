"""Compiled quadrature of a trajectory's sensor inputs (numba): Δθ and Δv of many sample pieces.

:meth:`rlgsim.sim.motion.trajectory.Trajectory.increments` evaluates ω_ib^b and f^b at four
Gauss–Legendre nodes per sub-interval — 240 000 evaluations per 600-s block at 100 Hz, each a
dozen 3×3 products; in NumPy the (k, 3, 3) temporaries cost ~2 s per block, here ~50 ms. The
formulas are those of the module docstring of :mod:`rlgsim.sim.motion.trajectory` (and of its
NumPy :meth:`~rlgsim.sim.motion.trajectory.Trajectory.rates`, which tests/test_trajectory.py
compares with this kernel), with one difference: the geodetic position at a node is the cubic
Hermite interpolant of the positions at the ends of its sub-interval (the DOP853 solution) and
their exact rates (L̇ = v_N/(R_M + h), λ̇ = v_E/((R_N + h) cos L), ḣ = v_U). Its error on a
sub-interval of length Δ ≤ 0.02 s is ≤ Δ⁴/384 · |p⁗| ≤ 4e-10 s⁴ · |p⁗|: for a vertical jerk rate
of 1 m/s⁴, 4e-10 m, which moves γ by 1e-15 m/s² (1e-16 of γ) and the Earth and transport rates
by less — at the float64 resolution of the inputs. The position enters only through those slowly varying terms.

The Earth model's constants come from :mod:`rlgsim.ground.earth` (passed in, never re-typed).
No ``fastmath``: the same IEEE operations in the same order for a piece whatever block holds it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _state(cf, dcf, tau, out, x, xd):  # pragma: no cover - compiled
    """Channels of one leg at leg time ``tau`` → ``out``: C_b^n (0..8 row-major), ω_nb^b
    (9..11), v^n (12..14), v̇^n (15..17); ``x``, ``xd`` (6,) work arrays."""
    for c in range(6):
        v = cf[c, 5]
        for k in range(4, -1, -1):
            v = v * tau + cf[c, k]
        x[c] = v
        d = dcf[c, 4]
        for k in range(3, -1, -1):
            d = d * tau + dcf[c, k]
        xd[c] = d
    cp, sp = math.cos(x[0]), math.sin(x[0])
    ct, st = math.cos(x[1]), math.sin(x[1])
    cr, sr = math.cos(x[2]), math.sin(x[2])
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
    y0 = xd[1]
    y1 = st * (-xd[0])
    y2 = ct * (-xd[0])
    w0 = cr * y0 - sr * y2
    w1 = y1 + xd[2]
    w2 = sr * y0 + cr * y2
    out[9], out[10], out[11] = w0, w1, w2
    vb0, vb1, vb2 = x[3], x[4], x[5]
    a0 = xd[3] + (w1 * vb2 - w2 * vb1)
    a1 = xd[4] + (w2 * vb0 - w0 * vb2)
    a2 = xd[5] + (w0 * vb1 - w1 * vb0)
    for i in range(3):
        out[12 + i] = out[3 * i] * vb0 + out[3 * i + 1] * vb1 + out[3 * i + 2] * vb2
        out[15 + i] = out[3 * i] * a0 + out[3 * i + 1] * a1 + out[3 * i + 2] * a2


@njit(cache=True, nogil=True)
def _state_geodetic(cf, dcf, d2cf, tau, out, x, xd, e2, a_axis):  # pragma: no cover
    """:func:`_state` of a leg whose channels 3-5 are the geodetic position (L, λ, h): the
    attitude part as there, v^n and v̇^n from the position's rates (the NumPy
    ``Trajectory._table_velocity``), and L, h into out[18], out[19]."""
    _state(cf, dcf, tau, out, x, xd)           # attitude, ω_nb^b; channels and their rates
    xdd = np.empty(3)
    for c in range(3):
        v = d2cf[3 + c, 3]
        for k in range(2, -1, -1):
            v = v * tau + d2cf[3 + c, k]
        xdd[c] = v
    lat, h = x[3], x[5]
    ld, od, hd = xd[3], xd[4], xd[5]
    sl, cl = math.sin(lat), math.cos(lat)
    w = 1.0 - e2 * sl * sl
    rn = a_axis / math.sqrt(w)
    rm = rn * (1.0 - e2) / w
    drn = rn * e2 * sl * cl / w
    drm = 3.0 * rm * e2 * sl * cl / w
    out[12] = (rn + h) * cl * od
    out[13] = (rm + h) * ld
    out[14] = hd
    out[15] = (drn * ld + hd) * cl * od - (rn + h) * sl * ld * od + (rn + h) * cl * xdd[1]
    out[16] = (drm * ld + hd) * ld + (rm + h) * xdd[0]
    out[17] = xdd[2]
    out[18] = lat
    out[19] = h


@njit(cache=True, nogil=True)
def _position_rate(p0, p2, ve, vn, vu, e2, a_axis):  # pragma: no cover - compiled
    """(L̇, λ̇, ḣ) at latitude ``p0`` [rad], height ``p2`` [m] and ENU velocity."""
    s = math.sin(p0)
    w = 1.0 - e2 * s * s
    rn = a_axis / math.sqrt(w)
    rm = rn * (1.0 - e2) / w
    return vn / (rm + p2), ve / ((rn + p2) * math.cos(p0)), vu


@njit(cache=True, nogil=True)
def piece_integrals(a, dur, sub, leg, t0, coef, dcoef, d2coef, geodetic, pos, nodes, weights,
                    earth, out_w, out_f):  # pragma: no cover - compiled
    """∫ω_ib^b and ∫f^b over pieces [a_p, a_p + dur_p) → ``out_w``, ``out_f`` (P, 3).

    ``sub`` equal sub-intervals per piece, Gauss–Legendre ``nodes``/``weights`` on [−1, 1];
    ``leg`` (P,) the leg of each piece, ``t0`` (m,) the legs' starts, ``coef`` (m, 6, 6) and
    ``dcoef`` (m, 6, 5), ``d2coef`` (m, 6, 4) their channel polynomials and derivatives;
    ``geodetic`` (m,) 1 where a leg's channels 3-5 are the position itself (then ``pos`` is
    not read: the position at a node is the leg's polynomial); ``pos`` (P, sub + 1, 3)
    the geodetic (L, λ, h) at the ends of each piece's sub-intervals; ``earth`` = (a, e², Ω, γ_e, k, f, m) of
    WGS-84 (:mod:`rlgsim.ground.earth`)."""
    a_axis, e2, omega, ge, kk, ff, mm = (earth[0], earth[1], earth[2], earth[3], earth[4],
                                         earth[5], earth[6])
    st = np.empty(20)
    x = np.empty(6)
    xd = np.empty(6)
    q = nodes.size
    for p in range(a.size):
        j = leg[p]
        cf, dcf = coef[j], dcoef[j]
        ta = a[p] - t0[j]
        d = dur[p]
        h = d / sub
        sw0 = sw1 = sw2 = 0.0
        sf0 = sf1 = sf2 = 0.0
        geo = geodetic[j] == 1
        d2cf = d2coef[j]
        for s in range(sub):
            # cubic Hermite of the position over this sub-interval from its ends
            t_lo = ta + h * s
            if geo:
                ra0 = ra1 = ra2 = rb0 = rb1 = rb2 = 0.0
            else:
                _state(cf, dcf, t_lo, st, x, xd)
                ra0, ra1, ra2 = _position_rate(pos[p, s, 0], pos[p, s, 2], st[12], st[13],
                                               st[14], e2, a_axis)
                _state(cf, dcf, t_lo + h, st, x, xd)
                rb0, rb1, rb2 = _position_rate(pos[p, s + 1, 0], pos[p, s + 1, 2], st[12],
                                               st[13], st[14], e2, a_axis)
            for i in range(q):
                off = 0.5 * h * (nodes[i] + 1.0)
                if geo:
                    _state_geodetic(cf, dcf, d2cf, t_lo + off, st, x, xd, e2, a_axis)
                    lat, hgt = st[18], st[19]
                else:
                    _state(cf, dcf, t_lo + off, st, x, xd)
                    u = off / h
                    h00 = (1.0 + 2.0 * u) * (1.0 - u) * (1.0 - u)
                    h10 = u * (1.0 - u) * (1.0 - u)
                    h01 = u * u * (3.0 - 2.0 * u)
                    h11 = u * u * (u - 1.0)
                    lat = (h00 * pos[p, s, 0] + h10 * h * ra0 + h01 * pos[p, s + 1, 0]
                           + h11 * h * rb0)
                    hgt = (h00 * pos[p, s, 2] + h10 * h * ra2 + h01 * pos[p, s + 1, 2]
                           + h11 * h * rb2)
                sl, cl = math.sin(lat), math.cos(lat)
                w = 1.0 - e2 * sl * sl
                rn = a_axis / math.sqrt(w)
                rm = rn * (1.0 - e2) / w
                ve, vn, vu = st[12], st[13], st[14]
                # Earth rate, transport rate (ENU), normal gravity (ground/earth.py formulas)
                wie1, wie2 = omega * cl, omega * sl
                wen0 = -vn / (rm + hgt)
                wen1 = ve / (rn + hgt)
                wen2 = ve * (sl / cl) / (rn + hgt)
                s2 = sl * sl
                g0 = ge * (1.0 + kk * s2) / math.sqrt(1.0 - e2 * s2)
                gam = g0 * (1.0 - 2.0 / a_axis * (1.0 + ff + mm - 2.0 * ff * s2) * hgt
                            + 3.0 * hgt * hgt / (a_axis * a_axis))
                c0 = wen0
                c1 = 2.0 * wie1 + wen1
                c2 = 2.0 * wie2 + wen2
                fn0 = st[15] + (c1 * vu - c2 * vn)
                fn1 = st[16] + (c2 * ve - c0 * vu)
                fn2 = st[17] + (c0 * vn - c1 * ve) + gam
                i0, i1, i2 = wen0, wie1 + wen1, wie2 + wen2
                wt = weights[i] * 0.5 * h
                # C_n^b = Cᵀ: column k of C dotted with the ENU vector
                sw0 += wt * (st[9] + st[0] * i0 + st[3] * i1 + st[6] * i2)
                sw1 += wt * (st[10] + st[1] * i0 + st[4] * i1 + st[7] * i2)
                sw2 += wt * (st[11] + st[2] * i0 + st[5] * i1 + st[8] * i2)
                sf0 += wt * (st[0] * fn0 + st[3] * fn1 + st[6] * fn2)
                sf1 += wt * (st[1] * fn0 + st[4] * fn1 + st[7] * fn2)
                sf2 += wt * (st[2] * fn0 + st[5] * fn1 + st[8] * fn2)
        out_w[p, 0], out_w[p, 1], out_w[p, 2] = sw0, sw1, sw2
        out_f[p, 0], out_f[p, 1], out_f[p, 2] = sf0, sf1, sf2


@njit(cache=True, nogil=True)
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):  # pragma: no cover - compiled
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True, nogil=True)
def sample_states(tau, leg, coef, dcoef, d2coef, geodetic, earth, out_v, out_q, out_e,
                  out_p):  # pragma: no cover - compiled
    """The truth at leg times ``tau`` (k,) of legs ``leg`` (k,): ENU velocity ``out_v`` (k, 3),
    attitude quaternion q_b^n = q_z(−ψ) ⊗ q_x(θ) ⊗ q_y(φ) ``out_q`` (k, 4) (Hamilton, scalar
    first), heading/pitch/roll ``out_e`` (k, 3) [rad] and, for geodetic legs, (L, λ, h) into
    ``out_p`` (k, 3) (left as it is for body-velocity legs, whose position is integrated)."""
    a_axis, e2 = earth[0], earth[1]
    st = np.empty(20)
    x = np.empty(6)
    xd = np.empty(6)
    for k in range(tau.size):
        j = leg[k]
        if geodetic[j] == 1:
            _state_geodetic(coef[j], dcoef[j], d2coef[j], tau[k], st, x, xd, e2, a_axis)
            out_p[k, 0], out_p[k, 1], out_p[k, 2] = x[3], x[4], x[5]
        else:
            _state(coef[j], dcoef[j], tau[k], st, x, xd)
        out_v[k, 0], out_v[k, 1], out_v[k, 2] = st[12], st[13], st[14]
        out_e[k, 0], out_e[k, 1], out_e[k, 2] = x[0], x[1], x[2]
        hz, hx, hy = 0.5 * x[0], 0.5 * x[1], 0.5 * x[2]
        q0, q1, q2, q3 = _qmul(math.cos(hz), 0.0, 0.0, -math.sin(hz),
                               math.cos(hx), math.sin(hx), 0.0, 0.0)
        q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, math.cos(hy), 0.0, math.sin(hy), 0.0)
        out_q[k, 0], out_q[k, 1], out_q[k, 2], out_q[k, 3] = q0, q1, q2, q3
