"""Whole chunks handed to HDF5's ``H5Dwrite_chunk`` from compiled code, without Python's GIL.

Why by hand: h5py's ``DatasetID.write_direct_chunk`` holds the GIL through the whole HDF5 call —
the chunk index update, the file space allocation and the ``pwrite`` into the page cache, ~6.5
µs a chunk — so while the writer thread writes, the main thread (the simulator's Python between
its compiled kernels) and the normals worker wait for the GIL; paper000_ramp's writer writes
~21 000 chunks a run, ~0.14 s of GIL. :func:`write_chunks` makes the same HDF5 call, chunk after
chunk of one write, from a numba loop that has released the GIL (a scale-offset dataset's
chunks encoded in the same call: :func:`encode_and_write`), through ``H5Dwrite_chunk`` of the
HDF5 library h5py loaded, bound by name (:func:`available`). It makes exactly the calls
``write_direct_chunk`` makes to write (``H5Dwrite_chunk`` with the default transfer properties,
no filter mask), in the same order, so the file is the same, byte for byte.

HDF5 is not thread-safe: h5py makes every HDF5 call under its lock (``h5py._objects.phil``; the
objects' deallocation too), and :func:`write_chunks`' caller holds that lock for the whole loop
(:meth:`rlgsim.sim.writer._direct_chunks.DirectChunks.write`), so no other thread enters HDF5
meanwhile. Only where h5py's wheel carries its own HDF5 (``h5py.libs/libhdf5-*.so``: one library,
the one h5py's modules are linked to) of a release whose signature was checked is the function
bound; elsewhere :func:`available` is False and h5py's call stays. The direct path's
self-check (:mod:`rlgsim.sim.writer._direct_check`) writes its files through this path too, so
a library that behaved differently would turn the whole direct path off for the process.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os

import llvmlite.binding as _llvm
import numpy as np
from numba import njit, types

from rlgsim.sim.writer._scaleoffset_kernel import encode_chunks

#: the HDF5 releases whose ``H5Dwrite_chunk`` has the signature below (1.10 to 2.0; 2.0.0 is
#: the library h5py 3.16's wheel carries): another release keeps h5py's own call
_CHECKED_RELEASES = ((1, 10), (2, 0))
#: the name the compiled calls link to (bound to the library's function by :func:`available`)
_SYMBOL = "rlgsim_H5Dwrite_chunk"

# H5Dwrite_chunk(hid_t dset, hid_t dxpl, uint32_t filters, const hsize_t *offset,
#                size_t size, const void *buf) -> herr_t; pointers passed as integers (the same
# register in the C calling convention), as sim/thermal/_heater_kernel.py passes numpy's BLAS
_h5d_write_chunk = types.ExternalFunction(_SYMBOL, types.int32(
    types.int64, types.int64, types.uint32, types.uintp, types.uintp, types.uintp))


@functools.cache
def available() -> bool:
    """Whether the compiled calls can be made: ``H5Dwrite_chunk`` found in the HDF5 library
    h5py's wheel carries (the library its modules use), of a checked release and the release
    h5py reports, and bound to the name the kernels link to (False: h5py's own call stays)."""
    fn = _find()
    if fn is None:
        return False
    _llvm.add_symbol(_SYMBOL, fn)
    return True


def _find() -> int | None:
    """The address of ``H5Dwrite_chunk`` (see :func:`available`), or None."""
    import h5py
    libs = glob.glob(os.path.join(os.path.dirname(os.path.dirname(h5py.__file__)),
                                  "h5py.libs", "libhdf5-*.so*"))
    if len(libs) != 1:
        return None
    try:
        lib = ctypes.CDLL(libs[0])          # already loaded by h5py: the same library
        major, minor, release = (ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint())
        lib.H5get_libversion(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(release))
        version = (major.value, minor.value, release.value)
        if version != h5py.version.hdf5_version_tuple[:3] \
                or not _CHECKED_RELEASES[0] <= version[:2] <= _CHECKED_RELEASES[1]:
            return None
        return ctypes.cast(lib.H5Dwrite_chunk, ctypes.c_void_p).value
    except (OSError, AttributeError):
        return None


@njit(cache=True, nogil=True)
def write_chunks(dset, first_row, rows, rank, buf, ends, first):  # pragma: no cover
    """Chunks ``first`` … ``len(ends) − 2`` of ``buf`` (chunk j: ``buf[ends[j]:ends[j + 1]]``,
    at row ``first_row + j·rows`` and 0 along the other ``rank − 1`` dimensions) to dataset
    ``dset`` through ``H5Dwrite_chunk(dset, H5P_DEFAULT = 0, no filter mask, …)`` (only after
    :func:`available` returned True). Returns −1, or the first chunk HDF5 refused (nothing
    after it is written)."""
    offset = np.zeros(rank, dtype=np.uint64)
    base = buf.ctypes.data
    for j in range(first, ends.shape[0] - 1):
        offset[0] = np.uint64(first_row + j * rows)
        if _h5d_write_chunk(dset, 0, 0, offset.ctypes.data, ends[j + 1] - ends[j],
                            base + ends[j]) < 0:
            return j
    return -1


@njit(cache=True, nogil=True)
def encode_and_write(values, raw, fill, top, bottom, out, ends, dset, first_row, rows, rank,
                     first):  # pragma: no cover
    """:func:`rlgsim.sim.writer._scaleoffset_kernel.encode_chunks` (its first seven arguments)
    and then :func:`write_chunks` of the encoded chunks, in one call without the GIL (one hand-off
    of the GIL a write instead of two). Returns what :func:`write_chunks` returns."""
    encode_chunks(values, raw, fill, top, bottom, out, ends)
    return write_chunks(dset, first_row, rows, rank, out, ends, first)
