"""The overlapping Allan deviation (``allantools.oadev(..., data_type="freq")``) with its inner
sum compiled (numba, ``nogil``): allantools' phase (:func:`allantools.frequency2phase`: the
mean removed, the running sum times 1/f, a leading zero — compiled in one pass when the record
has no NaN, allantools itself otherwise), τ list (:func:`allantools.tau_generator`) and small-n
rule, then per averaging factor ``m`` one pass over the phase ``x``::

    v_i = (x_{i+2m} − 2·x_{i+m}) + x_i,   s = Σ_i v_i²,   σ(τ) = √(s / 2n) / m · f

(NIST SP 1065 eq. 11; n = N − 2m second differences of the N phase values).

Why not allantools itself: the same numbers in fewer passes. allantools builds three slices,
two temporaries and a product per τ — five passes over the record at each of some twenty
octave τ. On the studies' figures (2.9 M samples of an 8 h run at 100 Hz, five curves per test
run) that was the largest single cost of a report (0.87 s a curve against 0.17 s compiled, one
series, 26 November 2026, under load: the ratio is what counts), and twice per identification
of a 20 h, 100 Hz recording. Here the squares ``v_i²`` are computed and summed in one compiled
pass (the same IEEE-754 operations in the same order, no ``fastmath``) that adds them in the
order of numpy's pairwise sum — the order ``numpy.sum`` of a contiguous array adds them, as
allantools sums them — so the deviations are allantools' bit for bit
(tests/test_allan_kernel.py, tests/test_identify_allan.py). Users: the studies' Allan figures
(:func:`rlgsim.estimators.metrics.allan_deviation`) and the twin's noise fit
(:mod:`rlgsim.estimators.identify.allan_noise`, octave τ up to a limit).
"""

from __future__ import annotations

import allantools
import numpy as np
from numba import njit
from numpy.typing import ArrayLike

__all__ = ["oadev", "oadev_octave"]


@njit(nogil=True, cache=True)
def _any_nan(y):                                               # pragma: no cover (compiled)
    """Whether ``y`` holds a NaN."""
    for i in range(y.size):
        if np.isnan(y[i]):
            return True
    return False


@njit(nogil=True, cache=True)
def _phase(y, mean, dt, out):                                  # pragma: no cover (compiled)
    """``out[0] = 0``, ``out[i+1] = (Σ_{k≤i} (y_k − mean))·dt``: allantools'
    ``np.cumsum(y − mean)·dt`` with the leading zero (a running sum in index order, as
    numpy's cumsum adds), in one pass."""
    out[0] = 0.0
    acc = 0.0
    for i in range(y.size):
        acc = acc + (y[i] - mean)
        out[i + 1] = acc * dt


def _frequency2phase(freq: np.ndarray, rate_hz: float) -> np.ndarray:
    """:func:`allantools.frequency2phase` bit for bit: without a NaN its mean is numpy's
    pairwise ``sum / n`` (what ``np.nanmean`` computes then) and its running sum is compiled
    (:func:`_phase`: one pass instead of allantools' trim, mean, difference, cumsum, product
    and insert, 0.45 s of a 7.2 M-sample record); with a NaN, allantools itself."""
    y = np.ascontiguousarray(freq, dtype=np.float64)
    if y.size == 0 or _any_nan(y):
        return allantools.frequency2phase(y, rate_hz)
    out = np.empty(y.size + 1)
    _phase(y, float(np.sum(y)) / y.size, 1.0 / float(rate_hz), out)
    return out


@njit(nogil=True, cache=True, inline="always")
def _term(x, m, i):                                            # pragma: no cover (compiled)
    """``v_i²``, ``v_i = (x[i+2m] − 2·x[i+m]) + x[i]`` (allantools' operations)."""
    v = x[i + 2 * m] - 2.0 * x[i + m] + x[i]
    return v * v


@njit(nogil=True, cache=True)
def _sum_of_squares(x, m, lo, n):                              # pragma: no cover (compiled)
    """Σ v_i² (:func:`_term`) over ``lo ≤ i < lo + n`` in numpy's pairwise order, so the result
    is ``np.sum`` of the squares bit for bit without writing them: under 8 terms one running
    sum from 0; up to 128 terms eight running sums of every eighth term, combined as
    ((r0+r1)+(r2+r3))+((r4+r5)+(r6+r7)), then the rest added in order; above, the two halves
    (the first a multiple of 8 long) summed alike and added (numpy's ``pairwise_sum``,
    ``PW_BLOCKSIZE`` 128). Eight scalars, not an array: 30 % faster."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += _term(x, m, i)
        return res
    if n <= 128:
        r0, r1, r2, r3 = _term(x, m, lo), _term(x, m, lo + 1), _term(x, m, lo + 2), \
            _term(x, m, lo + 3)
        r4, r5, r6, r7 = _term(x, m, lo + 4), _term(x, m, lo + 5), _term(x, m, lo + 6), \
            _term(x, m, lo + 7)
        i = lo + 8
        end8 = lo + n - n % 8
        while i < end8:
            r0 += _term(x, m, i)
            r1 += _term(x, m, i + 1)
            r2 += _term(x, m, i + 2)
            r3 += _term(x, m, i + 3)
            r4 += _term(x, m, i + 4)
            r5 += _term(x, m, i + 5)
            r6 += _term(x, m, i + 6)
            r7 += _term(x, m, i + 7)
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < lo + n:
            res += _term(x, m, i)
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _sum_of_squares(x, m, lo, n2) + _sum_of_squares(x, m, lo + n2, n - n2)


def oadev(freq: np.ndarray, rate_hz: float, taus: ArrayLike | str = "octave",
          max_tau_s: float = np.inf
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(taus, adev, adev_error, ns)`` of :func:`allantools.oadev` with ``data_type="freq"``
    (only τ ≤ ``max_tau_s``; estimates from a single difference left out as allantools does):
    τ [s], the deviation in the unit of ``freq``, its 1-σ error ``adev/√n`` and the number of
    differences n (float, as allantools returns it)."""
    phase = _frequency2phase(np.asarray(freq, dtype=float), rate_hz)
    phase, m, tau = allantools.tau_generator(phase, rate_hz, taus)
    m = np.asarray(m, dtype=np.int64)
    tau = np.asarray(tau, dtype=float)
    use = tau <= max_tau_s
    m, tau = m[use], tau[use]
    phase = np.ascontiguousarray(phase, dtype=np.float64)
    sums = np.empty(m.size)
    for j, mj in enumerate(m):                  # numpy's pairwise sum, as allantools sums
        sums[j] = _sum_of_squares(phase, int(mj), 0, max(phase.size - 2 * int(mj), 0))
    n = np.maximum(phase.size - 2 * m, 1)
    adev = np.sqrt(sums / (2.0 * n)) / m * rate_hz
    big = n > 1
    adev, n = adev[big], n[big].astype(float)
    return tau[big], adev, adev / np.sqrt(n), n


def oadev_octave(freq: np.ndarray, rate_hz: float, max_tau_s: float = np.inf
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(taus, adev, ns)`` of :func:`oadev` at octave τ up to ``max_tau_s`` (the twin's
    noise fit)."""
    tau, adev, _, n = oadev(freq, rate_hz, "octave", max_tau_s)
    return tau, adev, n.astype(np.int64)
