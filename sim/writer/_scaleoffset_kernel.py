"""Compiled loop of :func:`rlgsim.sim.writer._scaleoffset.encode` (numba): HDF5's integer scale-offset
encoding of whole chunks, the same bytes as HDF5's own filter (:mod:`rlgsim.sim.writer._scaleoffset`
states the format and why it is done here).

One call encodes every chunk of a write. Per chunk: the minimum and maximum of the values other
than the fill value, then every value's code (value − min, or all ones for the fill value) —
two loops the compiler vectorises — then the bit packing (:func:`_pack`): the codes' ``minbits``
low bits, most significant first, joined a few values at a time and shifted into a 64-bit
accumulator that is emptied 32 bits at a time. ~4-6 µs per chunk of 12 288 values (2-16 bits
each) against ~26 µs in HDF5's filter, which moves the bits one byte of one value at a time
through function calls. The accumulator, the bit counts and the indices are unsigned 64-bit
throughout (numba turns a mix of signed and unsigned integers into floats).

Bit for bit :func:`rlgsim.sim.writer._scaleoffset._encode_numpy` and HDF5's filter
(tests/test_scaleoffset.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

_1, _2, _3, _4, _5, _6, _7 = (np.uint64(k) for k in range(1, 8))
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
    u = np.empty(n, dtype=np.uint32)
    for c in range(k):
        v = values[c]
        lo = np.int64(9223372036854775807)
        hi = np.int64(-9223372036854775807 - 1)
        for i in range(n):
            x = np.int64(v[np.uint64(i)])
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
            code = np.uint32((1 << minbits) - 1)
            for i in range(n):            # the codes, in a loop the compiler vectorises
                ui = np.uint64(i)
                x = np.int64(v[ui])
                u[ui] = code if x == fill else np.uint32(x - lo)
            _pack(u, n, minbits, out, p, size)
            pos = p + size
        ends[c + 1] = pos


@njit(cache=True, nogil=True)
def _pack(u, n, minbits, out, p, size):  # pragma: no cover
    """The ``minbits`` (< 32) low bits of each ``u[:n]``, most significant first, into
    ``out[p:p + size]`` (``size`` = ⌊n·minbits/8⌋ + 1: the last byte is HDF5's extra one).

    Values are joined in groups of g (8, 4, 2 or 1: the most with g·minbits ≤ 32) before they
    enter the accumulator — one shift-or of the accumulator per group, the loop-carried chain
    — and every index is unsigned (numba adds a negative-index wrap-around to a signed index
    it cannot prove non-negative: ~40 % of this loop's time)."""
    out[p + size - 1] = 0
    bits = np.uint64(minbits)
    acc = np.uint64(0)
    held = np.uint64(0)                   # bits of acc not yet written
    j = np.uint64(p)
    i = np.uint64(0)
    nn = np.uint64(n)
    if minbits <= 4:
        b2 = bits + bits
        b4 = b2 + b2
        b8 = b4 + b4
        while i + _U8 <= nn:
            q = (((((np.uint64(u[i]) << bits) | np.uint64(u[i + _1])) << b2)
                  | ((np.uint64(u[i + _2]) << bits) | np.uint64(u[i + _3]))) << b4) \
                | (((np.uint64(u[i + _4]) << bits) | np.uint64(u[i + _5])) << b2) \
                | ((np.uint64(u[i + _6]) << bits) | np.uint64(u[i + _7]))
            acc = (acc << b8) | q
            held += b8
            if held >= _U32:
                held -= _U32
                j = _put32(out, j, acc >> held)
            i += _U8
    elif minbits <= 8:
        b2 = bits + bits
        b4 = b2 + b2
        while i + _4 <= nn:
            q = (((np.uint64(u[i]) << bits) | np.uint64(u[i + _1])) << b2) \
                | ((np.uint64(u[i + _2]) << bits) | np.uint64(u[i + _3]))
            acc = (acc << b4) | q
            held += b4
            if held >= _U32:
                held -= _U32
                j = _put32(out, j, acc >> held)
            i += _4
    elif minbits <= 16:
        b2 = bits + bits
        while i + _2 <= nn:
            acc = (acc << b2) | ((np.uint64(u[i]) << bits) | np.uint64(u[i + _1]))
            held += b2
            if held >= _U32:
                held -= _U32
                j = _put32(out, j, acc >> held)
            i += _2
    while i < nn:
        acc = (acc << bits) | np.uint64(u[i])
        held += bits
        if held >= _U32:
            held -= _U32
            j = _put32(out, j, acc >> held)
        i += _1
    while held >= _U8:
        held -= _U8
        out[j] = (acc >> held) & _BYTE
        j += _1
    if held > 0:
        out[j] = (acc << (_U8 - held)) & _BYTE


@njit(cache=True, nogil=True, inline="always")
def _put32(out, j, w):  # pragma: no cover
    """The low 32 bits of ``w`` into ``out[j:j + 4]``, most significant byte first; j + 4."""
    out[j] = (w >> np.uint64(24)) & _BYTE
    out[j + _1] = (w >> np.uint64(16)) & _BYTE
    out[j + _2] = (w >> _U8) & _BYTE
    out[j + _3] = w & _BYTE
    return j + _4
