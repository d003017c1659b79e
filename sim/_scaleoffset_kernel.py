"""Compiled loop of :func:`rlgsim.sim._scaleoffset.encode` (numba): HDF5's integer scale-offset
encoding of whole chunks, the same bytes as HDF5's own filter (:mod:`rlgsim.sim._scaleoffset`
states the format and why it is done here).

One call encodes every chunk of a write. Per chunk: the minimum and maximum of the values other
than the fill value (one pass, no branch the compiler cannot turn into selects), then the bit
packing — each value's ``minbits`` low bits, most significant first, appended to a 64-bit
accumulator that is emptied 32 bits at a time (``minbits`` < 32 here, so it never holds more than
63 bits). HDF5's filter moves the bits one byte of one value at a time through function calls
(~2 ns per value); this loop costs a fraction of that. The accumulator and the bit counts are
unsigned 64-bit throughout (numba would turn a mix of signed and unsigned integers into floats).

Bit for bit :func:`rlgsim.sim._scaleoffset._encode_numpy` and HDF5's filter
(tests/test_scaleoffset.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

_U8 = np.uint64(8)
_U32 = np.uint64(32)
_BYTE = np.uint64(0xFF)


@njit(cache=True, nogil=True)
def encode_chunks(values, raw, fill, out, ends):  # pragma: no cover
    """Encode the chunks ``values`` (k, n) (one chunk per row, an integer dtype of at most
    4 bytes, the dataset's byte order = native little-endian) into ``out`` (uint8, at least
    k·(n·s + 22) bytes, s the item size); chunk j's bytes are ``out[ends[j]:ends[j + 1]]``
    (``ends`` (k + 1,) int64). ``raw`` (k, n·s) uint8 is the same memory as ``values`` (copied as
    it is when a chunk needs the full width); ``fill`` the dataset's fill value."""
    k = values.shape[0]
    n = values.shape[1]
    s = raw.shape[1] // n if n > 0 else 1
    width = 8 * s
    pos = 0
    ends[0] = 0
    for c in range(k):
        v = values[c]
        lo = np.int64(9223372036854775807)
        hi = np.int64(-9223372036854775807 - 1)
        for i in range(n):
            x = np.int64(v[i])
            if x != fill:
                lo = min(lo, x)
                hi = max(hi, x)
        if lo > hi:                       # every value is the fill value
            lo = np.int64(0)
            hi = np.int64(0)
        if hi - lo > (np.int64(1) << width) - 3:
            minbits = width
            minval = np.int64(0)
        else:
            span = hi - lo + 2            # (max − min + 1) + 1: one more code for the fill value
            minbits = 0
            while (np.int64(1) << minbits) < span:      # ⌈log2(span)⌉
                minbits += 1
            minval = lo
        # header: minbits (4 bytes LE), sizeof(unsigned long long), minval (8 bytes LE), 8 zeros
        for b in range(4):
            out[pos + b] = (minbits >> (8 * b)) & 0xFF
        out[pos + 4] = 8
        for b in range(8):
            out[pos + 5 + b] = (minval >> (8 * b)) & 0xFF
        for b in range(13, 21):
            out[pos + b] = 0
        p = pos + 21
        if minbits == width:
            row = raw[c]
            for i in range(n * s):
                out[p + i] = row[i]
            pos = p + n * s
        else:
            size = (n * minbits) // 8 + 1
            for i in range(size):
                out[p + i] = 0
            bits = np.uint64(minbits)
            code = np.uint64((1 << minbits) - 1)
            acc = np.uint64(0)
            held = np.uint64(0)           # bits of acc not yet written
            j = p
            for i in range(n):
                x = np.int64(v[i])
                u = code if x == fill else np.uint64(x - lo)
                acc = (acc << bits) | u
                held += bits
                if held >= _U32:
                    held -= _U32
                    w = acc >> held
                    out[j] = (w >> np.uint64(24)) & _BYTE
                    out[j + 1] = (w >> np.uint64(16)) & _BYTE
                    out[j + 2] = (w >> _U8) & _BYTE
                    out[j + 3] = w & _BYTE
                    j += 4
            while held >= _U8:
                held -= _U8
                out[j] = (acc >> held) & _BYTE
                j += 1
            if held > 0:
                out[j] = (acc << (_U8 - held)) & _BYTE
            pos = p + size
        ends[c + 1] = pos
