"""A window feature of a nonlinear bias-law term computed once per parameter value
(:mod:`rlgsim.lab.identify.law_fit`): the term selection evaluates a knee's or step's
window-averaged feature at every point of its grid again for each refit — the outlier windows
left out one at a time, the mode-hop rounds — on the same per-step temperatures, and each
evaluation is a pass over every thermal step of the recording. The values are the same bytes
as computing them again.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["remembered"]


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
