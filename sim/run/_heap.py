"""Freed block buffers stay in the process heap during a run (glibc malloc thresholds).

Every 600 s block allocates and frees a few MB of arrays — increments, normals, pulses, truth
rows — in three threads (:mod:`rlgsim.sim.run.simulate`). glibc's malloc (its manual, "Memory
Allocation Tunables": ``M_MMAP_THRESHOLD``, ``M_TRIM_THRESHOLD``; mallopt(3)) serves a request
above its mmap threshold with fresh pages from the kernel and gives the top of a heap back to
the kernel above its trim threshold; its dynamic adjustment of both does not settle with several
threads, so each block's arrays were touched afresh: ~130 000 minor page faults and ~0.25 s of
kernel time per 24 h simulated at 100 Hz on the paper-000 programme, ~18 % of the run's CPU
(measured with ``resource.getrusage``; benchmarks/bench_sim.py prints the page faults). Fixed
thresholds — requests up to 32 MiB from the heap, up to 512 MiB of free heap kept — let the
next block reuse the same pages: ~100 faults per 24 h.

Process-wide and for the rest of the process: freed memory is reused by later allocations
rather than returned to the kernel, so the resident size stays near its peak (the run's
peak: a few hundred MB, flat in the duration). No value computed anywhere changes. Other C
libraries (or a glibc without ``mallopt``) are left alone.
"""

from __future__ import annotations

import ctypes
import sys

#: mallopt(3) parameter numbers (glibc malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: requests up to this size come from the heap (glibc's maximum on 64-bit: 32 MiB)
MMAP_THRESHOLD = 32 << 20
#: free memory kept at the top of a heap before it goes back to the kernel
TRIM_THRESHOLD = 512 << 20

_applied: bool | None = None


def keep_freed_memory() -> bool:
    """Set the two glibc thresholds once per process; True when they are set (Linux with
    glibc), False elsewhere."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
        gnu = libc.gnu_get_libc_version             # glibc only (musl has a no-op mallopt)
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    del gnu
    _applied = (mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
                and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1)
    return _applied
