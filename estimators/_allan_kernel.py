"""Compiled sums of the overlapping Allan variance (numba).

``allantools.oadev`` evaluates, for each averaging factor m, the sum of squared second
differences of the phase, Σ (x[i+2m] − 2·x[i+m] + x[i])² over i = 0 … N−2m−1 (NIST SP 1065,
eq. 11), with four NumPy temporaries of N values per m. On the studies' figures (2.9 M samples
of an 8 h run at 100 Hz, 21 octave averaging times, five curves per test run) that loop was the
largest single cost of a report: 0.87 s a curve against 0.17 s for one compiled pass per m
without temporaries (measured on the same series, 26 November 2026, under load; the ratio is
what matters). allantools stays the reference for everything else — the frequency-to-phase
integration, the τ list, dropping τ with fewer than two terms — and
``tests/test_allan_kernel.py`` holds this sum to allantools' deviation on the same data.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def second_difference_sums(phase: np.ndarray, ms: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """For each averaging factor ``ms[k]`` (samples, ≥ 1), the sum over i of
    (phase[i+2m] − 2·phase[i+m] + phase[i])², i = 0 … len(phase)−2m−1 (0 where no term)."""
    out = np.zeros(ms.size)
    n_all = phase.size
    for k in range(ms.size):
        m = ms[k]
        s = 0.0
        for i in range(n_all - 2 * m):
            d = phase[i + 2 * m] - 2.0 * phase[i + m] + phase[i]
            s += d * d
        out[k] = s
    return out
