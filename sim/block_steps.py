"""Step indices of a block, cached: ``np.arange(n)`` made once per length and read-only.

numpy's ``arange`` releases the GIL for every call however short, handing it to the run's
other threads (the IMU's normals worker, the writer) in the middle of a block; the thermal stage
and the IMU stage ask for the same short ranges every block (:mod:`rlgsim.sim.stages.thermal`,
:mod:`rlgsim.sim.sensors.imu`), so a kept array added to or multiplied by a number (no GIL
hand-off for small arrays) replaces the call.
"""

from __future__ import annotations

import functools

import numpy as np


@functools.lru_cache(maxsize=8)
def step_counts(n: int) -> np.ndarray:
    """``np.arange(n)`` (int64), made once per length and read-only (callers make new arrays
    from it: ``step_counts(m + 1) + k0``)."""
    out = np.arange(n, dtype=np.int64)
    out.flags.writeable = False
    return out
