"""Datasets and text attributes made and written with h5py's low-level calls: the file h5py's
high level makes.

The simulator lays out ~75 datasets per run (coordinates, parameters, growing series) before
its first block; through ``create_dataset`` each costs ~0.1 ms, ~60 % of it h5py's argument
checks and the creation property list built anew. :func:`new_dataset_id` makes the same HDF5
calls with the same property values — h5py's ``make_new_dset`` (h5py/_hl/dataset.py) is the
reference, and the tests compare the files' bytes (tests/test_dataset.py) — with each property
list built once per process. Only what the writer uses is covered (chunked growing datasets,
the scale-offset filter, fixed numeric and text data); anything else goes through h5py.

:func:`write_rows` writes rows the way ``Dataset.write_direct`` does, with the same H5Dwrite;
:func:`set_attr` writes a text attribute the way ``obj.attrs[name] = text`` does
(:class:`TextAttributes`), also on a bare dataset identifier (:class:`DatasetAttrs`).
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

_STR = h5py.string_dtype("utf-8")

#: dataset creation property lists by (chunk shape, scale-offset filter, dtype kind), built once
#: per process (:func:`new_dataset_id`)
_DCPL: dict[tuple, Any] = {}
#: h5py's file types of the dtypes datasets are made with (``h5t.py_create(dtype, logical=1)``)
_FILE_TYPES: dict[Any, Any] = {}
#: h5py's memory types of the arrays written at creation (``h5t.py_create(dtype)``, what
#: ``DatasetID.write`` makes when given none)
_MEMORY_TYPES: dict[Any, Any] = {}
#: dataspaces by (shape, maxshape): HDF5 copies the one H5Dcreate is given, so one serves every
#: dataset of that shape (a run makes ~75 datasets of ~15 shapes)
_SPACES: dict[tuple, Any] = {}


def new_dataset_id(group: h5py.Group, name: str, shape: tuple[int, ...], dtype: Any, *,
                   maxshape: tuple | None = None, chunks: tuple[int, ...] | None = None,
                   scaleoffset: int | None = None, data: np.ndarray | None = None
                   ) -> Any:
    """``group.create_dataset(name, shape, dtype, data=data, maxshape=…, chunks=…,
    scaleoffset=…, track_times=False)`` with h5py's default ``track_order`` — the same HDF5
    calls with the same property values (h5py's ``make_new_dset``: H5Pset_chunk, the
    scale-offset filter, H5Pset_obj_track_times, H5Pset_attr_creation_order, H5Dcreate2 and
    H5Dwrite of ``data``), so the file's bytes are the same, without h5py's per-call argument
    checks and property-list building (~0.06 ms of the ~0.1 ms a call costs through
    ``create_dataset``; a run lays out ~75 datasets). ``data`` must already be what h5py would
    write (a C-contiguous array; text as an object array viewed with h5py's string dtype).
    Returns the new dataset's ``h5py.h5d.DatasetID`` (an ``h5py.Dataset`` object would cost
    ~20 µs more)."""
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
        sid = _SPACES.get((shape, maxshape))
        if sid is None:
            sid = _SPACES[(shape, maxshape)] = h5s.create_simple(shape, maxshape)
        dsid = h5d.create(group.id, name.encode("utf-8"), tid, sid, dcpl=dcpl)
        if data is not None:
            mtype = _MEMORY_TYPES.get(data.dtype)
            if mtype is None:
                mtype = _MEMORY_TYPES[data.dtype] = h5t.py_create(data.dtype)
            dsid.write(h5s.ALL, h5s.ALL, data, mtype=mtype)
        return dsid


def plain_name(name: str) -> bool:
    """Whether h5py would create ``name`` in the group itself (no path, no intermediate
    groups): the only names :func:`new_dataset_id` takes."""
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


class TextAttributes:
    """Text attributes written as h5py's ``obj.attrs[name] = text`` writes them — a scalar
    variable-length UTF-8 string, the same HDF5 calls (an existing one deleted, H5Acreate,
    H5Awrite, H5Aclose) with the same types — without the per-call type guessing and
    conversion of h5py's high-level path: ~0.02 ms an attribute instead of ~0.07 ms, and a run
    writes ~170 of them (``units``, ``description``) while it lays out its file."""

    def __init__(self) -> None:
        from h5py import h5s, h5t
        self._file_type = h5t.py_create(_STR, logical=True)   # as AttributeManager.create
        self._memory_type = h5t.py_create(_STR)
        self._space = h5s.create_simple(())

    def write(self, obj_id: Any, name: str, text: str) -> None:
        from h5py import h5a
        key = name.encode("ascii")
        data = np.asarray(np.asarray(text, dtype=_STR), dtype=_STR)
        if h5a.exists(obj_id, key):
            h5a.delete(obj_id, key)
        attr = h5a.create(obj_id, key, self._file_type, self._space)
        try:
            attr.write(data, mtype=self._memory_type)
        except BaseException:
            attr.close()
            h5a.delete(obj_id, key)
            raise
        attr.close()


_TEXT_ATTRIBUTES: TextAttributes | None = None


def set_attr(obj: Any, name: str, value: Any) -> None:
    """``obj.attrs[name] = value`` — text with an ASCII name through :class:`TextAttributes`
    (the same attribute, faster), anything else through h5py."""
    global _TEXT_ATTRIBUTES
    if type(value) is str and name.isascii():
        if _TEXT_ATTRIBUTES is None:
            _TEXT_ATTRIBUTES = TextAttributes()
        with h5py._objects.phil:                  # h5py's lock, as its own attrs path holds
            _TEXT_ATTRIBUTES.write(obj.id, name, value)
    else:
        obj.attrs[name] = value


class DatasetAttrs:
    """A dataset's identifier where :func:`set_attr` takes an h5py object: ``id`` for text
    attributes, ``attrs`` (an ``h5py.Dataset``'s, made only then) for anything else."""

    __slots__ = ("id",)

    def __init__(self, dsid: Any) -> None:
        self.id = dsid

    @property
    def attrs(self) -> Any:
        return h5py.Dataset(self.id).attrs
