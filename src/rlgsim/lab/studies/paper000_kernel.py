"""Compiled pulse conversion of paper 000's system-level compensation (eqs. 26 and 29; numba).

:class:`rlgsim.lab.studies.paper000_compensation._Transform` converts every pulse of a
120-h campaign (43 M samples × 6 channels) to the desired temperature and rounds the running
sum back to whole pulses. In numpy that is ~15 full-length temporaries per block (time grid,
three linear interpolations, ratio, drift, running sum, rounding, differences); one pass in
compiled code does the same arithmetic per sample with no temporary, 5-10× faster.

The numbers are the numpy formulation's (``_Transform.numpy_block``), bit for bit, for finite
model values (the caller checks; numpy serves the rest; tests/test_study_paper000.py compares
the two on blocks with carries, and the study's compensated datasets were compared whole):
every product, quotient and sum is taken in the same order
on the same float64 operands (no fused multiply-add: numba does not contract without
``fastmath``), the running sum is sequential from the block's start with the carry added
after it (as ``cumsum`` then ``+ carry``), and the linear interpolation is ``numpy.interp``'s
own formula (numpy ``_core/src/multiarray/compiled_base.c``, ``arr_interp``): on the interval
xp[j] ≤ x < xp[j+1], slope (fp[j+1] − fp[j]) / (xp[j+1] − xp[j]) times (x − xp[j]) plus
fp[j]; fp[j] exactly at a grid point; the end values outside the grid; the other end of the
interval if the first form gives NaN (never, for finite values: not compiled here — its
mere presence in the loop made the pass 10× slower).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _locate(x: float, xp: np.ndarray, j: int) -> int:  # pragma: no cover - compiled
    """The interval j of increasing ``xp`` with xp[j] ≤ x < xp[j+1] (m − 1 from xp[m−1] on,
    0 before xp[0]), searched forward from the previous (smaller or equal) x's ``j``."""
    m = xp.size
    while j < m - 1 and xp[j + 1] <= x:
        j += 1
    return j


@njit(cache=True, nogil=True, inline="always")
def _interp(x: float, xp: np.ndarray, fp: np.ndarray, slope: np.ndarray,
            j: int) -> float:  # pragma: no cover - compiled
    """``numpy.interp(x, xp, fp)`` with x in interval ``j`` (:func:`_locate`) and ``slope``
    = (fp[1:] − fp[:-1]) / (xp[1:] − xp[:-1]) (:func:`slopes`, as numpy's own table), for
    finite ``fp`` and ``slope`` (then numpy's NaN fallbacks never apply: a finite slope times
    a finite distance plus a finite value is never NaN)."""
    m = xp.size
    if x < xp[0]:
        return fp[0]
    if x > xp[m - 1]:
        return fp[m - 1]
    if j == m - 1 or xp[j] == x:
        return fp[j]
    return slope[j] * (x - xp[j]) + fp[j]


def slopes(xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """The slopes of the linear interpolation of rows ``fp`` (r, m) on ``xp`` (m,), per
    interval (r, m − 1), computed as ``numpy.interp`` computes them."""
    return np.ascontiguousarray((fp[:, 1:] - fp[:, :-1]) / (xp[1:] - xp[:-1]))


@njit(cache=True, nogil=True)
def convert_block(pulses, k0, dt, ptime, sf_pos, sf_neg, bias, slopes_sf_pos, slopes_sf_neg,
                  slopes_bias, two_sided, num_pos, num_neg, kd_pos, kd_neg, bias_d, cum, last,
                  out):  # pragma: no cover - compiled
    """Eqs. (26)/(29) on one block of pulses, cumulatively rounded, into ``out``.

    ``pulses`` (n, 3) int32, samples k0 … k0 + n − 1 at their middles (k + ½) dt [s];
    ``ptime`` (m,) probe grid [s]; per axis i: ``sf_pos[i]``/``sf_neg[i]`` (m,) scale-factor
    error [ppm] for N ≥ 0 / N < 0 (``sf_neg`` used only with ``two_sided``),
    ``num_*[i]`` = 1 + 1e-6 s(T_d), ``kd_*[i]`` = K(T_d), ``bias[i]`` (m,) and ``bias_d[i]``
    the bias [pulse units / K per s], ``slopes_*`` their interpolation slopes (r, m − 1)
    (:func:`slopes`); ``cum``/``last`` (3,) the running sum and its rounding at
    the previous block's end (updated in place); ``out`` (n, 3) int32."""
    n = pulses.shape[0]
    for i in range(3):
        xs_p, xs_n, xb = sf_pos[i], sf_neg[i], bias[i]
        ss_p, ss_n, sb = slopes_sf_pos[i], slopes_sf_neg[i], slopes_bias[i]
        c = 0.0
        r_prev = last[i]
        tot = cum[i]
        j = max(int(np.searchsorted(ptime, (float(k0) + 0.5) * dt, side="right")) - 1, 0)
        for k in range(n):
            x = (float(k0 + k) + 0.5) * dt
            j = _locate(x, ptime, j)
            nv = float(pulses[k, i])
            if two_sided and nv < 0:
                den = _interp(x, ptime, xs_n, ss_n, j)
                num = num_neg[i]
                kd = kd_neg[i]
            else:
                den = _interp(x, ptime, xs_p, ss_p, j)
                num = num_pos[i]
                kd = kd_pos[i]
            den = den * 1e-6
            den = den + 1.0
            ratio = num / den
            comp = ratio * nv
            drift = _interp(x, ptime, xb, sb, j)
            drift = bias_d[i] - drift
            drift = kd * drift
            drift = drift * dt
            comp = comp + drift
            if k == 0:
                c = comp
            else:
                c = c + comp
            tot = c + cum[i]
            r = np.rint(tot)
            out[k, i] = np.int32(r - r_prev)
            r_prev = r
        if n > 0:
            cum[i] = tot
            last[i] = r_prev
