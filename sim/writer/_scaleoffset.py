"""HDF5's integer scale-offset filter done here, for whole chunks written with
:meth:`h5py.h5d.DatasetID.write_direct_chunk`: the bytes HDF5's own filter would store.

Why by hand: the IMU pulses (``scaleoffset=0``, :mod:`rlgsim.sim.writer.schema`) are most of a
run's file, and HDF5's filter (``H5Zscaleoffset.c``) packs them one byte of one value at a time
through function calls, ~2 ns per value in the writer thread — 0.55 s of CPU in a 43.4 M-epoch
paper000 run (perf). The compiled loop (:mod:`rlgsim.sim.writer._scaleoffset_kernel`) does the same
in a fraction of that; :func:`_encode_numpy` is its NumPy reference (same bytes).

The encoding (HDF5 ``H5Zscaleoffset.c``, integer class, minimum bits computed per chunk —
h5py's ``scaleoffset=0``, ``H5Z_SO_INT`` with ``H5Z_SO_INT_MINBITS_DEFAULT``) of one chunk of n
values of s bytes (B = 8·s bits), with the dataset's fill value f (h5py's datasets always have
one: 0 unless ``fillvalue`` is given):

* min and max over the values ≠ f (both 0 when every value is f);
* max − min > 2^B − 3: ``minbits`` = B and ``minval`` = 0; otherwise ``minbits`` =
  ⌈log2(max − min + 2)⌉ (one code more than the span, for f) and ``minval`` = min;
* a 21-byte header: ``minbits`` (uint32, little-endian), 8 (the size of ``minval``),
  ``minval`` (8 bytes little-endian, sign-extended), 8 zero bytes;
* ``minbits`` = B: the chunk's raw bytes follow (21 + n·s bytes);
* otherwise each value becomes u = 2^minbits − 1 where it equals f, else value − min, and the
  ``minbits`` low bits of each u follow, most significant first, the values back to back from
  the first byte's high bit, zero-padded: 21 + ⌊n·minbits/8⌋ + 1 bytes (HDF5 always adds the
  byte).

Not handled (:func:`codec_of` returns None and HDF5's filter writes those chunks): an undefined
fill value (``minbits`` may be 0 and HDF5 then leaves the extra byte uninitialised), a fixed
``minbits``, 8-byte or big-endian integers, any other filter in the pipeline.
"""

from __future__ import annotations

import functools
import sys
from dataclasses import dataclass

import h5py
import numpy as np

#: HDF5's filter id of scale-offset (``H5Z_FILTER_SCALEOFFSET``) and its parameter layout
#: (``cd_values``: scale type, scale factor, elements per chunk, class, size, sign, order,
#: fill-value-defined flag, then the fill value's bytes, 4 per entry, least significant first).
FILTER_ID = 6
_SO_INT = 2                  # H5Z_SO_INT
_CLASS_INTEGER = 0
_ORDER_LE = 0
_FILL_DEFINED = 1
#: Bytes of the header before the packed values.
HEADER = 21


@dataclass(frozen=True)
class Codec:
    """One dataset's scale-offset parameters: its dtype (native little-endian integer of at
    most 4 bytes), its fill value and the elements per chunk."""

    dtype: np.dtype
    fill: int
    chunk_elements: int


def codec_of(ds: h5py.Dataset) -> Codec | None:
    """The :class:`Codec` of a dataset whose only filter is HDF5's integer scale-offset with the
    minimum bits computed per chunk and a defined fill value — else None."""
    dt = ds.dtype
    if dt.kind not in "iu" or dt.itemsize > 4 or (dt.itemsize > 1 and dt.byteorder == ">") \
            or sys.byteorder != "little" or ds.chunks is None:
        return None
    dcpl = ds.id.get_create_plist()
    if dcpl.get_nfilters() != 1:
        return None
    fid, _flags, cd, _name = dcpl.get_filter(0)
    if fid != FILTER_ID or len(cd) < 9:
        return None
    n = int(np.prod(ds.chunks, dtype=np.int64))
    if (cd[0] != _SO_INT or cd[1] != 0 or cd[2] != n or cd[3] != _CLASS_INTEGER
            or cd[4] != dt.itemsize or cd[5] != (1 if dt.kind == "i" else 0)
            or cd[6] != _ORDER_LE or cd[7] != _FILL_DEFINED):
        return None
    word = np.uint32(cd[8]).astype("<u4").tobytes()[:dt.itemsize]
    fill = int(np.frombuffer(word, dtype=dt.newbyteorder("<"))[0])
    return Codec(dtype=np.dtype(dt), fill=fill, chunk_elements=n)


def encode(codec: Codec, chunks: np.ndarray, *, compiled: bool = True
           ) -> tuple[np.ndarray, np.ndarray]:
    """Encode ``chunks`` (k whole chunks: k·rows rows of the dataset's shape, C order, the
    dataset's dtype) as HDF5's filter would: returns ``(buf, ends)``, chunk j's stored bytes
    ``buf[ends[j]:ends[j + 1]]``. ``compiled``: the numba loop
    (:func:`rlgsim.sim.writer._scaleoffset_kernel.encode_chunks`); False: :func:`_encode_numpy`."""
    if compiled:
        from rlgsim.sim.writer._scaleoffset_kernel import encode_chunks
        args = encode_args(codec, chunks)
        encode_chunks(*args)
        return args[-2], args[-1]
    n = codec.chunk_elements
    values = np.ascontiguousarray(chunks, dtype=codec.dtype).reshape(-1, n)
    k = values.shape[0]
    raw = values.view(np.uint8).reshape(k, n * codec.dtype.itemsize)
    ends = np.empty(k + 1, dtype=np.int64)
    out = np.empty(k * (n * codec.dtype.itemsize + HEADER + 1), dtype=np.uint8)
    _encode_numpy(values, raw, codec.fill, out, ends)
    return out, ends


def encode_args(codec: Codec, chunks: np.ndarray) -> tuple:
    """The arguments of :func:`rlgsim.sim.writer._scaleoffset_kernel.encode_chunks` for
    ``chunks`` (as :func:`encode` takes them): ``(values, raw, fill, top, bottom, out, ends)``,
    ``out`` and ``ends`` new and still to be filled."""
    from rlgsim.sim.writer._scaleoffset_kernel import SLACK
    n = codec.chunk_elements
    values = np.ascontiguousarray(chunks, dtype=codec.dtype).reshape(-1, n)
    k = values.shape[0]
    raw = values.view(np.uint8).reshape(k, n * codec.dtype.itemsize)
    ends = np.empty(k + 1, dtype=np.int64)
    out = np.empty(k * (n * codec.dtype.itemsize + HEADER + 1) + SLACK, dtype=np.uint8)
    return (values, raw, *_scalars(codec), out, ends)


@functools.lru_cache(maxsize=None)
def _scalars(codec: Codec) -> tuple[np.integer, np.integer, np.integer]:
    """The fill value, largest and smallest value of ``codec``'s type, as scalars of that type
    (what :func:`rlgsim.sim.writer._scaleoffset_kernel.encode_chunks` takes)."""
    kind, info = codec.dtype.type, np.iinfo(codec.dtype)
    return kind(codec.fill), kind(info.max), kind(info.min)


def _encode_numpy(values: np.ndarray, raw: np.ndarray, fill: int, out: np.ndarray,
                  ends: np.ndarray) -> None:
    """:func:`rlgsim.sim.writer._scaleoffset_kernel.encode_chunks` in NumPy (its reference: the same
    bytes), one chunk at a time."""
    k, n = values.shape
    width = 8 * values.dtype.itemsize
    pos = 0
    ends[0] = 0
    for c in range(k):
        x = values[c].astype(np.int64)
        keep = x != fill
        lo, hi = (int(x[keep].min()), int(x[keep].max())) if keep.any() else (0, 0)
        if hi - lo > (1 << width) - 3:
            minbits, minval = width, 0
        else:
            minbits, minval = int(hi - lo + 1).bit_length(), lo     # ⌈log2(max − min + 2)⌉
        head = (np.array([minbits], "<u4").tobytes() + bytes([8])
                + np.array([minval], "<i8").tobytes() + bytes(8))
        if minbits == width:
            body = raw[c].tobytes()
        else:
            u = np.where(keep, x - lo, (1 << minbits) - 1).astype(np.uint64)
            shifts = np.arange(minbits - 1, -1, -1, dtype=np.uint64)
            bits = ((u[:, None] >> shifts) & np.uint64(1)).astype(np.uint8)
            body = np.packbits(bits.ravel()).tobytes()
            body += bytes(n * minbits // 8 + 1 - len(body))
        chunk = head + body
        out[pos:pos + len(chunk)] = np.frombuffer(chunk, dtype=np.uint8)
        pos += len(chunk)
        ends[c + 1] = pos
