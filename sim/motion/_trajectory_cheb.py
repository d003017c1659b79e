"""Compiled Chebyshev chunks of a trajectory's turning and accelerating legs (numba): a whole
sample's increments as the exact mean of a degree-11 interpolant of the integrands.

On a leg whose attitude turns (quadrature level 0, body frame) or whose velocity changes at a
constant attitude (level 1), the 4- or 3-point Gauss–Legendre quadrature of
:mod:`rlgsim.sim.motion._trajectory_block` evaluates the integrands 4-6 times a sample (~850
and ~380 ns at 100 Hz). Here the leg is cut into chunks of T seconds from its start
(``chunk``, set by :func:`rlgsim.sim.motion.trajectory._chunk_lengths`); the body-frame
integrands (ω_ib^b, f^b) at the N = :data:`NODES` Chebyshev points of the chunk widened by
half a sample each side (the position from the DOP853 dense output) give the Chebyshev series
of their interpolant p of degree N − 1 (a discrete cosine transform, ``DCT``), and the series
of its mean over a sample,

    mean_[s−δ, s+δ] p = Σ_(j ≥ 0) δ^(2j)/(2j + 1)! · p^(2j)(s)      (Taylor; exact for p),

δ a sample's half-width in the chunk's variable s ∈ [−1, 1], the derivatives' series by the
standard recurrence (Mason & Handscomb 2003, *Chebyshev Polynomials*, §2.4.5, §6.3). A sample
whose middle lies in the chunk is ``inv`` times that series at its middle, by Clenshaw's
recurrence: 12 evaluations of the integrands per chunk and one short sum per sample instead
of 4-6 evaluations per sample. Why by hand: NumPy's ``chebval``/``chebder`` are not callable
from compiled code, and the chunk must be a pure function of the sample's time (the same
numbers whatever block holds it).

**Error.** Interpolation at the N Chebyshev points of an interval of length L errs by
≤ 2 (L/4)^N max|F^(N)|/N! (Mason & Handscomb Thm 6.5), and Cauchy's estimate on a disc of
radius ρ, |F^(N)| ≤ N! M_ρ/ρ^N, gives ≤ 2 M_ρ (L/4ρ)^N. ρ is the radius on which every channel
of the leg moves by little — each angle by ≤ 0.5 rad (so |sin|, |cos| ≤ cosh 0.5) and each body
velocity by ≤ half its largest value (Σ_(k ≥ 1) max|c^(k)| ρ^k/k! below those bounds,
:func:`chunk_radii`) — so M_ρ is a few times max|F|. With T = :data:`RHO_FRACTION` ρ and
L ≤ 1.25 T (a chunk holds ≥ 4 samples), 2 (L/4ρ)^N ≤ 2 · 0.031^12 ≈ 2e-18: below float64's
rounding of the increments; the widening keeps every sample inside the interpolated interval
(no extrapolation, where |T_N| grows fast). The mean is exact for p. The position enters
through the Earth's terms only (time scale R/v ≥ hours). Rounding: the node values' few ulps
pass through the interpolant with its Lebesgue constant (≈ 2.5 at N = 12) and averaging does
not amplify them, so a sample errs by a few ulps of the chunk's largest integrand (the
quadrature's by a few of its own): on the shipped land and aircraft routes and gnss-ins-sim's
demo files the two differ by ≤ 19 ulps of each leg's largest Δθ or Δv component, and at the
land and aircraft routes' worst samples meet
the 10-point reference of tests/test_trajectory.py within 14 / 36 ulps of it (the quadrature:
5 / 29; the reference's own rounding is of that size; the tests allow 64). Cost at 100 Hz: ~95 ns a sample of a turn
(was ~850), ~105 of an acceleration (was ~380).

No ``fastmath``: the same operations in the same order for a sample whatever block holds it.
numba's cache keys :func:`~rlgsim.sim.motion._trajectory_block.block_increments` on its own
file: a change here must also edit that file's ``HELPERS_REVISION``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rlgsim.sim.motion._trajectory_kernel import (LF_DUR, _earth_terms, _position, _state,
                                                  chunk_bounds)

#: Chebyshev points of a chunk (the interpolant's degree + 1), the chunk length as a fraction
#: of the analytic radius ρ and its cap [s] (module docstring)
NODES = 12
RHO_FRACTION = 0.1
CHUNK_MAX_S = 1.0
#: the chunk's Chebyshev points x_i = cos(π(i + ½)/N) (row 0) and the transform from the
#: values at them to the series' coefficients a_k = (2 − [k = 0])/N Σ_i F_i T_k(x_i) (rows 1…N)
_X = np.polynomial.chebyshev.chebpts1(NODES)[::-1].copy()
DCT = np.vstack([_X[None, :],
                 np.polynomial.chebyshev.chebvander(_X, NODES - 1).T
                 * np.where(np.arange(NODES) == 0, 1.0, 2.0)[:, None] / NODES])


@njit(cache=True, nogil=True, inline="always")
def _derivative(c, out):  # pragma: no cover - compiled
    """The Chebyshev series of the derivative of the series ``c`` (N terms) → ``out`` (its
    first N − 1 terms, the last zero): d_(k−1) = d_(k+1) + 2k c_k, d_0 halved (Mason &
    Handscomb §2.4.5)."""
    n = c.shape[0]
    out[n - 1] = 0.0
    nxt = 0.0                                    # d_(k+1)
    cur = 0.0                                    # d_k
    for k in range(n - 1, 0, -1):
        d = nxt + 2.0 * k * c[k]
        out[k - 1] = d
        nxt, cur = cur, d
    out[0] *= 0.5


@njit(cache=True, nogil=True)
def cheb_fit(coef, dcoef, legs_i, legs_f, dense, j, lo, hi, inv, dct, earth, w,
             out):  # pragma: no cover - compiled
    """The mean series of leg ``j``'s chunk [lo, hi] (leg time) → ``out`` (N + 1, 6): rows
    0 … N − 1 the Chebyshev coefficients of the mean over a sample of ``inv`` seconds of the
    integrands' interpolant on the chunk widened by half a sample each side (within the leg;
    module docstring), row N (j, lo, hi, the widened interval's middle and 2/length)."""
    a = max(lo - 0.5 * inv, 0.0)                    # every sample whose middle is in the
    b = min(hi + 0.5 * inv, legs_f[j, LF_DUR])      # chunk lies in [a, b]: no extrapolation
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    vals = np.empty((NODES, 6))
    for i in range(NODES):
        tau = mid + half * dct[0, i]
        _state(coef, dcoef, j, tau, w)
        lat, lon, hgt = _position(legs_i, legs_f, dense, j, tau)
        i0, i1, i2, e0, e1, e2f, gam = _earth_terms(lat, hgt, w[12], w[13], w[14], earth)
        fn0, fn1, fn2 = w[15] + e0, w[16] + e1, w[17] + e2f + gam
        for r in range(3):
            vals[i, r] = w[9 + r] + (w[r] * i0 + w[3 + r] * i1 + w[6 + r] * i2)
            vals[i, 3 + r] = w[r] * fn0 + w[3 + r] * fn1 + w[6 + r] * fn2
    delta = 0.5 * inv / half                    # a sample's half-width in s
    d2 = delta * delta
    a = np.empty(NODES)
    d = np.empty(NODES)
    for q in range(6):
        for k in range(NODES):
            acc = 0.0
            for i in range(NODES):
                acc += dct[1 + k, i] * vals[i, q]
            a[k] = acc
            out[k, q] = acc
        scale = 1.0                              # δ^(2j)/(2j + 1)!
        for jj in range(1, NODES // 2):
            _derivative(a, d)
            _derivative(d, a)
            scale *= d2 / ((2 * jj) * (2 * jj + 1))
            for k in range(NODES - 2 * jj):
                out[k, q] += scale * a[k]
    out[NODES, 0], out[NODES, 1], out[NODES, 2] = j, lo, hi
    out[NODES, 3], out[NODES, 4] = mid, 1.0 / half


@njit(cache=True, nogil=True)
def cheb_refit(coef, dcoef, legs_i, legs_f, dense, j, tau, inv, chunk, dct, earth, w,
               out):  # pragma: no cover - compiled
    """Fit the chunk of leg ``j`` holding leg time ``tau`` (chunk i: i T ≤ τ < (i + 1) T, the
    last one to the leg's end; a pure function of τ) into ``out`` (:func:`cheb_fit`)."""
    lo, hi = chunk_bounds(legs_f[j, LF_DUR], chunk[j], tau)
    cheb_fit(coef, dcoef, legs_i, legs_f, dense, j, lo, hi, inv, dct, earth, w, out)


@njit(cache=True, nogil=True, inline="always")
def cheb_mean(cfit, tau, inv, quads, res):  # pragma: no cover - compiled
    """∫ω_ib^b, ∫f^b over the whole sample of ``inv`` seconds whose middle is at leg time
    ``tau`` → res[0:6]: ``inv`` times the chunk's mean series at the sample's middle
    (Clenshaw's recurrence)."""
    s = (tau - cfit[NODES, 3]) * cfit[NODES, 4]
    s2 = 2.0 * s
    for q in range(6):
        b1 = b2 = 0.0
        for k in range(NODES - 1, 0, -1):
            b1, b2 = cfit[k, q] + s2 * b1 - b2, b1
        res[q] = inv * (cfit[0, q] + s * b1 - b2)


#: the radii tried by :func:`chunk_radii` [s]: 5 % apart (the largest one that passes is taken)
_RHO_GRID = np.geomspace(1e-4, 1e6, 461)


def chunk_radii(coef: np.ndarray, duration: np.ndarray) -> np.ndarray:
    """ρ [s] (m,) of legs' channel polynomials ``coef`` (m, 6, 6: heading, pitch, roll [rad],
    body velocity [m/s]; coefficients of τ⁰ … τ⁵) on [0, ``duration``] (module docstring): the
    largest radius of :data:`_RHO_GRID` with Σ_(k ≥ 1) max|c^(k)| ρ^k/k! ≤ 0.5 rad for each
    angle and ≤ half the largest |value| for each velocity (the maxima on 65 points of the
    leg); inf when nothing moves, 0 when not even the smallest passes."""
    m, deg = coef.shape[0], coef.shape[2]
    if m == 0:
        return np.zeros(0)
    tau = np.linspace(0.0, 1.0, 65)[None, :] * np.asarray(duration, dtype=float)[:, None]
    powers = np.ones((m, tau.shape[1], deg))                         # τ^n (m, 65, deg)
    for n in range(1, deg):
        powers[:, :, n] = powers[:, :, n - 1] * tau
    peaks = np.zeros((m, 6, deg - 1))
    for k in range(1, deg):          # the k-th derivative / k!: c_n C(n, k) τ^(n − k)
        binom = np.array([math.comb(n, k) for n in range(k, deg)], dtype=float)
        d = powers[:, :, :deg - k] @ (coef[:, :, k:] * binom).transpose(0, 2, 1)
        peaks[:, :, k - 1] = np.max(np.abs(d), axis=1)
    values = np.max(np.abs(powers @ coef.transpose(0, 2, 1)), axis=1)     # (m, 6)
    limits = np.concatenate([np.full((m, 3), 0.5), 0.5 * values[:, 3:]], axis=1)
    growth = peaks @ (_RHO_GRID[None, :] ** np.arange(1, deg)[:, None])    # (m, 6, grid)
    ok = np.all(growth <= limits[:, :, None], axis=1)                      # (m, grid)
    first_bad = np.argmin(ok, axis=1)
    return np.where(ok[:, -1], np.inf,
                    np.where(ok[:, 0], _RHO_GRID[np.maximum(first_bad - 1, 0)], 0.0))
