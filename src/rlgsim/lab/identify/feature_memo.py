"""A window feature of a nonlinear bias-law term computed once per parameter value
(:mod:`rlgsim.lab.identify.law_fit`): the term selection evaluates a knee's or step's
window-averaged feature at every point of its grid again for each refit — the outlier windows
left out one at a time, the mode-hop rounds — on the same per-step temperatures, and each
evaluation is a pass over every thermal step of the recording. The values are the same bytes
as computing them again. :func:`window_means` is the window average every candidate term
goes through, some 1,300 times a 20 h identification.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["remembered", "window_means"]


def remembered(f: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    """``f`` computing each ``theta`` once: the term selection evaluates a nonlinear term's
    window feature at every grid point again for each refit (outliers, mode hops: the same
    per-step temperatures), and each evaluation is a pass over every thermal step. The stored
    arrays are read-only; a theta is the same when its bytes are."""
    seen: dict[bytes, np.ndarray] = {}

    def g(th: np.ndarray) -> np.ndarray:
        key = np.asarray(th, dtype=float).tobytes()
        v = seen.get(key)
        if v is None:
            if len(seen) >= 4096:                       # a bound on the memory, not reached
                seen.clear()
            v = np.asarray(f(th), dtype=float)
            v.setflags(write=False)
            seen[key] = v
        return v
    return g


def window_means(v: np.ndarray, rate_hz: float, window_s: float, rows: np.ndarray) -> np.ndarray:
    """The rows ``rows`` of :func:`rlgsim.estimators.features.window_average` of the per-step
    series ``v`` (at ``rate_hz``, windows of ``window_s``): the same reshape and mean, without
    its input validation (scikit-learn's ``check_array``, most of a call's cost on a 20 h
    recording's 72,000 steps) when ``v`` is a finite 1-D series at least a window long —
    otherwise ``window_average`` itself, with its errors."""
    from rlgsim.estimators.features import samples_per_window, window_average
    v = np.asarray(v, dtype=float)
    m = samples_per_window(rate_hz, window_s)
    if v.ndim == 1 and v.size >= m and np.isfinite(v).all():
        n = v.size // m
        return v[:n * m].reshape(n, m).mean(axis=1)[rows]
    return np.asarray(window_average(v, rate_hz, window_s))[rows]
