"""Scale-offset chunks packed here (sim/writer/_scaleoffset.py, sim/writer/_scaleoffset_kernel.py) are the
bytes HDF5's own filter stores, with and without numba, and the direct-chunk path
(sim/writer/_direct_chunks.py, dataset._ChunkStage) writes the same file as HDF5's path, byte for byte
— chunks leave the mirrored chunk cache when HDF5's would."""

from __future__ import annotations

import pathlib

import h5py
import numpy as np
import pytest

from rlgsim.sim.writer import dataset
from rlgsim.sim.writer._scaleoffset import Codec, codec_of, encode


def _chunks(dtype: np.dtype, shape: tuple[int, ...], rng: np.random.Generator):
    """Adversarial chunks: every value the fill value, one value, the type's extremes, spans
    at the edges of a bit width and of HDF5's full-width test, an outlier, negatives."""
    info = np.iinfo(dtype)
    lo_t, hi_t = int(info.min), int(info.max)

    def spread(lo: int, d: int) -> np.ndarray:
        x = rng.integers(lo, lo + d, shape, endpoint=True).astype(dtype)
        x.flat[0], x.flat[-1] = lo, lo + d
        return x

    yield "all fill", np.zeros(shape, dtype)
    yield "one value", np.full(shape, 3, dtype)
    yield "type minimum", np.full(shape, lo_t, dtype)
    yield "full range", spread(lo_t, hi_t - lo_t)
    yield "random", rng.integers(lo_t, hi_t, shape, endpoint=True).astype(dtype)
    width = 8 * np.dtype(dtype).itemsize
    for d in sorted({1, 2, 5, 126, 127, 128, 253, 254, (1 << 15) - 2, (1 << 15) - 1,
                     (1 << width) - 4, (1 << width) - 3, (1 << width) - 2}):
        if d <= hi_t - lo_t:
            yield f"span {d} low", spread(lo_t, d)
            yield f"span {d} high", spread(hi_t - d, d)
    small = rng.integers(max(lo_t, -3), 4, shape).astype(dtype)
    yield "small", small
    outlier = small.copy()
    outlier.flat[min(100, outlier.size - 1)] = hi_t
    yield "one outlier", outlier
    one = np.zeros(shape, dtype)
    one.flat[min(50, one.size - 1)] = 1 if lo_t == 0 else -1
    yield "one non-fill", one
    yield "fill and maximum", (rng.integers(0, 2, shape) * hi_t).astype(dtype)


@pytest.mark.parametrize("dtype", [np.int32, np.int16, np.int8, np.uint32, np.uint16, np.uint8])
@pytest.mark.parametrize("fill", [None, 5])
def test_packed_chunks_are_the_bytes_hdf5_stores(dtype, fill):
    rng = np.random.default_rng(np.dtype(dtype).num * 10 + (fill or 0))
    with h5py.File("mem.h5", "w", driver="core", backing_store=False) as f:
        for shape in ((4096, 3), (1000,), (7, 2)):
            for name, x in _chunks(dtype, shape, rng):
                kw = {} if fill is None else {"fillvalue": fill}
                ds = f.create_dataset(f"{shape}/{name}", shape=shape, chunks=shape, dtype=dtype,
                                      scaleoffset=0, **kw)
                ds[...] = x
                codec = codec_of(ds)
                assert codec == Codec(np.dtype(dtype), fill or 0, int(np.prod(shape)))
                _, stored = ds.id.read_direct_chunk((0,) * len(shape))
                for compiled in (True, False):
                    buf, ends = encode(codec, x, compiled=compiled)
                    assert ends.tolist() == [0, len(stored)], (shape, name, compiled)
                    assert buf[:ends[1]].tobytes() == stored, (shape, name, compiled)


@pytest.mark.parametrize("dtype", [np.int32, np.uint16])
def test_every_code_width_in_groups_and_tail(dtype):
    """Every ``minbits`` the compiled packer meets (1 up to the type's width: the group-of-8
    path below 9 bits, the two-word one below 16, the serial one above) in chunks of n values
    with n mod 8 = 0 and 3 (the tail), with fill values among them: HDF5's stored bytes."""
    rng = np.random.default_rng(7)
    info = np.iinfo(dtype)
    width = 8 * np.dtype(dtype).itemsize
    with h5py.File("mem.h5", "w", driver="core", backing_store=False) as f:
        for shape in ((512, 3), (1003,)):
            for bits in range(1, width + 1):
                d = min((1 << bits) - 2, int(info.max) - int(info.min))   # minbits = bits
                lo = int(rng.integers(int(info.min), int(info.max) - d, endpoint=True))
                x = rng.integers(lo, lo + d, shape, endpoint=True).astype(dtype)
                x.flat[1::7] = 0                                        # the fill value
                x.flat[0], x.flat[-1] = lo, lo + d                      # then the extremes
                ds = f.create_dataset(f"{shape}/{bits}", data=x, chunks=shape, scaleoffset=0)
                _, stored = ds.id.read_direct_chunk((0,) * len(shape))
                # HDF5's chunk header starts with its minbits (4 bytes, little-endian): the
                # width this case is meant to reach, so every path is really taken
                assert int.from_bytes(stored[:4], "little") == bits, (shape, bits)
                buf, ends = encode(codec_of(ds), x, compiled=True)
                assert buf[:ends[1]].tobytes() == stored, (shape, bits)


def test_several_chunks_in_one_call_and_read_back():
    rng = np.random.default_rng(1)
    x = rng.integers(-40, 40, (5 * 64, 3)).astype(np.int32)
    x[64:128] = 0
    x[128:192, 1] = np.iinfo(np.int32).max
    with h5py.File("mem.h5", "w", driver="core", backing_store=False) as f:
        ref = f.create_dataset("ref", data=x, chunks=(64, 3), scaleoffset=0)
        out = f.create_dataset("out", shape=x.shape, chunks=(64, 3), dtype=np.int32,
                               scaleoffset=0)
        codec = codec_of(ref)
        for compiled in (True, False):
            buf, ends = encode(codec, x, compiled=compiled)
            for j in range(5):
                chunk = buf[ends[j]:ends[j + 1]].tobytes()
                assert chunk == ref.id.read_direct_chunk((64 * j, 0))[1]
                out.id.write_direct_chunk((64 * j, 0), chunk)
            np.testing.assert_array_equal(out[...], x)


def test_datasets_hdf5_must_pack_are_declined():
    with h5py.File("mem.h5", "w", driver="core", backing_store=False) as f:
        kw = {"shape": (10, 3), "chunks": (5, 3)}
        assert codec_of(f.create_dataset("a", dtype=np.int32, scaleoffset=4, **kw)) is None
        assert codec_of(f.create_dataset("b", dtype=np.int64, scaleoffset=0, **kw)) is None
        assert codec_of(f.create_dataset("c", dtype=">i4", scaleoffset=0, **kw)) is None
        assert codec_of(f.create_dataset("d", dtype=np.float32, scaleoffset=2, **kw)) is None
        assert codec_of(f.create_dataset("e", dtype=np.int32, compression="gzip", **kw)) is None
        assert codec_of(f.create_dataset("f", dtype=np.int32, scaleoffset=0, shuffle=True,
                                         **kw)) is None
        assert codec_of(f.create_dataset("g", dtype=np.int32, **kw)) is None
        assert codec_of(f.create_dataset("h", dtype=np.int32, scaleoffset=0, **kw)) is not None


def _write(path: pathlib.Path, blocks: list[dict[str, np.ndarray]], direct: bool,
           monkeypatch, extra_append: bool = False) -> None:
    """A dataset like the simulator's: two pulse-like scale-offset variables (one with chunks
    larger than HDF5's chunk cache: written at once), two unfiltered ones (``w`` like the
    ``trajectory`` velocity: more whole chunks than the cache holds, the direct path's raw
    bytes), appended block by block in uneven blocks."""
    monkeypatch.setattr(dataset, "DIRECT_CHUNKS", direct)
    with dataset.DatasetWriter(path, {"seed": 1}) as w:
        g = w.group("imu", "test group")
        g.dimension("sample")
        g.coordinate("axis", ["x", "y", "z"], description="axis")
        g.variable("p", ("sample", "axis"), units="1", dtype=np.int32, description="pulses",
                   storage={"scaleoffset": 0, "chunks": (4096, 3)})
        g.variable("q", ("sample",), units="1", dtype=np.int16, description="small pulses",
                   storage={"scaleoffset": 0, "chunks": (4096,)})
        g.variable("big", ("sample", "axis"), units="1", dtype=np.int32, description="big chunks",
                   storage={"scaleoffset": 0, "chunks": (700_000, 3)})       # > 8 MiB
        g.variable("v", ("sample",), units="V", dtype=np.float32, description="unfiltered")
        g.variable("w", ("sample", "axis"), units="m s-1", description="unfiltered float64",
                   storage={"chunks": (4096, 3)})
        for rows in blocks:
            g.append("sample", rows)
        if extra_append:
            g.flush()
            g.append("sample", blocks[0])


def _blocks(rng: np.random.Generator, n: int) -> list[dict[str, np.ndarray]]:
    sizes = rng.integers(1, 60_000, n)
    out = []
    for m in sizes:
        p = rng.integers(-3, 4, (m, 3)).astype(np.int32)
        p[: m // 3] = rng.integers(-2000, 2000, (m // 3, 3))
        out.append({"p": p, "q": rng.integers(-5, 5, m).astype(np.int16),
                    "big": rng.integers(-9, 9, (m, 3)).astype(np.int32),
                    "v": rng.standard_normal(m).astype(np.float32),
                    "w": rng.standard_normal((m, 3))})
    return out


def test_the_direct_path_writes_the_same_file(tmp_path, monkeypatch):
    """More chunks than HDF5's chunk cache holds (its evictions interleave with the other
    datasets' writes), a partial last chunk, chunks too big for the cache."""
    blocks = _blocks(np.random.default_rng(7), 50)
    rows = sum(len(b["v"]) for b in blocks)
    with h5py.File(tmp_path / "probe.h5", "w") as f:
        cache_bytes = f.id.get_access_plist().get_cache()[2]
    assert rows > 2 * cache_bytes // (4096 * 3 * 4)       # the cache overflows
    for direct in (False, True):
        _write(tmp_path / f"{direct}.h5", blocks, direct, monkeypatch)
    assert (tmp_path / "True.h5").read_bytes() == (tmp_path / "False.h5").read_bytes()
    with h5py.File(tmp_path / "True.h5") as f:
        for name in ("p", "q", "big", "v", "w"):
            np.testing.assert_array_equal(f["imu"][name][...],
                                          np.concatenate([b[name] for b in blocks]))


def test_without_numba_the_numpy_packer_writes_the_same_file(tmp_path, monkeypatch):
    import importlib.util
    import sys

    import rlgsim.sim.writer._direct_chunks as direct
    blocks = _blocks(np.random.default_rng(3), 12)
    _write(tmp_path / "hdf5.h5", blocks, False, monkeypatch)
    find_spec = importlib.util.find_spec
    monkeypatch.delitem(sys.modules, "numba", raising=False)
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "numba" else find_spec(name, *a))
    calls, encode_ = [], direct.encode

    def spy(*args, **kwargs):
        calls.append(kwargs["compiled"])
        return encode_(*args, **kwargs)
    monkeypatch.setattr(direct, "encode", spy)
    _write(tmp_path / "numpy.h5", blocks, True, monkeypatch)
    assert calls and not any(calls)
    assert (tmp_path / "numpy.h5").read_bytes() == (tmp_path / "hdf5.h5").read_bytes()


def test_rows_appended_after_a_flush_are_all_stored(tmp_path, monkeypatch):
    blocks = _blocks(np.random.default_rng(8), 6)
    _write(tmp_path / "x.h5", blocks, True, monkeypatch, extra_append=True)
    with h5py.File(tmp_path / "x.h5") as f:
        for name in ("p", "q", "big", "v", "w"):
            want = np.concatenate([b[name] for b in blocks + blocks[:1]])
            np.testing.assert_array_equal(f["imu"][name][...], want)


def test_a_simulated_dataset_is_the_same_file_either_way(tmp_path, monkeypatch):
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    paths = {}
    for direct in (False, True):
        monkeypatch.setattr(dataset, "DIRECT_CHUNKS", direct)
        paths[direct] = simulate(load_scenario("quickstart"), tmp_path / f"{direct}.h5",
                                 progress=False)
    assert paths[True].read_bytes() == paths[False].read_bytes()


def test_an_added_group_is_the_same_file_either_way(tmp_path, monkeypatch):
    blocks = _blocks(np.random.default_rng(9), 8)
    for direct in (False, True):
        path = tmp_path / f"{direct}.h5"
        _write(path, blocks[:2], False, monkeypatch)
        monkeypatch.setattr(dataset, "DIRECT_CHUNKS", direct)
        with dataset.add_group(path, "extra", "added") as g:
            g.dimension("sample")
            g.variable("p", ("sample",), units="1", dtype=np.int32, description="pulses",
                       storage={"scaleoffset": 0, "chunks": (4096,)})
            for b in blocks:
                g.append("sample", {"p": b["q"].astype(np.int32)})
    assert (tmp_path / "True.h5").read_bytes() == (tmp_path / "False.h5").read_bytes()


def test_the_self_check_passes_here_and_sees_a_wrong_flush_order(monkeypatch):
    """The once-per-process check (sim/writer/_direct_check.py) agrees with this HDF5, and it does
    compare layouts: chunks the mirror flushes at close in the wrong order fail it."""
    import rlgsim.sim.writer._direct_chunks as direct
    from rlgsim.sim.writer._direct_check import direct_path_agrees
    writer = (dataset.GroupWriter, dataset._close_stages)
    assert direct_path_agrees(*writer)
    assert dataset._DIRECT_OK is not False and dataset._direct_path_ok()   # the process's too
    close = direct.DirectChunks.close

    def reversed_close(self):
        self.pending.reverse()
        close(self)
    monkeypatch.setattr(direct.DirectChunks, "close", reversed_close)
    assert not direct_path_agrees(*writer)


def test_a_failed_self_check_keeps_hdf5s_filter(tmp_path, monkeypatch):
    """When the self-check fails the direct path stays off for the process (the check runs
    once) and the writer's file is HDF5's own, byte for byte."""
    import rlgsim.sim.writer._direct_check as check
    import rlgsim.sim.writer._direct_chunks as direct
    blocks = _blocks(np.random.default_rng(5), 10)
    _write(tmp_path / "hdf5.h5", blocks, False, monkeypatch)
    checks, mirrors, of = [], [], direct.DirectChunks.of
    monkeypatch.setattr(dataset, "_DIRECT_OK", None)
    monkeypatch.setattr(check, "direct_path_agrees", lambda *a: checks.append(1) or False)
    monkeypatch.setattr(direct.DirectChunks, "of",
                        staticmethod(lambda *a, **k: mirrors.append(1) or of(*a, **k)))
    for run in range(2):
        _write(tmp_path / f"direct{run}.h5", blocks, True, monkeypatch)
        assert (tmp_path / f"direct{run}.h5").read_bytes() == (tmp_path / "hdf5.h5").read_bytes()
    assert checks == [1] and not mirrors and dataset._DIRECT_OK is False
    monkeypatch.setattr(dataset, "_DIRECT_OK", True)        # the path is taken when it passes
    _write(tmp_path / "on.h5", blocks, True, monkeypatch)
    assert mirrors


def test_chunks_written_from_compiled_code_are_h5pys_calls():
    """sim/writer/_chunk_calls.write_chunks (H5Dwrite_chunk without the GIL, h5py's lock held)
    writes the file h5py's write_direct_chunk writes, byte for byte; a chunk HDF5 refuses (an
    offset off the chunk grid) is reported by its index, with nothing written after it."""
    from rlgsim.sim.writer._chunk_calls import available, write_chunks
    if not available():
        pytest.skip("h5py without its own HDF5 library: h5py's write_direct_chunk is kept")
    rng = np.random.default_rng(3)
    chunks = [rng.integers(0, 256, int(rng.integers(1, 900)), dtype=np.uint8) for _ in range(5)]
    buf = np.concatenate(chunks)
    ends = np.concatenate([[0], np.cumsum([c.size for c in chunks])]).astype(np.int64)
    images = []
    for compiled in (True, False):
        with h5py.File(f"calls-{compiled}.h5", "w", driver="core", backing_store=False,
                       libver=("earliest", "v110"), rdcc_nbytes=0) as f:
            ds = f.create_dataset("p", shape=(5 * 64, 3), maxshape=(None, 3), chunks=(64, 3),
                                  dtype=np.int32, scaleoffset=0)
            if compiled:
                with h5py._objects.phil:
                    assert write_chunks(ds.id.id, 10, 64, 2, buf, ends, 0) == 0  # row 10
                    assert ds.id.get_num_chunks() == 0
                    assert write_chunks(ds.id.id, 0, 64, 2, buf, ends, 0) == -1
            else:
                for j in range(5):
                    ds.id.write_direct_chunk((64 * j, 0), chunks[j])
            f.flush()
            images.append(f.id.get_file_image())
    assert images[0] == images[1]
