"""rlgsim datasets: HDF5 files (h5py) laid out the netCDF-4 way, written by streaming.

Layout (docs/dataset.md is the schema; :mod:`rlgsim.sim.writer.schema` declares every group the
simulator writes): one HDF5 group per part of the simulation (``timeline``, ``thermal``,
``probes``, ``imu``, ``turntable``, ``truth``). Inside a group every dimension has a coordinate
variable that is an HDF5 *dimension scale*, and every variable has its dimensions attached,
exactly as netCDF-4 does it — so each group opens with
``xarray.open_dataset(path, engine="h5netcdf", group="thermal")``. Every variable carries
``units`` and ``description`` attributes. The root carries the format marker
(:data:`rlgsim.ground.dataset_format.FORMAT`, ``FORMAT_VERSION``), the scenario text, seed and
software version.

Writing: :class:`DatasetWriter` opens a temporary file in the target directory
(``<out>.tmp-<pid>``); groups declare their coordinates and variables, then rows are appended
along the growing dimension (``time``) in bounded chunks; :meth:`DatasetWriter.commit` closes
the file and ``os.replace``-s it onto the final path, so a run that fails or is killed never
leaves a file at the output path. HDF5 chunk shapes depend only on a variable's shape, never on
how the caller chunks its appends, so the stored arrays do not depend on the chunk size. The
whole chunks of scale-offset variables (the IMU pulses) are packed by
:mod:`rlgsim.sim.writer._scaleoffset`, and those of unfiltered numeric variables (a vehicle's
``trajectory`` states) taken as they are, and written directly when HDF5's chunk cache would
have written them (:mod:`rlgsim.sim.writer._direct_chunks`): the same bytes as HDF5's path, in a
fraction of its CPU time — once a self-check has shown that with the HDF5 this process loaded
(:mod:`rlgsim.sim.writer._direct_check`; HDF5's filter otherwise).
:func:`add_group` adds (or replaces) a group of an existing dataset (``rlgsim calibrate``).
A run may defer its layout (``DatasetWriter(..., defer_layout=True)``: the file too is made
later): the groups are declared at once — names, fixed dimension sizes and the size estimate's
row bytes taken — their HDF5 calls recorded and made later, in order, by
:meth:`DatasetWriter.lay_out` in the run's writer thread while the first block is computed. A
growing variable over a fixed dimension the group has not declared is refused at once
(ValueError); what only HDF5 checks — a name used twice, a fixed variable over a dimension
that does not exist — fails when ``lay_out`` makes the calls (in the writer thread: the run
raises it at its next block), before any row is written.

Reading: :func:`rlgsim.ground.dataset_format.open_dataset` (the one reader; it checks the
format marker and version); :func:`summary` (:mod:`rlgsim.sim.writer.summary`) is what
``rlgsim info`` prints.

Why this file is over 400 lines: it is the one HDF5 writer — the group writer with its chunk
staging, direct-chunk path and deferred layout, the dataset's life cycle (temporary file,
marker written last, stale temporaries) and ``add_group``, which must agree with it on the
layout; the encoders, the direct-chunk checks, the low-level creation calls, the summary and
the versions are apart (_scaleoffset*.py, _direct_*.py, _new_dataset.py, summary.py, versions.py).
"""

from __future__ import annotations

import contextlib
import importlib.util
import itertools
import math
import os
import pathlib
import sys
import threading
from typing import Any, Callable, Iterable, Iterator, Mapping

import h5py
import numpy as np

from rlgsim.ground.dataset_format import (FORMAT, FORMAT_ATTR, FORMAT_VERSION, INCOMPLETE,
                                          INCOMPLETE_ATTR, VERSION_ATTR)
from rlgsim.ground.paths import check_writable, sweep_temporaries
from rlgsim.sim.writer._new_dataset import (_STR, DatasetAttrs, new_dataset_id, plain_name,
                                           set_attr as _set_attr, write_rows)
from rlgsim.sim.writer.summary import summary  # noqa: F401 - what ``rlgsim info`` prints
from rlgsim.sim.writer.versions import software_version, versions_json_once as _versions_json

#: Target size of one HDF5 chunk [bytes] along the growing dimension.
_CHUNK_BYTES = 1 << 18
#: HDF5's chunk cache [bytes per dataset] of a file the simulator writes: none. The writer hands
#: HDF5 whole chunks only (:class:`_ChunkStage`) and never reads them back, so a cache would only
#: hold each dataset's latest chunks until it needs room or the file closes. With the library's
#: default (8 MiB per dataset since HDF5 2.0, 1 MiB before) a run's resident memory grew with its
#: duration until every growing dataset's cache was full — a 1 Hz float64 series fills 8 MiB in
#: 12 days, so a run kept its slow series whole: ~1.8 MB per simulated hour on the land route and
#: on a static run (benchmarks/bench_sim_memory.py). With no cache each chunk gets its file space
#: when it is written, in the order of writing: the file's layout (not its content, format or
#: determinism) differs from a file written with the cache.
CHUNK_CACHE_BYTES = 0
#: NAME of a netCDF-4 dimension scale that is not a variable (netCDF-C / h5netcdf convention).
_NOT_A_VARIABLE = "This is a netCDF dimension but not a netCDF variable."


def _attr_value(value: Any) -> Any:
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return np.int8(value)
    if value is None:
        return ""
    return value


class GroupWriter:
    """One group: coordinates (dimension scales) and variables; rows appended along ``time``."""

    def __init__(self, group: h5py.Group | None, *, direct: bool | None = None,
                 name: str | None = None, ops: list[Callable[[], Any]] | None = None) -> None:
        self._g = group             # None until a deferred layout makes it (``ops``)
        self._name = name if name is not None else group.name.lstrip("/")
        #: the HDF5 calls recorded while the layout is deferred (shared with the dataset
        #: writer, which makes them in order: :meth:`DatasetWriter.lay_out`); None: made now
        self._ops = ops
        self._direct = direct       # the direct-chunk path forced on/off (None: _direct_chunks)
        self._growing: dict[str, list[str]] = {}     # growing dim -> variables along it
        self._dim_only: set[str] = set()             # growing dims without coordinate values
        self._staged: dict[str, _ChunkStage] = {}    # name -> its chunk-aligned writer
        self._rows: dict[str, int] = {}              # growing dim -> rows appended so far
        #: bytes per row of the growing datasets, by growing dimension (a coordinate-less
        #: ``sample`` dimension holds none): the run's size estimate (sim/run/run_budget.py)
        #: without visiting the file
        self.row_bytes: dict[str, int] = {}
        #: names of the growing datasets (none is kept open here: an open dataset keeps its
        #: chunks in HDF5's chunk cache past the writer's close, which moves where they land)
        self._growing_names: list[str] = []
        #: what each growing dataset was made with here (its type, chunk shape and shape: no
        #: rows yet), so its first append reopens it with one H5Dopen instead of asking HDF5
        #: back through h5py's group lookup and Dataset properties (:class:`_Made`)
        self._made: dict[str, tuple[np.dtype, tuple[int, ...], tuple[int, ...]]] = {}
        #: length of each fixed coordinate made here (a growing variable's fixed dimensions)
        self._sizes: dict[str, int] = {}
        #: the scales kept open while a deferred layout is made (:meth:`_scale`); else None
        self._open_scales: dict[str, Any] | None = None

    def _count_row(self, name: str, dim: str, dtype: Any, tail: tuple[int, ...] = (),
                   scale: bool = False) -> None:
        """Add growing dataset ``name`` (along ``dim``; the ``dtype`` and fixed dimensions
        ``tail`` it was made with) to :attr:`row_bytes` — as
        :func:`rlgsim.sim.run.run_budget._row_bytes` counts it in the file (the stored type's
        item size: 8 for a text's reference; a scale named ``sample`` holds no bytes)."""
        self._growing_names.append(name)
        if scale and name == "sample":
            return
        row = int(np.dtype(dtype).itemsize * math.prod(tail))
        self.row_bytes[dim] = self.row_bytes.get(dim, 0) + row

    @property
    def name(self) -> str:
        return self._name

    def _chunks(self, dtype: np.dtype, tail: tuple[int, ...]) -> tuple[int, ...]:
        row = max(1, int(np.prod(tail, dtype=np.int64))) * max(1, np.dtype(dtype).itemsize)
        rows = int(min(1 << 16, max(64, _CHUNK_BYTES // row)))
        return (rows, *tail)

    def _do(self, call: Callable[[], Any]) -> None:
        """Make HDF5 call(s) ``call`` now, or record it for :meth:`DatasetWriter.lay_out` when
        the dataset's layout is deferred (``DatasetWriter(..., defer_layout=True)``)."""
        if self._ops is None:
            call()
        else:
            self._ops.append(call)

    def coordinate(self, name: str, values: Iterable | None = None, *, units: str | None = None,
                   description: str, dtype: Any = np.float64, growing: bool = False,
                   attrs: Mapping[str, Any] | None = None) -> None:
        """A dimension with its coordinate variable. ``growing=True`` makes it the unlimited
        dimension that :meth:`append` extends (its values arrive with the rows)."""
        if growing:
            chunks = self._chunks(dtype, ())
            self._made[name] = (np.dtype(dtype), chunks, (0,))
            self._growing[name] = [name]
            self._count_row(name, name, dtype, scale=True)

            def make() -> Any:
                return new_dataset_id(self._g, name, (0,), dtype, maxshape=(None,),
                                      chunks=chunks)
        else:
            data = np.array(list(values) if not isinstance(values, np.ndarray) else values)
            if data.dtype.kind in "UO":
                data = np.asarray([str(v) for v in data], dtype=object)
                dtype = _STR
            self._sizes[name] = int(data.shape[0])

            def make() -> Any:
                return self._fixed(name, data, dtype)

        def lay_out() -> None:
            dsid = make()
            with h5py._objects.phil:                  # Dataset.make_scale(name)'s call
                h5py.h5ds.set_scale(dsid, name.encode("utf-8"))
            self._set_attrs(dsid, units, description, attrs)
        self._do(lay_out)

    def dimension(self, name: str) -> None:
        """A growing dimension *without* coordinate values (netCDF-4: "a dimension but not a
        variable"; xarray shows it without an index). For sample-rate axes whose coordinate is
        implicit, where a stored coordinate would cost 8 bytes per sample; :meth:`append` along
        it takes the variables only."""
        self._made[name] = (np.dtype(">f4"), (1 << 16,), (0,))
        self._growing[name] = []
        self._dim_only.add(name)
        self._count_row(name, name, ">f4", scale=True)

        def lay_out() -> None:
            dsid = new_dataset_id(self._g, name, (0,), ">f4", maxshape=(None,),
                                  chunks=(1 << 16,))
            with h5py._objects.phil:
                h5py.h5ds.set_scale(dsid, f"{_NOT_A_VARIABLE}{0:10d}".encode("utf-8"))
        self._do(lay_out)

    def set_attrs(self, attrs: Mapping[str, Any]) -> None:
        """Set attributes of the group itself."""
        values = {key: _attr_value(value) for key, value in attrs.items()}

        def lay_out() -> None:
            for key, value in values.items():
                self._g.attrs[key] = value
        self._do(lay_out)

    def variable(self, name: str, dims: tuple[str, ...], *, units: str | None = None,
                 description: str, dtype: Any = np.float64, data: Any = None,
                 attrs: Mapping[str, Any] | None = None,
                 storage: Mapping[str, Any] | None = None) -> None:
        """A variable over existing dimensions; along a growing dimension (first) it starts empty
        and is filled by :meth:`append`, otherwise ``data`` gives its values. ``storage``: extra
        h5py keywords of a growing variable — ``chunks`` (overrides the default chunk shape) and
        filters built into HDF5, so every netCDF-4 reader decodes them (e.g.
        ``{"scaleoffset": 0}``: lossless packing of integers into the bits each chunk needs)."""
        string = np.dtype(dtype).kind in "UO" if dtype is not _STR else True
        if string:
            dtype = _STR
        if dims and dims[0] in self._growing:
            tail = tuple(self._size(d, name) for d in dims[1:])
            extra = dict(storage or {})
            chunks = tuple(extra.pop("chunks", None) or self._chunks(dtype, tail))
            low_level = set(extra) <= {"scaleoffset"} and plain_name(name)
            if low_level:
                self._made[name] = (np.dtype(dtype), chunks, (0, *tail))
            self._growing[dims[0]].append(name)
            self._count_row(name, dims[0], dtype, tail)

            def make() -> Any:
                if low_level:
                    return new_dataset_id(self._g, name, (0, *tail), dtype,
                                          maxshape=(None, *tail), chunks=chunks,
                                          scaleoffset=extra.get("scaleoffset"))
                return self._g.create_dataset(name, shape=(0, *tail),   # other filters:
                                              maxshape=(None, *tail),  # h5py's own checks
                                              dtype=dtype, chunks=chunks, track_times=False,
                                              **extra).id
        else:
            arr = np.array(data)
            if string:
                arr = np.asarray([str(v) for v in arr.ravel()], dtype=object).reshape(arr.shape)

            def make() -> Any:
                return self._fixed(name, arr, dtype)

        def lay_out() -> None:
            scales = [self._scale(d) for d in dims]
            dsid = make()
            with h5py._objects.phil:
                for axis, scale in enumerate(scales):   # ds.dims[axis].attach_scale(scale)
                    h5py.h5ds.attach_scale(dsid, scale, axis)
            self._set_attrs(dsid, units, description, attrs)
        self._do(lay_out)

    def _scale(self, dim: str) -> Any:
        """The dimension scale ``dim`` opened (H5Dopen) for attaching: for this call only, or,
        while a deferred layout is made (:meth:`DatasetWriter.lay_out`: no chunk is written
        meanwhile, and the simulator's files have no chunk cache), kept open until its end."""
        opened = self._open_scales
        if opened is not None and dim in opened:
            return opened[dim]
        with h5py._objects.phil:
            scale = h5py.h5d.open(self._g.id, dim.encode("utf-8"))
        if opened is not None:
            opened[dim] = scale
        return scale

    def _size(self, dim: str, name: str) -> int:
        """Length of the fixed dimension ``dim`` of growing variable ``name``, as its
        :meth:`coordinate` declared it; ValueError naming the group, variable and dimension
        when this group declared no such fixed dimension (before anything is laid out)."""
        size = self._sizes.get(dim)
        if size is None:
            raise ValueError(f"{self.name}/{name}: dimension {dim!r} is not a fixed dimension "
                             f"declared in group {self.name!r} (declare it first with "
                             f"coordinate(name, values))")
        return size

    def _fixed(self, name: str, data: np.ndarray, dtype: Any) -> Any:
        """A dataset holding ``data`` (not growing): ``create_dataset(name, data=data,
        dtype=dtype, track_times=False)``, through
        :func:`~rlgsim.sim.writer._new_dataset.new_dataset_id` for numbers and text (h5py's
        ``array_for_new_object`` decides what is written: the array as it is, text as an
        object array of ``str`` viewed with h5py's UTF-8 string dtype). Returns its
        ``DatasetID``."""
        kind = data.dtype.kind
        if plain_name(name) and (kind in "biuf" or (
                kind == "O" and dtype is _STR and all(type(v) is str for v in data.flat))):
            arr = np.asarray(data, order="C")
            if kind == "O":
                arr = arr.view(dtype=_STR)
            return new_dataset_id(self._g, name, arr.shape, dtype, data=arr)
        return self._g.create_dataset(name, data=data, dtype=dtype, track_times=False).id

    @staticmethod
    def _set_attrs(dsid: Any, units: str | None, description: str,
                   attrs: Mapping[str, Any] | None) -> None:
        """The attributes of the dataset ``dsid`` (a ``DatasetID``)."""
        ds = DatasetAttrs(dsid)
        if units is not None:
            _set_attr(ds, "units", units)
        _set_attr(ds, "description", description)
        for key, value in (attrs or {}).items():
            _set_attr(ds, key, _attr_value(value))

    def append(self, dim: str, rows: Mapping[str, np.ndarray]) -> None:
        """Append the same number of rows to ``dim`` and every variable along it.

        Rows are staged per variable and reach the file in whole HDF5 chunks
        (:class:`_ChunkStage`); :meth:`flush` (called by :meth:`DatasetWriter.commit` and
        :func:`add_group`) writes the last, partial chunk. The stored arrays — and the file's
        bytes — depend only on the rows in order, not on how they were grouped into calls."""
        names = self._growing[dim]
        if len(rows) != len(names) or any(v not in rows for v in names):
            missing = set(names) - set(rows)
            extra = set(rows) - set(names)
            raise ValueError(f"{self.name}: append along {dim} needs exactly {sorted(names)}; "
                             f"missing {sorted(missing)}, unexpected {sorted(extra)}")
        n = {len(rows[v]) for v in names}
        if len(n) != 1:
            raise ValueError(f"{self.name}: rows of different lengths {sorted(n)}")
        m = n.pop()
        if m == 0:
            return
        start = self._rows.get(dim, 0)      # every growing dimension was made here, empty
        for v in names:
            st = self._staged.get(v)
            if st is None:
                st = self._staged[v] = _ChunkStage(self._open(v), start, self._direct)
            st.append(rows[v])
        self._rows[dim] = start + m

    def _open(self, name: str) -> "h5py.Dataset | _Made":
        """Growing dataset ``name`` opened for its stage: one H5Dopen with what it was made
        with here (:class:`_Made`), else (a dataset this writer did not make) through h5py."""
        made = self._made.get(name)
        if made is None:
            return self._g[name]
        with h5py._objects.phil:
            return _Made(h5py.h5d.open(self._g.id, name.encode("utf-8")), *made)

    def flush(self) -> None:
        """Write every staged row (the partial last chunks) and size the coordinate-less
        dimensions; the group's datasets then hold every appended row once their stages are
        closed (:class:`DatasetWriter` and :func:`add_group` close them: whole chunks of a
        scale-offset dataset may wait until then, as they would in HDF5's chunk cache)."""
        for st in self._staged.values():
            st.flush()
        for dim in self._dim_only:
            rows = self._rows.get(dim)
            if rows is not None and self._g[dim].shape[0] != rows:
                self._g[dim].resize(rows, axis=0)


class _Made:
    """A growing dataset this writer made, open for its stage: its HDF5 identifier and the
    type, chunk shape and shape (no rows: it is opened before its first append) it was made
    with — what :class:`_ChunkStage` and :mod:`rlgsim.sim.writer._direct_chunks` read of an
    ``h5py.Dataset`` (``id``, ``dtype``, ``chunks``, ``shape``), without h5py's group lookup,
    Dataset object and the HDF5 calls its properties make (~0.1 ms a dataset: a run's first
    block opens ~30 in the writer thread)."""

    __slots__ = ("id", "dtype", "chunks", "shape")

    def __init__(self, dsid: Any, dtype: np.dtype, chunks: tuple[int, ...],
                 shape: tuple[int, ...]) -> None:
        self.id, self.dtype, self.chunks, self.shape = dsid, dtype, chunks, shape


class _ChunkStage:
    """Appends to one growing dataset in whole HDF5 chunks.

    The hot path of a long run: each block appends a few hundred to tens of thousands of rows
    to ~30 datasets. Writing each append as it comes costs a resize and an HDF5 write per call
    (~0.1 ms each through h5py) and writes partial chunks that HDF5 must complete later
    (through its chunk cache and, for filtered datasets, the filter). Here rows are copied into
    a one-chunk staging buffer (the dataset's dtype: the conversion happens once, in numpy)
    and every run of full chunks goes to the file in one ``write_direct`` — straight from the
    caller's array when it is aligned. Memory: one chunk per dataset.

    A scale-offset dataset's whole chunks are packed here instead of by HDF5's filter (an
    unfiltered one's taken as they are) and
    written with ``write_direct_chunk`` when HDF5 would have written them
    (:mod:`rlgsim.sim.writer._direct_chunks`, :data:`DIRECT_CHUNKS`): the same file, bytes and all.
    :meth:`close` (in the order the stages were created: the order HDF5 closes the datasets
    at file close) writes what that path still holds and closes the dataset."""

    __slots__ = ("ds", "rows", "tail", "written", "buf", "fill", "dtype", "direct", "flushed",
                 "order")

    def __init__(self, ds: "h5py.Dataset | _Made", start: int, direct: bool | None = None
                 ) -> None:
        self.ds = ds
        self.dtype = ds.dtype
        self.rows = int(ds.chunks[0])
        self.tail = tuple(ds.shape[1:])      # the fixed dimensions
        self.written = int(start)            # rows in the file (a chunk boundary once staged)
        self.buf = None
        self.fill = 0                        # rows staged in buf
        self.direct = _direct_chunks(ds, start, direct)
        self.flushed = False
        self.order = next(_STAGE_ORDER)      # creation order = the dataset's open order

    def _write(self, data: np.ndarray, reused: bool = True) -> None:
        """Rows ``data`` to the file after the rows written (``reused``: ``data`` is the
        staging buffer, which changes afterwards)."""
        k = data.shape[0]
        # Dataset.resize(n, axis=0) without its checks (~35 µs a call: the dataset's creation
        # properties and shape read back each time): the same HDF5 call
        self.ds.id.set_extent((self.written + k, *self.tail))
        if self.direct is not None and self.flushed:
            # rows after a flush: the mirror's chunks go now and HDF5 writes the rest (the
            # data are right; the file layout need not match a run without the flush)
            self.direct.close()
            self.direct = None
        if self.direct is not None and k % self.rows == 0 and self.written % self.rows == 0:
            self.direct.write(data, self.written, reused)
        else:
            if self.direct is not None:
                self.direct.make_room()      # what HDF5 evicts to cache this partial chunk
            write_rows(self.ds, data, self.written)
        self.written += k

    def append(self, arr: np.ndarray) -> None:
        arr = np.asarray(arr)
        m, r = arr.shape[0], self.rows
        pos = 0
        if self.fill or self.written % r:
            if self.buf is None:
                self.buf = np.empty((r, *self.tail), dtype=self.dtype)
            # complete the chunk in progress (the first one may start mid-chunk: an
            # existing dataset that is appended to)
            room = r - (self.written + self.fill) % r
            pos = min(room, m)
            self.buf[self.fill:self.fill + pos] = arr[:pos]
            self.fill += pos
            if pos < room:
                return
            self._write(self.buf[:self.fill])
            self.fill = 0
        full = (m - pos) // r * r
        if full:
            self._write(np.ascontiguousarray(arr[pos:pos + full], dtype=self.dtype),
                        reused=False)
            pos += full
        if pos < m:
            if self.buf is None:
                self.buf = np.empty((r, *self.tail), dtype=self.dtype)
            self.buf[:m - pos] = arr[pos:]
            self.fill = m - pos

    def flush(self) -> None:
        if self.fill:
            self._write(self.buf[:self.fill])
            self.fill = 0
        self.flushed = True

    def close(self) -> None:
        """Write what the direct path still holds and close the dataset (as closing the file
        would: HDF5 then writes the chunks its cache holds)."""
        if self.direct is not None:
            self.direct.close()
            self.direct = None
        if self.ds.id.valid:
            self.ds.id.close()


#: Whole chunks of scale-offset datasets packed by :mod:`rlgsim.sim.writer._scaleoffset` and written
#: directly (:mod:`rlgsim.sim.writer._direct_chunks`; the same file bytes as HDF5's filter): None (the
#: default) when numba is already loaded in the process (the compiled packer; a long run's IMU
#: stage loads it — importing it only for this would cost a short run more than it saves),
#: True always, False never (HDF5's filter packs them). Either way only if the process's HDF5
#: passes the self-check (:func:`_direct_path_ok`).
DIRECT_CHUNKS: bool | None = None

_STAGE_ORDER = itertools.count()

#: The self-check's result (:func:`_direct_path_ok`): None until it has run.
_DIRECT_OK: bool | None = None
_DIRECT_OK_LOCK = threading.Lock()


def _direct_path_ok() -> bool:
    """Whether the direct-chunk path writes HDF5's file with the HDF5 this process loaded:
    :func:`rlgsim.sim.writer._direct_check.direct_path_agrees` (two small in-memory files, a few ms),
    run once per process, before the first direct write; False keeps HDF5's filter."""
    global _DIRECT_OK
    ok = _DIRECT_OK
    if ok is None:
        with _DIRECT_OK_LOCK:
            ok = _DIRECT_OK
            if ok is None:
                from rlgsim.sim.writer._direct_check import direct_path_agrees
                ok = _DIRECT_OK = direct_path_agrees(GroupWriter, _close_stages)
    return ok


def _direct_chunks(ds: h5py.Dataset, start: int, force: bool | None = None):
    """The direct-chunk path of a dataset (:class:`rlgsim.sim.writer._direct_chunks.DirectChunks`)
    or None (HDF5's own path). ``force`` True/False: on/off without :data:`DIRECT_CHUNKS` or
    the self-check (the self-check's own files)."""
    if force is False or ds.chunks is None:
        return None
    numba = "numba" in sys.modules
    if force is None and not (DIRECT_CHUNKS is not False and (DIRECT_CHUNKS or numba)
                              and _direct_path_ok()):
        return None
    from rlgsim.sim.writer._direct_chunks import DirectChunks
    compiled = numba or importlib.util.find_spec("numba") is not None
    return DirectChunks.of(ds, start, compiled=compiled)


def _close_stages(groups: Iterable[GroupWriter]) -> None:
    """Close every staged dataset of ``groups`` in the order they were opened — the order in
    which closing the file would close (and flush) them."""
    stages = sorted((st for g in groups for st in g._staged.values()), key=lambda st: st.order)
    for st in stages:
        st.close()
    for g in groups:
        g._staged.clear()


def remove_stale_temporaries(path: pathlib.Path) -> list[pathlib.Path]:
    """Delete ``<path>.tmp-<pid>`` files whose writing process no longer runs (a run killed
    with SIGKILL, a power cut); the temporary file of a live process is kept. Returns the
    files removed (:func:`rlgsim.ground.paths.sweep_temporaries`, shared by every command)."""
    return sweep_temporaries(path)


class DatasetWriter:
    """Stream a dataset to ``<path>.tmp-<pid>``; :meth:`commit` renames it onto ``path``.

    Use as a context manager: leaving the block normally commits, an exception (or
    KeyboardInterrupt) deletes the temporary file.

    ``defer_layout=True``: the file is not made here; it and the groups declared until
    :meth:`lay_out` are made by that call, in the order declared, in whichever thread calls it
    (the run's writer thread, while the main thread computes the first block:
    sim/run/simulate.py). Declaring takes the names, fixed dimension sizes and row bytes at once
    (see the module for which mistakes are refused then and which only by ``lay_out``).
    """

    def __init__(self, path: str | os.PathLike, attrs: Mapping[str, Any], *,
                 defer_layout: bool = False) -> None:
        self.path = check_writable(path)
        remove_stale_temporaries(self.path)
        self.tmp_path = self.path.with_name(f"{self.path.name}.tmp-{os.getpid()}")
        self._file: h5py.File | None = None
        self._groups: list[GroupWriter] = []
        self._ops: list[Callable[[], Any]] | None = None    # a deferred layout's calls
        values = {key: _attr_value(value) for key, value in attrs.items()}
        if defer_layout:                    # the file too is made by lay_out (defer_layout)
            self._ops = [lambda: self._open(values)]
        else:
            self._open(values)

    def _open(self, attrs: Mapping[str, Any]) -> None:
        """Create the temporary file with its root attributes."""
        # HDF5's chunk cache off (rdcc_nbytes=0, :data:`CHUNK_CACHE_BYTES`): every chunk goes
        # to the file when it is written (see the constant)
        self._file = h5py.File(self.tmp_path, "w", libver=("earliest", "v110"), track_order=True,
                               rdcc_nbytes=CHUNK_CACHE_BYTES)
        # The format marker is written last (commit): until then the file says it is
        # incomplete, so the temporary file of a killed run is never taken for a dataset.
        root = self._file["/"]             # File.attrs opens the root group at every use
        _set_attr(root, INCOMPLETE_ATTR, INCOMPLETE)
        _set_attr(root, "software_version", software_version())
        # provenance: the versions of the libraries behind the stored numbers (issue 29)
        _set_attr(root, "software_versions", _versions_json())
        for key, value in attrs.items():
            _set_attr(root, key, value)

    @property
    def groups(self) -> tuple[GroupWriter, ...]:
        """The group writers made so far, in order."""
        return tuple(self._groups)

    def read_dimension_lists(self) -> None:
        """Read the dimension list of every growing dataset (HDF5's ``H5DSget_num_scales``),
        in the order of the file's names, as the run's size estimate did when it visited the
        file (sim/run/run_budget.py ``_row_bytes``): the read loads the global-heap
        collections holding those lists into HDF5's cache, which decides where the text
        attributes written later (the format marker at :meth:`commit`) are stored. The
        estimate now counts the rows as they are declared (:attr:`GroupWriter.row_bytes`);
        this read (~0.1 ms) keeps the file's bytes those of the visit."""
        growing = sorted((g.name, name, g) for g in self._groups for name in g._growing_names)
        for _, name, g in growing:
            with h5py._objects.phil:
                ds = h5py.h5d.open(g._g.id, name.encode("utf-8"))
                try:
                    h5py.h5ds.get_num_scales(ds, 0)
                finally:
                    ds.close()

    def group(self, name: str, description: str,
              attrs: Mapping[str, Any] | None = None) -> GroupWriter:
        values = {key: _attr_value(value) for key, value in (attrs or {}).items()}
        writer = GroupWriter(None, name=name, ops=self._ops)

        def lay_out() -> None:
            g = writer._g = self._file.create_group(name, track_order=True)
            _set_attr(g, "description", description)
            for key, value in values.items():
                _set_attr(g, key, value)
        if self._ops is None:
            lay_out()
        else:
            self._ops.append(lay_out)
        self._groups.append(writer)
        return writer

    def lay_out(self) -> None:
        """Make the recorded HDF5 calls of a deferred layout, in order (none when nothing is
        deferred), then read the dimension lists as the size estimate's visit did
        (:meth:`read_dimension_lists`); later declarations are made at once again."""
        ops, self._ops = self._ops, None
        for g in self._groups:
            g._ops = None
            g._open_scales = {} if ops else None
        try:
            for call in ops or ():
                call()
        finally:
            with h5py._objects.phil:
                for g in self._groups:
                    for scale in (g._open_scales or {}).values():
                        scale.close()
                    g._open_scales = None
        self.read_dimension_lists()

    def commit(self) -> pathlib.Path:
        if self._ops is not None:              # a deferred layout never made: make it now
            self.lay_out()
        for g in self._groups:                 # rows still staged (GroupWriter.append)
            g.flush()
        del self._file.attrs[INCOMPLETE_ATTR]
        self._file.attrs[FORMAT_ATTR] = FORMAT
        self._file.attrs[VERSION_ATTR] = FORMAT_VERSION
        _close_stages(self._groups)
        self._file.close()
        os.replace(self.tmp_path, self.path)
        return self.path

    def abort(self) -> None:
        """Close and delete the temporary file. Closing flushes HDF5's metadata, which fails
        again on a full disk: that second error is dropped so the one that stopped the run is
        the one raised, and the file is deleted either way."""
        try:
            if self._file is not None:      # (a deferred layout may not have made it)
                self._file.close()
        except Exception:
            pass
        finally:
            try:
                self.tmp_path.unlink()
            except OSError:
                pass

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()


@contextlib.contextmanager
def add_group(path: str | os.PathLike, name: str, description: str,
              attrs: Mapping[str, Any] | None = None) -> Iterator[GroupWriter]:
    """Add (or replace) the group ``name`` of an existing dataset: yields a
    :class:`GroupWriter` of a group under a temporary name that is moved onto ``name`` when the
    block ends normally (and deleted on an error), so an interrupted write never leaves a half
    group named ``name``."""
    tmp = f"{name}.tmp-{os.getpid()}"
    with h5py.File(path, "r+") as f:
        if tmp in f:
            del f[tmp]
        g = f.create_group(tmp, track_order=True)
        g.attrs["description"] = description
        for key, value in (attrs or {}).items():
            g.attrs[key] = _attr_value(value)
        try:
            writer = GroupWriter(g)
            yield writer
            writer.flush()
        except BaseException:
            del f[tmp]
            raise
        if name in f:
            del f[name]
        f.move(tmp, name)
        _close_stages([writer])
