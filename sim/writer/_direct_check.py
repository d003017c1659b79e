"""Does the direct-chunk path write HDF5's file with the HDF5 library this process loaded?

:mod:`rlgsim.sim.writer._direct_chunks` writes a scale-offset dataset's whole chunks when HDF5's chunk
cache would have flushed them, and that timing rests on how the installed HDF5 behaves: the
order its cache evicts chunks, the order closing the datasets flushes them, and a direct
write dropping the cached copy of its chunk unwritten (``H5Dchunk.c``). Another HDF5 could do
any of these differently; the arrays would still be right, but the file's layout would differ
from the one HDF5's filter writes. :func:`direct_path_agrees` writes one small file both ways
in memory — through the writer's own code (:class:`rlgsim.sim.writer.dataset.GroupWriter`,
``_ChunkStage``, ``_close_stages``) with the direct path forced on and off — and compares the
two file images byte for byte. :func:`rlgsim.sim.writer.dataset._direct_path_ok` runs it once per
process, before the first direct write, and keeps HDF5's filter for the process if the images
differ.

The file: the writer's file settings (``libver``, ``track_order``), written twice: with no chunk
cache (the simulator's files: :data:`rlgsim.sim.writer.dataset.CHUNK_CACHE_BYTES`, each chunk
written at once) and with a chunk cache of 16 KiB (a group added to an existing file keeps the
library's default, 1 MiB: the eviction rules are the same, and the smaller cache overflows with
130 KiB of data instead of megabytes); two int32 scale-offset
datasets of 3 columns like the pulses (chunks of 3 and 6 KiB), two unfiltered float64 ones
whose whole chunks also go the direct path (3 columns like the ``trajectory`` velocity, chunks
of 6 KiB; one column, chunks of 4 KiB) and an unfiltered float32 one that never fills a chunk
(HDF5's path throughout), appended in uneven blocks: 23 chunks of the first (the cache holds 5 at a time), chunk ranges from one
value to the full int32 span, a partial last chunk. Cost: ~15 ms after the packer is loaded
(which the first direct write would load anyway).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

#: Chunk-cache sizes [bytes] of the check's in-memory files: none (the simulator's files) and
#: 5 chunks of the int32 dataset.
_CACHE_BYTES = (0, 16 << 10)
_ROWS = 256                              # rows per chunk of the int32 dataset (3 KiB chunks)
_N = 23 * _ROWS - 100                    # rows written: 22 whole chunks and a partial one


def _data() -> dict[str, np.ndarray]:
    """The rows: per chunk a different range (fill-only, one value, small, wide, the int32
    extremes), a fixed seed."""
    rng = np.random.default_rng(20261124)
    p = np.empty((_N, 3), np.int32)
    info = np.iinfo(np.int32)
    for j, lo in enumerate(range(0, _N, _ROWS)):
        n = min(_ROWS, _N - lo)
        span = (0, 1, 7, 300, 70_000, 1 << 30)[j % 6]
        base = int(rng.integers(-1000, 1000))
        p[lo:lo + n] = rng.integers(base, base + span + 1, (n, 3))
    p[5 * _ROWS + 3] = info.max
    p[5 * _ROWS + 4] = info.min
    q = rng.integers(-9, 9, (_N, 3)).astype(np.int32)
    q[:700] = 0
    v = rng.standard_normal(_N).astype(np.float32)
    r = rng.standard_normal((_N, 3))
    s = rng.standard_normal(_N)
    return {"p": p, "q": q, "v": v, "r": r, "s": s}


def _image(direct: bool, rows: dict[str, np.ndarray], group_writer: Any,
           close_stages: Callable[[list], None], cache_bytes: int) -> bytes:
    """The file image written by the writer's code (``group_writer``: the
    :class:`rlgsim.sim.writer.dataset.GroupWriter` class, ``close_stages`` its module's
    ``_close_stages``; passed in, so this module imports nothing of the writer) with the direct
    path ``direct`` and a chunk cache of ``cache_bytes`` per dataset."""
    import h5py

    GroupWriter, _close_stages = group_writer, close_stages
    with h5py.File(f"direct-check-{direct}.h5", "w", driver="core", backing_store=False,
                   libver=("earliest", "v110"), track_order=True,
                   rdcc_nbytes=cache_bytes) as f:
        g = GroupWriter(f.create_group("g", track_order=True), direct=direct)
        g.dimension("sample")
        g.coordinate("axis", ["x", "y", "z"], description="axis")
        g.variable("p", ("sample", "axis"), units="1", dtype=np.int32, description="p",
                   storage={"scaleoffset": 0, "chunks": (_ROWS, 3)})
        g.variable("q", ("sample", "axis"), units="1", dtype=np.int32, description="q",
                   storage={"scaleoffset": 0, "chunks": (2 * _ROWS, 3)})
        g.variable("v", ("sample",), units="1", dtype=np.float32, description="v")
        g.variable("r", ("sample", "axis"), units="1", description="r",
                   storage={"chunks": (_ROWS, 3)})
        g.variable("s", ("sample",), units="1", description="s",
                   storage={"chunks": (2 * _ROWS,)})
        lo = 0
        for m in (37, 900, 1, 2000, 513, _N):
            hi = min(_N, lo + m)
            g.append("sample", {k: a[lo:hi] for k, a in rows.items()})
            lo = hi
        if direct and any(g._staged[k].direct is None for k in ("p", "q", "r", "s")):
            raise RuntimeError("the direct path declined the check's datasets")
        g.flush()                          # what DatasetWriter.commit does, in its order
        _close_stages([g])
        f.flush()
        return f.id.get_file_image()


def direct_path_agrees(group_writer: Any, close_stages: Callable[[list], None]) -> bool:
    """True when the direct-chunk path writes the same file as HDF5's filter here (see the
    module; ``group_writer``, ``close_stages`` as :func:`_image` takes them); False when the
    files differ or the direct path fails."""
    try:
        rows = _data()
        return all(_image(True, rows, group_writer, close_stages, cache)
                   == _image(False, rows, group_writer, close_stages, cache)
                   for cache in _CACHE_BYTES)
    except Exception:                      # noqa: BLE001 — any failure: keep HDF5's path
        return False
