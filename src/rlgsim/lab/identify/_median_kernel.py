"""Compiled centred rolling median (numba, ``nogil``): ``pandas.Series(x).rolling(2h + 1,
center=True, min_periods=p).median()`` for the spike scan of :mod:`.spike_fit`, whose 31-sample
median over every gyro sample of a recording (7.2 million at 100 Hz for 20 h) was the scan's
cost.

Why not pandas: the same values in one pass without its window machinery. The window of
sample ``i`` is ``x[i−h … i+h]`` cut at the ends; missing values (NaN) are left out; with
fewer than ``p`` values present the result is NaN; the median of ``n`` present values is the
middle one of them sorted, for even ``n`` the half-sum of the two middle ones. The present
values are kept sorted in a buffer of ``2h + 1``, one inserted and one removed per step.
tests/test_identify_maths.py holds it to pandas bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["rolling_median"]


@njit(nogil=True, cache=True)
def _insert(buf, cnt, v):                                     # pragma: no cover (compiled)
    """Insert ``v`` into the sorted ``buf[:cnt]``."""
    lo, hi = 0, cnt
    while lo < hi:
        mid = (lo + hi) // 2
        if buf[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    for k in range(cnt, lo, -1):
        buf[k] = buf[k - 1]
    buf[lo] = v


@njit(nogil=True, cache=True)
def _remove(buf, cnt, v):                                     # pragma: no cover (compiled)
    """Remove one ``v`` from the sorted ``buf[:cnt]`` (it is there)."""
    lo, hi = 0, cnt
    while lo < hi:
        mid = (lo + hi) // 2
        if buf[mid] < v:
            lo = mid + 1
        else:
            hi = mid
    for k in range(lo, cnt - 1):
        buf[k] = buf[k + 1]


@njit(nogil=True, cache=True)
def _rolling_median(x, half, min_periods, out):               # pragma: no cover (compiled)
    """The centred rolling median of ``x`` into ``out`` (module docstring)."""
    n = x.size
    buf = np.empty(2 * half + 1)
    cnt = 0
    for j in range(min(half, n)):
        if x[j] == x[j]:
            _insert(buf, cnt, x[j])
            cnt += 1
    for i in range(n):
        j = i + half
        if j < n and x[j] == x[j]:
            _insert(buf, cnt, x[j])
            cnt += 1
        k = i - half - 1
        if k >= 0 and x[k] == x[k]:
            _remove(buf, cnt, x[k])
            cnt -= 1
        if cnt >= min_periods and cnt > 0:
            mid = cnt // 2
            if cnt % 2:
                out[i] = buf[mid]
            else:
                out[i] = (buf[mid] + buf[mid - 1]) / 2.0
        else:
            out[i] = np.nan


def rolling_median(x: np.ndarray, window: int, min_periods: int) -> np.ndarray:
    """``pandas.Series(x).rolling(window, center=True, min_periods=min_periods).median()``
    for an odd ``window`` (module docstring), as a float64 array."""
    if window < 1 or window % 2 == 0:
        raise ValueError(f"the window must be odd and positive, not {window}")
    x = np.ascontiguousarray(x, dtype=float)
    out = np.empty(x.size)
    _rolling_median(x, window // 2, max(int(min_periods), 0), out)
    return out
