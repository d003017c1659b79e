"""The machine code of a compiled kernel, for the tests that look for fused multiply-adds.

A kernel compiled in this process can be inspected as it is; one loaded from numba's on-disk
cache cannot (numba keeps only its object code), so that one is compiled again, uncached, from
the same Python function with the same options but ``cache`` (the options do not reach the
code: ``cache`` only decides where the result is kept). On a cold cache (a clean clone, CI) the
first case saves the second compile of each kernel (1-3 s each, the suite's time, issue 30).
"""

from __future__ import annotations

FMA = r"f(n)?m(add|sub)|fml[as]"      # x86 vf[n]m…, aarch64 fml[as]


def compiled_asm(dispatcher, sig) -> str:
    """Lower-case assembly of ``dispatcher``'s specialisation ``sig`` (which must be compiled
    or loaded already)."""
    if dispatcher._cache_misses.get(sig, 0) and not dispatcher._cache_hits.get(sig, 0):
        return dispatcher.inspect_asm(sig).lower()         # compiled here: inspectable
    from numba import njit
    options = {k: v for k, v in dispatcher.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = njit(**options)(dispatcher.py_func)
    fresh.compile(sig)
    return fresh.inspect_asm(sig).lower()
