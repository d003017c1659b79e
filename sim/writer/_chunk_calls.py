"""Whole chunks handed to HDF5's ``H5Dwrite_chunk`` from compiled code, without Python's GIL.

Why by hand: h5py's ``DatasetID.write_direct_chunk`` holds the GIL through the whole HDF5 call —
the chunk index update, the file space allocation and the ``pwrite`` into the page cache, ~6.5
µs a chunk — so while the writer thread writes, the main thread (the simulator's Python between
its compiled kernels) and the normals worker wait for the GIL; paper000_ramp's writer writes
~21 000 chunks a run, ~0.14 s of GIL. :func:`write_chunks` makes the same HDF5 call, chunk after
chunk of one write, from a numba loop that has released the GIL (a scale-offset dataset's
chunks encoded in the same call: :func:`encode_and_write`), through the address of
``H5Dwrite_chunk`` in the HDF5 library h5py loaded (:func:`address`). It makes exactly the calls
``write_direct_chunk`` makes to write (``H5Dwrite_chunk`` with the default transfer
properties, no filter mask), in the same order, so the file is the same, byte for byte.

HDF5 is not thread-safe: h5py makes every HDF5 call under its lock (``h5py._objects.phil``; the
objects' deallocation too), and :func:`write_chunks`' caller holds that lock for the whole loop
(:meth:`rlgsim.sim.writer._direct_chunks.DirectChunks.write`), so no other thread enters HDF5
meanwhile. Only where h5py's wheel carries its own HDF5 (``h5py.libs/libhdf5-*.so``: one library,
the one h5py's modules are linked to) is the address taken; elsewhere :func:`address` returns
None and h5py's call stays. The direct path's self-check (:mod:`rlgsim.sim.writer._direct_check`)
writes its files through this path too, so a library that behaved differently would turn the
whole direct path off for the process.
"""

from __future__ import annotations

import ctypes
import glob
import os
import threading

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from rlgsim.sim.writer._scaleoffset_kernel import encode_chunks

_ADDRESS: int | None = None
_LOOKED = False
_LOCK = threading.Lock()


def address() -> int | None:
    """The address of ``H5Dwrite_chunk`` in the HDF5 library h5py's wheel carries (the library
    its modules use), or None (another h5py build: h5py's own call stays)."""
    global _ADDRESS, _LOOKED
    with _LOCK:
        if not _LOOKED:
            _LOOKED = True
            _ADDRESS = _find()
    return _ADDRESS


def _find() -> int | None:
    import h5py
    libs = glob.glob(os.path.join(os.path.dirname(os.path.dirname(h5py.__file__)),
                                  "h5py.libs", "libhdf5-*.so*"))
    if len(libs) != 1:
        return None
    try:
        lib = ctypes.CDLL(libs[0])          # already loaded by h5py: the same library
        major, minor, release = (ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint())
        lib.H5get_libversion(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(release))
        if (major.value, minor.value, release.value) != h5py.version.hdf5_version_tuple[:3]:
            return None
        return ctypes.cast(lib.H5Dwrite_chunk, ctypes.c_void_p).value
    except (OSError, AttributeError):
        return None


@intrinsic
def _h5d_write_chunk(typingctx, fn, dset, offset, size, buf):
    """``H5Dwrite_chunk(dset, H5P_DEFAULT, 0, offset, size, buf)`` through the function address
    ``fn`` (all arguments int64; ``offset`` and ``buf`` addresses): HDF5's return value."""
    sig = types.int32(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        fn_, dset_, offset_, size_, buf_ = args
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.IntType(32), [ir.IntType(64), ir.IntType(64), ir.IntType(32),
                                                 i8p, ir.IntType(64), i8p])
        target = builder.inttoptr(fn_, fnty.as_pointer())
        return builder.call(target, [dset_, ir.Constant(ir.IntType(64), 0),   # H5P_DEFAULT
                                     ir.Constant(ir.IntType(32), 0),          # no filter mask
                                     builder.inttoptr(offset_, i8p), size_,
                                     builder.inttoptr(buf_, i8p)])
    return sig, codegen


@njit(cache=True, nogil=True)
def write_chunks(fn, dset, first_row, rows, rank, buf, ends, first):  # pragma: no cover
    """Chunks ``first`` … ``len(ends) − 2`` of ``buf`` (chunk j: ``buf[ends[j]:ends[j + 1]]``,
    at row ``first_row + j·rows`` and 0 along the other ``rank − 1`` dimensions) to dataset
    ``dset`` through ``H5Dwrite_chunk`` at address ``fn``. Returns −1, or the first chunk HDF5
    refused (nothing after it is written)."""
    offset = np.zeros(rank, dtype=np.uint64)
    where = np.int64(offset.ctypes.data)   # addresses as int64 (numba makes uint64 + int64 a float)
    base = np.int64(buf.ctypes.data)
    for j in range(first, ends.shape[0] - 1):
        offset[0] = np.uint64(first_row + j * rows)
        if _h5d_write_chunk(fn, dset, where, ends[j + 1] - ends[j], base + ends[j]) < 0:
            return j
    return -1


@njit(cache=True, nogil=True)
def encode_and_write(values, raw, fill, top, bottom, out, ends, fn, dset, first_row, rows,
                     rank, first):  # pragma: no cover
    """:func:`rlgsim.sim.writer._scaleoffset_kernel.encode_chunks` (its first seven arguments)
    and then :func:`write_chunks` of the encoded chunks, in one call without the GIL (one hand-off
    of the GIL a write instead of two). Returns what :func:`write_chunks` returns."""
    encode_chunks(values, raw, fill, top, bottom, out, ends)
    return write_chunks(fn, dset, first_row, rows, rank, out, ends, first)
