"""estimators/_malloc.py: with the allocator told to keep freed memory, the arrays of one
calibration window freed together and allocated again for the next are served from memory
already mapped (no page faults), where glibc's defaults give most of it back and fault it in
again (~7 500 faults for the three windows below)."""

from __future__ import annotations

import resource
import sys

import numpy as np
import pytest

from rlgsim.estimators._malloc import retain_freed_memory


def _window() -> float:
    """A window's worth of temporaries alive together (a quarter of a 40-min window at 100 Hz:
    ten (n, 3) float arrays and one filter array of steps × rows × states, 20 MB)."""
    n = 60_000
    arrays = [np.ones((n, 3)) for _ in range(10)] + [np.ones((600, 24, 51))]
    return float(sum(a.sum() for a in arrays))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_freed_window_arrays_are_reused_without_page_faults():
    if not retain_freed_memory():
        pytest.skip("no glibc")
    _window()                            # the first window grows the heap
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(3):
        _window()
    assert resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults < 300
