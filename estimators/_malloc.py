"""Keep freed memory in the process for reuse (glibc ``malloc``), so that the large temporaries
of a calibration campaign stop paying page faults on every allocation.

A calibration window of 40 min at 100 Hz makes (n, 3) float arrays of 5.8 MB — pulses,
increments, attitudes, velocities — and a (steps × rows × states) filter array of ~24 MB, two
or three times per window. glibc serves every allocation above its mmap threshold (128 KiB,
rising at most to the size of the last freed block) from a fresh ``mmap`` and unmaps it on
``free``, so each such array is faulted in page by page (zeroed by the kernel) and given back:
~420 000 minor page faults per 33 windows of the paper000 campaign, a quarter to a third of
the campaign's CPU time (measured 5.2-5.9 → 3.9-4.0 s CPU, the same table byte for byte).
Raising the mmap threshold and the trim threshold (``mallopt(3)``: ``M_MMAP_THRESHOLD``,
``M_TRIM_THRESHOLD``; glibc manual, "Memory Allocation Tunables") keeps those blocks in the
heap for the next window. The numbers do not change — only where the arrays live; the cost is
that a process keeps up to ``trim_threshold`` of freed memory instead of returning it.

Written by hand: no library in the project's dependencies sets glibc's allocator parameters
(they are a C call, reached here through :mod:`ctypes`). Elsewhere (macOS, musl) nothing is
done.
"""

from __future__ import annotations

import ctypes
import ctypes.util

__all__ = ["retain_freed_memory"]

#: mallopt(3) parameter numbers (glibc ``malloc.h``).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3


def retain_freed_memory(mmap_threshold: int = 32 << 20, trim_threshold: int = 256 << 20
                        ) -> bool:
    """Serve allocations below ``mmap_threshold`` bytes from the heap and keep up to
    ``trim_threshold`` bytes of freed heap memory in this process (and in the processes it
    forks afterwards); True if glibc took both settings, False where there is no glibc."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, int(mmap_threshold))) \
        & bool(mallopt(M_TRIM_THRESHOLD, int(trim_threshold)))
