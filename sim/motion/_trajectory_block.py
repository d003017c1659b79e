"""Compiled block of a trajectory (numba): the increments of ``n`` samples (their truth
states: :mod:`rlgsim.sim.motion._trajectory_truth`).

:meth:`rlgsim.sim.motion.trajectory.Trajectory.increments` hands a whole block to this
kernel: the sample grid, its split at the leg starts, the standing-still runs, the geodetic positions from the legs' DOP853 dense
output and the quadrature of :mod:`rlgsim.sim.motion._trajectory_kernel` — one compiled loop
over the samples, no per-sample NumPy temporaries (the NumPy form of the same steps cost ~15×
the quadrature itself).

The positions come from the legs' DOP853 dense output (:func:`rlgsim.sim.motion._trajectory_kernel._position`: the
interpolant of scipy's ``Dop853DenseOutput``, its operations in its order).

**Quadrature.** Per piece (a sample, or the part of one inside a leg), on sub-intervals of
≤ 0.02 s:

* a leg of **constant attitude** (heading, pitch, roll constant: holds, straight accelerations;
  a moving hold's whole samples: the next item):
  C_b^n is one matrix, ω_nb^b = 0, v^n = C_b^n v^b(τ) with v^b a polynomial of degree ≤ 5, so
  the integrands are C_n^b times (ω_ie^n + ω_en^n) and v̇^n + (2ω_ie^n + ω_en^n) × v^n + (0, 0, γ),
  summed in ENU and turned into the body once per piece. m-point Gauss–Legendre over Δ errs by
  Δ^(2m+1) (m!)⁴ / ((2m+1) ((2m)!)³) |F^(2m)| (Abramowitz & Stegun 25.4.30). With the velocity
  changing, m = 3 (:data:`NODES_CHANGING`) integrates v̇^n and the Coriolis term (degree ≤ 5)
  exactly; the transport-rate term ~ v²/R is of degree 10 with |F⁽⁶⁾| ≲ 20 |v⁽³⁾|²/R, a
  relative error ≲ 1e-20 at Δ = 0.02 s for jerks up to 100 m/s³. Holding the velocity, the
  integrands vary only with the position (time scale R/v ≥ 6000 s below 1 km/s), and m = 2
  (:data:`NODES_HOLDING`) errs by ≲ Δ⁵/4320 |F| (v/R)⁴ ~ 1e-28 |F|. The position at each node
  is the dense output itself.
* a leg of **constant attitude and velocity that moves**: a whole sample is the exact integral
  of a **fitted chunk** (:func:`_refit`, :func:`_fitted_mean`): the leg is cut into chunks of
  T seconds from its start (``chunk``, set by :func:`rlgsim.sim.motion.trajectory._chunk_lengths`: min(10 s,
  1e-3 τ), τ the time the integrands' nearest singularity in L or h is away at the leg's
  speed); the body-frame integrands at 6 Chebyshev points of the chunk are interpolated by a
  quintic (:func:`_chunk_fit`) whose mean over the sample is exact (:func:`_mean_coefficients`).
  Lagrange's remainder with Cauchy's estimate |F⁽⁶⁾| ≤ 6!|F|/τ⁶ bounds the interpolant's error
  by 2(T/4τ)⁶|F| ≈ 5e-22 |F| (≤ 2e-20 |F| a half sample past the chunk's end) —
  docs/trajectories.md. Six evaluations serve a chunk's ~1000 samples instead of two each.
* a body-frame leg that turns or accelerates, where a chunk holds ≥ 4 samples: a whole sample
  is the exact mean of a **Chebyshev chunk**'s degree-11 interpolant
  (:mod:`rlgsim.sim.motion._trajectory_cheb`: bounds and rounding there);
* every other leg: 4-point Gauss–Legendre with the cubic Hermite position of
  :mod:`rlgsim.sim.motion._trajectory_kernel` (its error bounds there), operation for
  operation as that module's quadrature was written.

Either way the increments are the exact integrals to float64 rounding (tests/test_trajectory.py
checks them against 10-point Gauss–Legendre on 4 sub-intervals of the NumPy formulas).

No ``fastmath``: the same IEEE operations in the same order for a sample whatever block holds
it (tests/test_trajectory.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rlgsim.sim.motion._trajectory_cheb import NODES as CHEB_NODES
from rlgsim.sim.motion._trajectory_cheb import cheb_mean, cheb_refit
from rlgsim.sim.motion._trajectory_kernel import (LF_DUR, LF_T0, LI_GEO, LI_LEVEL, LI_STILL,
                                                  _earth_terms, _position, _position_rate,
                                                  _state, _state_geodetic, chunk_bounds)

#: numba's on-disk cache keys each kernel on its own file only, yet the kernels here compile
#: in helpers of _trajectory_kernel and _trajectory_cheb: a change to those must edit this
#: line too, or a checkout with a warm cache keeps running the old helpers
HELPERS_REVISION = "2026-11-27: cheb_fit no longer stores the unused half-width (_trajectory_cheb)"

#: Gauss–Legendre points per sub-interval of a leg whose attitude turns (with the Hermite
#: position), of one of constant attitude whose velocity changes, and of one holding its
#: velocity too (module docstring): the quadrature levels 0, 1, 2
NODES_TURNING, NODES_CHANGING, NODES_HOLDING = 4, 3, 2
POINTS = (NODES_TURNING, NODES_CHANGING, NODES_HOLDING)
#: points of the fitted chunks of a leg holding its attitude and velocity (module docstring)
#: and the one whose integrands the others' deviations are taken from
FIT_NODES, FIT_REF = 6, 2


@njit(cache=True, nogil=True)
def _piece_hermite(coef, dcoef, d2coef, legs_i, j, ta, d, sub, pos, quads, earth, w,
                   res):  # pragma: no cover - compiled
    """∫ω_ib^b, ∫f^b over leg time [ta, ta + d) of leg ``j`` → res[0:6]: ``sub``
    sub-intervals, 4-point Gauss–Legendre (``quads[0]``), the cubic Hermite position from
    ``pos`` (sub + 1, 3) at their ends."""
    a_axis, e2 = earth[0], earth[1]
    geo = legs_i[j, LI_GEO] == 1
    h = d / sub
    sw0 = sw1 = sw2 = 0.0
    sf0 = sf1 = sf2 = 0.0
    for s in range(sub):
        t_lo = ta + h * s
        if geo:
            ra0 = ra2 = rb0 = rb2 = 0.0
        else:
            _state(coef, dcoef, j, t_lo, w)
            ra0, ra1, ra2 = _position_rate(pos[s, 0], pos[s, 2], w[12], w[13], w[14], e2,
                                           a_axis)
            _state(coef, dcoef, j, t_lo + h, w)
            rb0, rb1, rb2 = _position_rate(pos[s + 1, 0], pos[s + 1, 2], w[12], w[13], w[14],
                                           e2, a_axis)
        for i in range(NODES_TURNING):
            off = 0.5 * h * (quads[0, 0, i] + 1.0)
            if geo:
                _state_geodetic(coef, dcoef, d2coef, j, t_lo + off, w, e2, a_axis)
                lat, hgt = w[18], w[19]
            else:
                _state(coef, dcoef, j, t_lo + off, w)
                u = off / h
                h00 = (1.0 + 2.0 * u) * (1.0 - u) * (1.0 - u)
                h10 = u * (1.0 - u) * (1.0 - u)
                h01 = u * u * (3.0 - 2.0 * u)
                h11 = u * u * (u - 1.0)
                lat = h00 * pos[s, 0] + h10 * h * ra0 + h01 * pos[s + 1, 0] + h11 * h * rb0
                hgt = h00 * pos[s, 2] + h10 * h * ra2 + h01 * pos[s + 1, 2] + h11 * h * rb2
            i0, i1, i2, e0, e1, e2f, gam = _earth_terms(lat, hgt, w[12], w[13], w[14], earth)
            fn0, fn1, fn2 = w[15] + e0, w[16] + e1, w[17] + e2f + gam
            wt = quads[0, 1, i] * 0.5 * h
            sw0 += wt * (w[9] + w[0] * i0 + w[3] * i1 + w[6] * i2)
            sw1 += wt * (w[10] + w[1] * i0 + w[4] * i1 + w[7] * i2)
            sw2 += wt * (w[11] + w[2] * i0 + w[5] * i1 + w[8] * i2)
            sf0 += wt * (w[0] * fn0 + w[3] * fn1 + w[6] * fn2)
            sf1 += wt * (w[1] * fn0 + w[4] * fn1 + w[7] * fn2)
            sf2 += wt * (w[2] * fn0 + w[5] * fn1 + w[8] * fn2)
    res[0], res[1], res[2], res[3], res[4], res[5] = sw0, sw1, sw2, sf0, sf1, sf2


@njit(cache=True, nogil=True, inline="always")
def _piece_level(coef, dcoef, legs_i, legs_f, dense, j, ta, d, sub, c, quads, level, earth,
                 res):  # pragma: no cover - compiled
    """∫ω_ib^b, ∫f^b over leg time [ta, ta + d) of leg ``j`` of constant attitude C_b^n =
    ``c`` (row-major, 9) → res[0:6]: ``sub`` sub-intervals, Gauss–Legendre of quadrature level
    ``level`` (``quads[level]``: nodes, weights), the position from the dense output at each node, the sums in ENU turned into
    the body at the end."""
    h = d / sub
    sw0 = sw1 = sw2 = 0.0
    sf0 = sf1 = sf2 = 0.0
    for s in range(sub):
        t_lo = ta + h * s
        for i in range(POINTS[level]):
            tau = t_lo + 0.5 * h * (quads[level, 0, i] + 1.0)
            vb0, vb1, vb2 = coef[j, 3, 5], coef[j, 4, 5], coef[j, 5, 5]
            ab0, ab1, ab2 = dcoef[j, 3, 4], dcoef[j, 4, 4], dcoef[j, 5, 4]
            for k in range(4, -1, -1):
                vb0 = vb0 * tau + coef[j, 3, k]
                vb1 = vb1 * tau + coef[j, 4, k]
                vb2 = vb2 * tau + coef[j, 5, k]
            for k in range(3, -1, -1):
                ab0 = ab0 * tau + dcoef[j, 3, k]
                ab1 = ab1 * tau + dcoef[j, 4, k]
                ab2 = ab2 * tau + dcoef[j, 5, k]
            ve = c[0] * vb0 + c[1] * vb1 + c[2] * vb2
            vn = c[3] * vb0 + c[4] * vb1 + c[5] * vb2
            vu = c[6] * vb0 + c[7] * vb1 + c[8] * vb2
            lat, lon, hgt = _position(legs_i, legs_f, dense, j, tau)
            i0, i1, i2, e0, e1, e2f, gam = _earth_terms(lat, hgt, ve, vn, vu, earth)
            wt = quads[level, 1, i] * 0.5 * h
            sw0 += wt * i0
            sw1 += wt * i1
            sw2 += wt * i2
            sf0 += wt * ((c[0] * ab0 + c[1] * ab1 + c[2] * ab2) + e0)
            sf1 += wt * ((c[3] * ab0 + c[4] * ab1 + c[5] * ab2) + e1)
            sf2 += wt * ((c[6] * ab0 + c[7] * ab1 + c[8] * ab2) + e2f + gam)
    res[0] = c[0] * sw0 + c[3] * sw1 + c[6] * sw2
    res[1] = c[1] * sw0 + c[4] * sw1 + c[7] * sw2
    res[2] = c[2] * sw0 + c[5] * sw1 + c[8] * sw2
    res[3] = c[0] * sf0 + c[3] * sf1 + c[6] * sf2
    res[4] = c[1] * sf0 + c[4] * sf1 + c[7] * sf2
    res[5] = c[2] * sf0 + c[5] * sf1 + c[8] * sf2


@njit(cache=True, nogil=True)
def _chunk_fit(coef, legs_i, legs_f, dense, j, lo, hi, c, fit, earth,
               out):  # pragma: no cover - compiled
    """The interpolant of the body-frame integrands (ω_ib^b, f^b) of leg ``j`` (holding its
    attitude C_b^n = ``c`` and its velocity) over leg time [lo, hi] → ``out`` rows 0-6: row 0 the
    integrands at node :data:`FIT_REF`, rows 1 + k the coefficients of s^k of the degree-5
    polynomial through the deviations from it at the six Chebyshev points s_i = ``fit[0]`` of
    τ = (lo + hi)/2 + s (hi − lo)/2 (``fit[1:]`` the inverse Vandermonde matrix). The
    deviations are ~1e-5 of the integrands (their relative change over ≤ 10 s) and exact
    (Sterbenz), so the fit adds rounding of ~1e-5 ulp."""
    vb0, vb1, vb2 = coef[j, 3, 0], coef[j, 4, 0], coef[j, 5, 0]
    ve = c[0] * vb0 + c[1] * vb1 + c[2] * vb2
    vn = c[3] * vb0 + c[4] * vb1 + c[5] * vb2
    vu = c[6] * vb0 + c[7] * vb1 + c[8] * vb2
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    vals = np.empty((FIT_NODES, 6))
    for i in range(FIT_NODES):
        lat, lon, hgt = _position(legs_i, legs_f, dense, j, mid + half * fit[0, i])
        i0, i1, i2, e0, e1, e2f, gam = _earth_terms(lat, hgt, ve, vn, vu, earth)
        e2f += gam
        vals[i, 0] = c[0] * i0 + c[3] * i1 + c[6] * i2
        vals[i, 1] = c[1] * i0 + c[4] * i1 + c[7] * i2
        vals[i, 2] = c[2] * i0 + c[5] * i1 + c[8] * i2
        vals[i, 3] = c[0] * e0 + c[3] * e1 + c[6] * e2f
        vals[i, 4] = c[1] * e0 + c[4] * e1 + c[7] * e2f
        vals[i, 5] = c[2] * e0 + c[5] * e1 + c[8] * e2f
    for q in range(6):
        ref = vals[FIT_REF, q]
        out[0, q] = ref
        for k in range(FIT_NODES):
            acc = 0.0
            for i in range(FIT_NODES):
                acc += fit[1 + k, i] * (vals[i, q] - ref)
            out[1 + k, q] = acc


@njit(cache=True, nogil=True, inline="always")
def _mean_coefficients(b, d):  # pragma: no cover - compiled
    """Turn ``b`` rows 1-6 (the coefficients of s⁰ … s⁵ of :func:`_chunk_fit`'s quintic p) into
    those of its mean over [s − δ, s + δ], δ = ``d`` (the mean of (s + x)^k over |x| ≤ δ is
    Σ_(j even) C(k, j) s^(k−j) δ^j/(j + 1)), exact for the quintic."""
    d2 = d * d
    d4 = d2 * d2
    for q in range(b.shape[1]):
        c0, c1, c2, c3, c4, c5 = b[1, q], b[2, q], b[3, q], b[4, q], b[5, q], b[6, q]
        b[1, q] = c0 + c2 * d2 / 3.0 + c4 * d4 / 5.0
        b[2, q] = c1 + c3 * d2 + c5 * d4
        b[3, q] = c2 + 2.0 * c4 * d2
        b[4, q] = c3 + c5 * d2 * 10.0 / 3.0


@njit(cache=True, nogil=True)
def _refit(coef, legs_i, legs_f, dense, j, tau, inv, chunk, c, fit, earth,
           bfit):  # pragma: no cover - compiled
    """Fit the chunk of leg ``j`` (holding its attitude C_b^n = ``c`` and velocity) that holds
    leg time ``tau`` — chunk i of ``chunk[j]`` = T seconds: i T ≤ τ < (i + 1) T, the last one
    up to the leg's end, a pure function of τ — into ``bfit``: rows 0-6 its mean polynomial
    for samples of ``inv`` seconds (:func:`_chunk_fit`, :func:`_mean_coefficients`), row 7 the
    leg, the chunk's start and end, its middle and 2/length."""
    lo, hi = chunk_bounds(legs_f[j, LF_DUR], chunk[j], tau)
    _chunk_fit(coef, legs_i, legs_f, dense, j, lo, hi, c, fit, earth, bfit)
    _mean_coefficients(bfit, inv / (hi - lo))
    bfit[7, 0], bfit[7, 1], bfit[7, 2], bfit[7, 3], bfit[7, 4] = (j, lo, hi, 0.5 * (lo + hi),
                                                                  2.0 / (hi - lo))


@njit(cache=True, nogil=True, inline="always")
def _fitted_mean(bfit, tau, inv, res):  # pragma: no cover - compiled
    """∫ω_ib^b, ∫f^b over the whole sample of ``inv`` seconds whose middle is at leg time
    ``tau`` → res[0:6]: ``inv`` times the fitted chunk's mean polynomial (:func:`_refit`) at
    the sample's middle, exact for the chunk's quintic. (Two arrays: numba counts the
    references of every array a call takes, ~5-10 ns each, even inlined — per sample.)"""
    s = (tau - bfit[7, 3]) * bfit[7, 4]
    for q in range(6):
        p = bfit[6, q]
        for k in range(5, 0, -1):
            p = p * s + bfit[k, q]
        res[q] = inv * (bfit[0, q] + p)


@njit(cache=True, nogil=True, inline="always")
def _piece(coef, dcoef, d2coef, legs_i, legs_f, dense, j, ta, d, sub, frac, quads, earth, w,
           c, pos, res):  # pragma: no cover - compiled
    """∫ω_ib^b, ∫f^b over leg time [ta, ta + d) of leg ``j`` → res[0:6] by the leg's
    quadrature (module docstring); ``c`` holds C_b^n of a leg of constant attitude."""
    level = legs_i[j, LI_LEVEL]
    if level != 0:
        _piece_level(coef, dcoef, legs_i, legs_f, dense, j, ta, d, sub, c, quads, level,
                     earth, res)
        return
    if legs_i[j, LI_GEO] == 0:
        for s in range(sub + 1):
            pos[s, 0], pos[s, 1], pos[s, 2] = _position(legs_i, legs_f, dense, j,
                                                        ta + d * frac[s])
    _piece_hermite(coef, dcoef, d2coef, legs_i, j, ta, d, sub, pos, quads, earth, w, res)


@njit(cache=True, nogil=True)
def block_increments(k0, n, rate, sub, coef, dcoef, d2coef, legs_i, legs_f, dense, quads,
                     earth, chunk, fit, dct, out_w, out_f, runs):  # pragma: no cover - compiled
    """Δθ → ``out_w``, Δv → ``out_f`` (3, n: axis by axis) of samples k0 … k0 + n − 1 at
    ``rate`` [Hz].

    Sample i covers [(k0 + i)/f, (k0 + i + 1)/f); a leg start strictly inside it splits it into
    pieces summed in time order (a whole sample lasts exactly 1/f). A piece standing still
    (a still leg, a whole sample) after one of the same leg holds its numbers. ``coef``,
    ``dcoef``, ``d2coef`` the legs' channel polynomials, ``legs_i``, ``legs_f``, ``dense`` as
    :mod:`rlgsim.sim.motion._trajectory_kernel` lays them out; ``quads`` (3, 2, 4) the
    Gauss–Legendre nodes and weights of each quadrature level (:data:`POINTS` of them, the rest
    padding); ``sub`` sub-intervals per piece; ``chunk`` (m,) the fitted chunks' length [s] of
    each leg holding its attitude and velocity while moving and of each turning or
    accelerating one (0: none; module docstring), ``fit`` (7, 6) the Chebyshev points and
    inverse Vandermonde matrix of :func:`_chunk_fit`, ``dct`` the Chebyshev chunks'
    (:mod:`rlgsim.sim.motion._trajectory_cheb`). The runs (lo, hi) of ≥ 2 samples standing
    still in one leg go to ``runs`` (r, 2); returns r."""
    m = legs_i.shape[0]
    inv = 1.0 / rate
    w = np.empty(32)
    res = np.zeros(6)
    c = np.empty(9)
    c_leg = -1
    bfit = np.full((FIT_NODES + 2, 6), -1.0)    # the fitted chunk (_refit): none yet
    cfit = np.full((CHEB_NODES + 1, 6), -1.0)   # the Chebyshev chunk (cheb_refit): none yet
    pos = np.empty((sub + 1, 3))
    frac = np.arange(sub + 1) / sub
    cuts = np.empty(m + 2)
    ci = 0                          # next leg start not yet passed
    leg = 0
    have_prev = prev_still = False
    prev_leg = last_sample = -1
    n_runs = run_lo = run_len = 0
    for i in range(n):
        a_i = (float(k0) + float(i)) / rate
        b_i = (float(k0) + float(i + 1)) / rate
        while ci < m and legs_f[ci, LF_T0] <= a_i:
            ci += 1
        cuts[0] = a_i
        nc = 1
        while ci < m and legs_f[ci, LF_T0] < b_i:
            if legs_f[ci, LF_T0] != cuts[nc - 1]:
                cuts[nc] = legs_f[ci, LF_T0]
                nc += 1
            ci += 1
        cuts[nc] = b_i
        whole = nc == 1
        acc0 = acc1 = acc2 = acc3 = acc4 = acc5 = 0.0
        for p in range(nc):
            a = cuts[p]
            d = inv if whole else cuts[p + 1] - a
            while leg + 1 < m and legs_f[leg + 1, LF_T0] <= a:
                leg += 1
            is_still = legs_i[leg, LI_STILL] == 1 and whole
            if not (is_still and prev_still and leg == prev_leg):
                ta = a - legs_f[leg, LF_T0]
                if legs_i[leg, LI_LEVEL] != 0 and c_leg != leg:     # C_b^n of the leg, once
                    _state(coef, dcoef, leg, ta, w)
                    c[:] = w[0:9]
                    c_leg = leg
                dur = legs_f[leg, LF_DUR]
                if (whole and chunk[leg] >= 4.0 * inv and dur >= 4.0 * inv
                        and ta + inv <= dur):           # a fitted chunk (module docstring)
                    tm = ta + 0.5 * inv
                    if legs_i[leg, LI_LEVEL] != 2:      # turning or accelerating
                        if not (cfit[CHEB_NODES, 0] == leg
                                and cfit[CHEB_NODES, 1] <= tm < cfit[CHEB_NODES, 2]):
                            cheb_refit(coef, dcoef, legs_i, legs_f, dense, leg, tm, inv, chunk,
                                       dct, earth, w, cfit)
                        cheb_mean(cfit, tm, inv, quads, res)
                    else:
                        if not (bfit[7, 0] == leg and bfit[7, 1] <= tm < bfit[7, 2]):
                            _refit(coef, legs_i, legs_f, dense, leg, tm, inv, chunk, c, fit,
                                   earth, bfit)
                        _fitted_mean(bfit, tm, inv, res)
                else:
                    _piece(coef, dcoef, d2coef, legs_i, legs_f, dense, leg, ta, d, sub, frac,
                           quads, earth, w, c, pos, res)
            acc0 += res[0]
            acc1 += res[1]
            acc2 += res[2]
            acc3 += res[3]
            acc4 += res[4]
            acc5 += res[5]
            # runs of still pieces in one leg (each a whole sample)
            if have_prev and is_still == prev_still and leg == prev_leg:
                run_len += 1
            else:
                if have_prev and prev_still and run_len > 1:
                    runs[n_runs, 0], runs[n_runs, 1] = run_lo, last_sample + 1
                    n_runs += 1
                run_lo, run_len = i, 1
            have_prev = True
            prev_still, prev_leg, last_sample = is_still, leg, i
        out_w[0, i], out_w[1, i], out_w[2, i] = acc0, acc1, acc2
        out_f[0, i], out_f[1, i], out_f[2, i] = acc3, acc4, acc5
    if have_prev and prev_still and run_len > 1:
        runs[n_runs, 0], runs[n_runs, 1] = run_lo, last_sample + 1
        n_runs += 1
    return n_runs
