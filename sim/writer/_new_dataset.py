"""Datasets made and written with h5py's low-level calls: the file h5py's high level makes.

The simulator lays out ~75 datasets per run (coordinates, parameters, growing series) before
its first block; through ``create_dataset`` each costs ~0.1 ms, ~60 % of it h5py's argument
checks and the creation property list built anew. :func:`new_dataset` makes the same HDF5
calls with the same property values — h5py's ``make_new_dset`` (h5py/_hl/dataset.py) is the
reference, and the tests compare the files' bytes (tests/test_dataset.py) — with each property
list built once per process. Only what the writer uses is covered (chunked growing datasets,
the scale-offset filter, fixed numeric and text data); anything else goes through h5py.

:func:`write_rows` writes rows the way ``Dataset.write_direct`` does, with the same H5Dwrite.
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

#: dataset creation property lists by (chunk shape, scale-offset filter, dtype kind), built once
#: per process (:func:`new_dataset`)
_DCPL: dict[tuple, Any] = {}
#: h5py's file types of the dtypes datasets are made with (``h5t.py_create(dtype, logical=1)``)
_FILE_TYPES: dict[Any, Any] = {}


def new_dataset(group: h5py.Group, name: str, shape: tuple[int, ...], dtype: Any, *,
                maxshape: tuple | None = None, chunks: tuple[int, ...] | None = None,
                scaleoffset: int | None = None, data: np.ndarray | None = None
                ) -> h5py.Dataset:
    """``group.create_dataset(name, shape, dtype, data=data, maxshape=…, chunks=…,
    scaleoffset=…, track_times=False)`` with h5py's default ``track_order`` — the same HDF5
    calls with the same property values (h5py's ``make_new_dset``: H5Pset_chunk, the
    scale-offset filter, H5Pset_obj_track_times, H5Pset_attr_creation_order, H5Dcreate2 and
    H5Dwrite of ``data``), so the file's bytes are the same, without h5py's per-call argument
    checks and property-list building (~0.06 ms of the ~0.1 ms a call costs through
    ``create_dataset``; a run lays out ~75 datasets). ``data`` must already be what h5py would
    write (a C-contiguous array; text as an object array viewed with h5py's string dtype)."""
    from h5py import h5d, h5p, h5s, h5t, h5z
    dtype = np.dtype(dtype)
    key = (chunks, scaleoffset, dtype.kind if scaleoffset is not None else None)
    with h5py._objects.phil:
        dcpl = _DCPL.get(key)
        if dcpl is None:
            dcpl = h5p.create(h5p.DATASET_CREATE)
            if chunks is not None:
                dcpl.set_chunk(chunks)
            if scaleoffset is not None:
                dcpl.set_scaleoffset(h5z.SO_INT if dtype.kind in "ui" else h5z.SO_FLOAT_DSCALE,
                                     scaleoffset)
            dcpl.set_obj_track_times(False)
            dcpl.set_attr_creation_order(0)
            _DCPL[key] = dcpl
        tid = _FILE_TYPES.get(dtype)
        if tid is None:
            tid = _FILE_TYPES[dtype] = h5t.py_create(dtype, logical=1)
        if maxshape is not None:
            maxshape = tuple(h5s.UNLIMITED if m is None else m for m in maxshape)
        sid = h5s.create_simple(shape, maxshape)
        dsid = h5d.create(group.id, name.encode("utf-8"), tid, sid, dcpl=dcpl)
        if data is not None:
            dsid.write(h5s.ALL, h5s.ALL, data)
        return h5py.Dataset(dsid)


def plain_name(name: str) -> bool:
    """Whether h5py would create ``name`` in the group itself (no path, no intermediate
    groups): the only names :func:`new_dataset` takes."""
    return bool(name) and "/" not in name


def write_rows(ds: h5py.Dataset, data: np.ndarray, row: int) -> None:
    """``ds.write_direct(data, dest_sel=np.s_[row:row + len(data)])`` — the same H5Dwrite (a
    memory space of ``data``'s shape, the file space's hyperslab of those rows over the whole
    trailing dimensions, default transfer properties) without h5py's selection objects (~20
    µs a call instead of ~45; a run makes one per growing dataset at its commit). ``data``
    C-contiguous, ``ds`` already extended over the rows."""
    from h5py import h5s
    k = data.shape[0]
    with h5py._objects.phil:
        dsid = ds.id
        fspace = dsid.get_space()
        fspace.select_hyperslab((row,) + (0,) * (data.ndim - 1), (k,) + data.shape[1:])
        dsid.write(h5s.create_simple(data.shape), fspace, data)
