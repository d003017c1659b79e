"""Whole chunks of a scale-offset dataset encoded here (:mod:`rlgsim.sim.writer._scaleoffset`) and
written with ``write_direct_chunk`` — at the moment HDF5 would have written them, so the file
keeps its bytes.

Through ``write_direct`` a whole chunk of a filtered dataset goes into the dataset's chunk
cache (HDF5 ``H5Dchunk.c``); it is filtered and given file space only when it leaves the cache:
when a new chunk needs room (the oldest chunk first — every chunk here is written whole once,
so the LRU list is the order of writing, and an entry leaves while the cache's bytes plus the
new chunk's exceed its size) or when the dataset is closed (oldest first). File space is
allocated in that order, interleaved with the other datasets', so writing each chunk as it
comes would move the chunks and the index nodes in the file. :class:`DirectChunks` keeps the
encoded chunks in a mirror of that cache (the same capacity in bytes of unfiltered chunks,
read from the dataset's access properties) and writes each one when HDF5 would have flushed it.
A direct write allocates, writes and indexes a chunk in the same order as a flush.

An **unfiltered** dataset (the ``trajectory`` group's 13 float64 states per IMU sample, 37 MB
an hour at 100 Hz) takes the same path with its chunks' raw bytes (``codec`` None): its whole
chunks went through the cache the same way (copied in, allocated and written at eviction), and
HDF5's chunk-cache bookkeeping of a 256 KiB chunk cost ~3× the plain write of its bytes (the
writer thread's CPU; benchmarks/bench_sim_trajectory.py).

Two calls stay with HDF5: the dataset's first write goes through ``write_direct`` for its first
chunk (HDF5 creates the chunk index then; that chunk stays in HDF5's cache, and the direct write
of its encoded copy at its turn evicts it unwritten), and a partial chunk (the last one)
goes to HDF5's cache after the mirror made the room HDF5 would make. The caller then closes the
datasets in the order HDF5 closes a file's open datasets (the order they were opened), each
after :meth:`DirectChunks.close` wrote what the mirror still holds.
"""

from __future__ import annotations

from collections import deque

import h5py
import numpy as np

from rlgsim.sim.writer._new_dataset import write_rows
from rlgsim.sim.writer._scaleoffset import Codec, codec_of, encode


class DirectChunks:
    """The mirror of one dataset's chunk cache, holding encoded chunks (see the module)."""

    def __init__(self, ds: h5py.Dataset, codec: Codec | None, capacity: int,
                 compiled: bool) -> None:
        self.ds = ds
        self.codec = codec                    # None: an unfiltered dataset (its raw bytes)
        self.rows = int(ds.chunks[0])
        self.tail = (0,) * (len(ds.shape) - 1)
        self.chunk_bytes = _chunk_bytes(ds)
        self.capacity = capacity              # bytes of unfiltered chunks; 0: no cache
        self.compiled = compiled
        #: chunks written by the compiled calls (:mod:`rlgsim.sim.writer._chunk_calls`), else by
        #: h5py's; decided at the first write
        self.calls: bool | None = None
        #: chunks the cache holds: (n + 1)·chunk_bytes > capacity ⇔ n ≥ capacity // chunk_bytes
        self.entries = capacity // self.chunk_bytes
        self.pending: deque[tuple[int, np.ndarray]] = deque()   # (first row, encoded bytes)
        self.started = False                  # the chunk index exists

    @classmethod
    def of(cls, ds: h5py.Dataset, start: int, compiled: bool) -> "DirectChunks | None":
        """The mirror of ``ds`` written from row ``start``, or None when HDF5's own path must
        stay: not a scale-offset dataset :mod:`rlgsim.sim.writer._scaleoffset` encodes, rows already
        written, chunks not spanning the trailing dimensions, or a cache small enough in slots
        that chunks could collide in its hash table."""
        if ds.chunks is None or start != 0 or ds.shape[0] != 0 \
                or tuple(ds.chunks[1:]) != ds.shape[1:]:
            return None
        codec = codec_of(ds)
        if codec is None and not _raw(ds):
            return None
        nslots, nbytes, _w0 = ds.id.get_access_plist().get_chunk_cache()
        chunk_bytes = _chunk_bytes(ds)
        cacheable = nslots > 0 and chunk_bytes <= nbytes
        capacity = int(nbytes) if cacheable else 0
        if cacheable and capacity // chunk_bytes + 2 >= nslots:
            return None
        return cls(ds, codec, capacity, compiled)

    def write(self, data: np.ndarray, row: int, reused: bool = True) -> None:
        """Whole chunks ``data`` (a multiple of the chunk's rows) at row ``row`` (a chunk
        boundary; the dataset already extends over them); ``reused``: the caller changes
        ``data`` afterwards (its staging buffer), so an unfiltered dataset's mirror keeps a
        copy (else the array itself: rows handed to the writer do not change)."""
        if self.calls is None:
            self.calls = self.compiled and _compiled_calls()
        if self.codec is not None and not self.capacity and self.calls:
            self._encode_and_write(data, row)     # the simulator's pulses: one compiled call
            return
        if self.codec is None:                    # unfiltered: the chunks' own bytes
            buf = np.ascontiguousarray(data, dtype=self.ds.dtype).reshape(-1).view(np.uint8)
            ends = np.arange(0, buf.size + 1, self.chunk_bytes)
            if reused and self.capacity:   # kept in the mirror: a copy
                buf = buf.copy()
        else:
            buf, ends = encode(self.codec, data, compiled=self.compiled)
            if self.capacity:
                buf = buf[:ends[-1]].copy()       # what the mirror holds: the encoded bytes
        first = self._start(data, row)
        if first and self.capacity:
            self._insert(row, buf[ends[0]:ends[1]])
        if not self.capacity:
            # no cache (the simulator's files): the mirror holds nothing (pending stays empty)
            # and each chunk goes to the file as it comes, in order, as HDF5 writes it with no
            # cache — no per-chunk bookkeeping (~3 µs of the writer thread's Python each;
            # paper000_ramp writes ~21 000), from compiled code without the GIL when it can
            if self.calls and first < len(ends) - 1:
                self._write_compiled(buf, ends, row, first)
                return
            ends = ends.tolist()
            write_chunk, tail, rows = self.ds.id.write_direct_chunk, self.tail, self.rows
            for j in range(first, len(ends) - 1):
                write_chunk((row + j * rows, *tail), buf[ends[j]:ends[j + 1]])
            return
        ends = ends.tolist()
        for j in range(first, len(ends) - 1):
            self._insert(row + j * self.rows, buf[ends[j]:ends[j + 1]])

    def _start(self, data: np.ndarray, row: int) -> int:
        """The dataset's first write, once: its first chunk through HDF5 (which creates the
        chunk index then). Returns the chunks of ``data`` it wrote (1 or 0)."""
        if self.started:
            return 0
        write_rows(self.ds, np.ascontiguousarray(data[:self.rows]), row)
        self.started = True
        return 1

    def _encode_and_write(self, data: np.ndarray, row: int) -> None:
        """Whole chunks ``data`` of a scale-offset dataset without a chunk cache, encoded and
        written in one compiled call (:func:`rlgsim.sim.writer._chunk_calls.encode_and_write`;
        h5py's lock held), after the dataset's first write (:meth:`_start`): the HDF5 calls
        and their order of the path through :meth:`_write_compiled`."""
        from rlgsim.sim.writer._chunk_calls import encode_and_write
        from rlgsim.sim.writer._scaleoffset import encode_args
        args = encode_args(self.codec, data)
        first = self._start(data, row)
        with h5py._objects.phil:
            failed = encode_and_write(*args, self.ds.id.id, row, self.rows, len(self.tail) + 1,
                                      first)
        self._rest_through_h5py(failed, args[5], args[6], row)

    def _rest_through_h5py(self, failed: int, buf: np.ndarray, ends: np.ndarray,
                           row: int) -> None:
        """The chunk HDF5 refused to the compiled calls (``failed`` ≥ 0; −1: none) and those
        after it (not written) through h5py's ``write_direct_chunk``: the same calls in the same
        order, so HDF5 either takes them (the same file) or h5py raises HDF5's own error with
        its reason (e.g. ``OSError``, no space left on device)."""
        if failed < 0:
            return
        ends = np.asarray(ends).tolist()
        for j in range(failed, len(ends) - 1):
            self.ds.id.write_direct_chunk((row + j * self.rows, *self.tail),
                                          buf[ends[j]:ends[j + 1]])

    def _write_compiled(self, buf: np.ndarray, ends: np.ndarray, row: int, first: int) -> None:
        """Chunks ``first`` … of ``buf`` (``ends``) from row ``row`` through
        :func:`rlgsim.sim.writer._chunk_calls.write_chunks` (h5py's lock held: no other thread
        enters HDF5 while the loop runs without the GIL)."""
        from rlgsim.sim.writer._chunk_calls import write_chunks
        with h5py._objects.phil:
            buf = np.ascontiguousarray(buf, dtype=np.uint8)
            failed = write_chunks(self.ds.id.id, row, self.rows, len(self.tail) + 1, buf,
                                  np.asarray(ends, dtype=np.int64), first)
        self._rest_through_h5py(failed, buf, ends, row)

    def make_room(self) -> None:
        """What HDF5 flushes from the cache before it takes in one more chunk (a partial chunk
        written through ``write_direct`` right after): the oldest chunks while the cache's
        bytes and the new chunk's exceed its size."""
        while self.pending and len(self.pending) >= self.entries:
            row, chunk = self.pending.popleft()
            self.ds.id.write_direct_chunk((row, *self.tail), chunk)

    def close(self) -> None:
        """Write every chunk the mirror holds, oldest first (what closing the dataset flushes)."""
        while self.pending:
            row, chunk = self.pending.popleft()
            self.ds.id.write_direct_chunk((row, *self.tail), chunk)

    def _insert(self, row: int, chunk: np.ndarray) -> None:
        """A chunk enters the cache (a dataset with one: :meth:`write` writes a no-cache
        dataset's chunks at once): HDF5 makes room first."""
        if len(self.pending) >= self.entries:
            self.make_room()
        self.pending.append((row, chunk))


def _compiled_calls() -> bool:
    """:func:`rlgsim.sim.writer._chunk_calls.available` (imported with the compiled packer)."""
    from rlgsim.sim.writer._chunk_calls import available
    return available()


def _chunk_bytes(ds: h5py.Dataset) -> int:
    """Bytes of one whole chunk of ``ds`` before any filter."""
    return int(np.prod(ds.chunks, dtype=np.int64)) * ds.dtype.itemsize


def _raw(ds: h5py.Dataset) -> bool:
    """Whether ``ds`` stores its chunks as they are: no filter, numbers of a fixed size."""
    return ds.dtype.kind in "fiu" and ds.id.get_create_plist().get_nfilters() == 0
