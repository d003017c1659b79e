"""Compiled loop of :func:`rlgsim.sim.writer._scaleoffset.encode` (numba): HDF5's integer scale-offset
encoding of whole chunks, the same bytes as HDF5's own filter (:mod:`rlgsim.sim.writer._scaleoffset`
states the format and why it is done here).

One call encodes every chunk of a write. Per chunk: the minimum and maximum of the values other
than the fill value, in the values' own type (a loop the compiler vectorises: 16 int32 lanes),
then the codes (value − min, or all ones for the fill value) and their bit packing. A chunk's
codes of ``minbits`` < 16 bits are packed without a loop-carried chain: every 8 codes make
exactly ``minbits`` bytes, so pairs of codes are joined first (2·minbits bits, computed with the
codes), then pairs of pairs (4·minbits bits, in 64-bit words), and each group of 8 is written as
one or two big-endian 64-bit stores at its own byte offset (the bytes past the group's ``minbits``
are overwritten by the next group, or by the next chunk's header). What is left — the last
n mod 8 codes, and every code of a chunk of 16 bits or more — goes through the serial packer
(:func:`_pack`) from that byte boundary. ~4-6 µs per chunk of 12 288 values (2-11 bits: the
paper000_ramp pulses) against ~9 µs for the serial packer alone and ~26 µs in HDF5's filter,
which moves the bits one byte of one value at a time through function calls. Indices, shifts and
words are unsigned 64-bit throughout (numba turns a mix of signed and unsigned integers into
floats, and adds a negative-index wrap-around to a signed index).

Bit for bit :func:`rlgsim.sim.writer._scaleoffset._encode_numpy` and HDF5's filter
(tests/test_scaleoffset.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

_1, _2, _3, _4, _5, _6, _7 = (np.uint64(k) for k in range(1, 8))
_U8 = np.uint64(8)
_U32 = np.uint64(32)
_U64 = np.uint64(64)
_BYTE = np.uint64(0xFF)
#: bytes :func:`encode_chunks` may write past a chunk's end (a group's last 64-bit stores)
SLACK = 16


@njit(cache=True, nogil=True)
def encode_chunks(values, raw, fill, top, bottom, out, ends):  # pragma: no cover
    """Encode the chunks ``values`` (k, n) (one chunk per row, an integer dtype of at most
    4 bytes, the dataset's byte order = native little-endian) into ``out`` (uint8, at least
    k·(n·s + 22) + :data:`SLACK` bytes, s the item size); chunk j's bytes are
    ``out[ends[j]:ends[j + 1]]`` (``ends`` (k + 1,) int64). ``raw`` (k, n·s) uint8 is the same
    memory as ``values`` (copied as it is when a chunk needs the full width); ``fill`` the
    dataset's fill value, ``top`` and ``bottom`` the largest and smallest values of the type
    (all three scalars of ``values``' type)."""
    k = values.shape[0]
    n = values.shape[1]
    s = raw.shape[1] // n if n > 0 else 1
    width = 8 * s
    pos = 0
    ends[0] = 0
    nn = np.uint64(n)
    u = np.empty(n, dtype=np.uint32)      # codes for the serial packer
    pairs = np.empty(n // 2 + 1, dtype=np.uint32)
    quads = np.empty(n // 4 + 1, dtype=np.uint64)
    for c in range(k):
        v = values[c]
        lo_t = top                        # min and max of the values other than the fill
        hi_t = bottom
        for i in range(n):
            x = v[i]
            is_fill = x == fill
            lo_t = min(lo_t, top if is_fill else x)
            hi_t = max(hi_t, bottom if is_fill else x)
        lo = np.int64(lo_t)
        hi = np.int64(hi_t)
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
            ends[c + 1] = pos
            continue
        size = (n * minbits) // 8 + 1
        code = np.uint32((1 << minbits) - 1)
        # value − min in 32-bit arithmetic modulo 2^32: exact, the span fits in minbits < 32
        lo32 = np.uint32(lo & 0xFFFFFFFF)
        done = np.uint64(0)               # codes packed in whole groups of 8
        if minbits < 16:
            done = _pack_groups(v, fill, code, lo32, minbits, out, np.uint64(p), pairs, quads)
        rest = nn - done
        for i in range(rest):
            x = v[done + i]
            u[i] = code if x == fill else np.uint32(np.uint32(x) - lo32)
        start = np.uint64(p) + done // _U8 * np.uint64(minbits)
        _pack(u, rest, minbits, out, start, np.uint64(p + size) - start)
        pos = p + size
        ends[c + 1] = pos


@njit(cache=True, nogil=True)
def _pack_groups(v, fill, code, lo32, minbits, out, p, pairs, quads):  # pragma: no cover
    """The codes of the whole groups of 8 values of ``v`` (``code`` for the fill value, else
    value − min: ``lo32`` the minimum modulo 2^32), ``minbits`` (< 16) bits each, most
    significant first, into ``out`` from byte ``p`` — ``minbits`` bytes a group, written as one
    or two big-endian 64-bit words (up to :data:`SLACK` bytes past the last group's end).
    ``pairs`` and ``quads`` are scratch (≥ n/2 and n/4 entries). Returns the values packed."""
    groups = np.uint64(v.shape[0]) // _U8
    m = np.uint64(minbits)
    m32 = np.uint32(minbits)
    for i in range(groups * _4):          # pairs of codes: 2·minbits bits
        b = i + i
        x0 = v[b]
        x1 = v[b + _1]
        c0 = code if x0 == fill else np.uint32(np.uint32(x0) - lo32)
        c1 = code if x1 == fill else np.uint32(np.uint32(x1) - lo32)
        pairs[i] = (c0 << m32) | c1
    m2 = m + m
    for i in range(groups * _2):          # pairs of pairs: 4·minbits bits
        quads[i] = (np.uint64(pairs[i + i]) << m2) | np.uint64(pairs[i + i + _1])
    j = p
    if minbits <= 8:                      # 8 codes: one word of 8·minbits ≤ 64 bits
        m4 = m2 + m2
        shift = _U64 - _U8 * m
        for g in range(groups):
            _put64(out, j, ((quads[g + g] << m4) | quads[g + g + _1]) << shift)
            j += m
    else:                                 # 8·minbits bits: the first 64 in one word, the rest next
        s1 = _U64 - _4 * m
        s2 = _U8 * m - _U64
        s3 = np.uint64(128) - _U8 * m
        for g in range(groups):
            h = quads[g + g]
            w = quads[g + g + _1]
            _put64(out, j, (h << s1) | (w >> s2))
            _put64(out, j + _U8, w << s3)
            j += m
    return groups * _U8


@njit(cache=True, nogil=True)
def _put64(out, j, w):  # pragma: no cover
    """The 64 bits of ``w`` into ``out[j:j + 8]``, most significant byte first (one
    byte-swapped store once compiled)."""
    out[j] = (w >> np.uint64(56)) & _BYTE
    out[j + _1] = (w >> np.uint64(48)) & _BYTE
    out[j + _2] = (w >> np.uint64(40)) & _BYTE
    out[j + _3] = (w >> _U32) & _BYTE
    out[j + _4] = (w >> np.uint64(24)) & _BYTE
    out[j + _5] = (w >> np.uint64(16)) & _BYTE
    out[j + _6] = (w >> _U8) & _BYTE
    out[j + _7] = w & _BYTE


@njit(cache=True, nogil=True)
def _pack(u, n, minbits, out, p, size):  # pragma: no cover
    """The ``minbits`` (< 32) low bits of each ``u[:n]``, most significant first, into
    ``out[p:p + size]`` (``size`` = ⌊n·minbits/8⌋ + 1: the last byte is HDF5's extra one; p a
    byte boundary of the chunk's bits).

    One shift-or of a 64-bit accumulator per code, emptied 32 bits at a time: what
    :func:`encode_chunks` leaves to it is short (the last n mod 8 codes of a chunk) or wide
    (16 bits or more a code). Every index is unsigned (numba adds a negative-index wrap-around
    to a signed index it cannot prove non-negative)."""
    out[p + size - 1] = 0
    bits = np.uint64(minbits)
    acc = np.uint64(0)
    held = np.uint64(0)                   # bits of acc not yet written
    j = np.uint64(p)
    i = np.uint64(0)
    nn = np.uint64(n)
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
