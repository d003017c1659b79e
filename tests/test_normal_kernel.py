"""The compiled float32 normals (sim/sensors/_normal_kernel.py) are numpy's
``Generator.standard_normal(n, dtype=np.float32)``, and its float64 ones (the
IMU's slow-noise and UHFO drives, ``fill_streams``) numpy's ``standard_normal(shape)``, bit for bit. The float32 ones: on the simulator's own
streams (the seed tree's white-noise leaves), for any channel count and length, leaving each
generator in numpy's state, with the ziggurat's rare branches reached — the tail (|z| beyond
the last strip, r ≈ 3.654) thousands of times and the wedges about 0.7 % of all draws (the
branch where numba's own float32 normal parts from numpy's stream)."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.sim.sensors import _normal_kernel
from rlgsim.sim.rng import generator

#: NumPy's ziggurat_nor_r_f: where the ziggurat's base strip hands over to the tail
TAIL_START = np.float32(3.6541528853610087963519472518)


def numpy_normals(generators, n: int) -> np.ndarray:
    out = np.empty((len(generators), n), dtype=np.float32)
    for g, row in zip(generators, out):
        g.standard_normal(n, dtype=np.float32, out=row)
    return out


def test_the_self_check_passes_here():
    assert _normal_kernel.available()


def test_the_simulators_streams_are_numpys_draws():
    """~29 million draws: 80 blocks × two triads × 20 000 samples of the white-noise leaves of
    three (seed, unit) pairs."""
    tails = 0
    for seed, unit in ((0, 0), (7, 3), (2**40 + 5, 11)):
        for b in range(0, 80 * 37, 37):
            for purpose in ("gyro.white", "accel.white"):
                ours = [generator(seed, unit, purpose, ax, b) for ax in "xyz"]
                theirs = [generator(seed, unit, purpose, ax, b) for ax in "xyz"]
                got = np.empty((3, 20_000), dtype=np.float32)
                _normal_kernel.fill(ours, got)
                ref = numpy_normals(theirs, 20_000)
                assert got.tobytes() == ref.tobytes(), (seed, unit, b, purpose)
                tails += int(np.count_nonzero(np.abs(ref) > TAIL_START))
                assert all(x.bit_generator.state == y.bit_generator.state
                           for x, y in zip(ours, theirs))
    # P(|z| > 3.654) = 2.6e-4: ~7 500 of the 28.8 million draws came from the tail branch
    assert tails > 5_000


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
@pytest.mark.parametrize("n", [0, 1, 7, 100_003])
def test_any_channel_count_and_length(channels, n):
    ours = [np.random.default_rng([channels, n, c]) for c in range(channels)]
    theirs = [np.random.default_rng([channels, n, c]) for c in range(channels)]
    got = np.empty((channels, n), dtype=np.float32)
    _normal_kernel.fill(ours, got)
    assert got.tobytes() == numpy_normals(theirs, n).tobytes()
    # the generators go on as numpy's do
    assert all(x.standard_normal(5).tobytes() == y.standard_normal(5).tobytes()
               for x, y in zip(ours, theirs))


def test_draws_continue_a_used_generator():
    """A generator that has already drawn (an odd number of 32-bit halves buffered) goes on
    with numpy's next value."""
    ours, theirs = np.random.default_rng(99), np.random.default_rng(99)
    ours.standard_normal(3, dtype=np.float32)
    theirs.standard_normal(3, dtype=np.float32)
    got = np.empty((1, 1001), dtype=np.float32)
    _normal_kernel.fill([ours], got)
    assert got.tobytes() == theirs.standard_normal(1001, dtype=np.float32).tobytes()


def test_other_bit_generators_are_drawn_by_numpy_and_advance_false_leaves_the_state():
    def gens():
        return [np.random.Generator(np.random.PCG64(1)), np.random.Generator(np.random.Philox(2)),
                np.random.Generator(np.random.PCG64(3))]
    ours, theirs = gens(), gens()
    got = np.empty((3, 5000), dtype=np.float32)
    _normal_kernel.fill(ours, got)
    assert got.tobytes() == numpy_normals(theirs, 5000).tobytes()
    assert all(str(x.bit_generator.state) == str(y.bit_generator.state)
               for x, y in zip(ours, theirs))
    kept = np.random.default_rng(4)
    before = kept.bit_generator.state
    _normal_kernel.fill([kept], np.empty((1, 100), dtype=np.float32), advance=False)
    assert kept.bit_generator.state == before


def test_rows_and_generators_must_match_one_to_one():
    g = np.random.default_rng(5)
    with pytest.raises(ValueError, match="its own generator"):
        _normal_kernel.fill([g, g], np.empty((2, 10), dtype=np.float32))
    with pytest.raises(ValueError, match="C-contiguous float32 array of 2 rows"):
        _normal_kernel.fill([g, np.random.default_rng(6)], np.empty((3, 10), dtype=np.float32))
    with pytest.raises(ValueError, match="C-contiguous float32"):
        _normal_kernel.fill([g], np.empty((1, 10)))


def _drive_simulator(compiled: bool):
    from rlgsim.sim.run.scenario import load_device
    from rlgsim.sim.sensors.imu import ImuSimulator
    from rlgsim.sim.sensors.imu_model import ImuModel
    dev = load_device("rlg_imu_000")
    real = ImuModel.from_device(dev).realise(generator(3, 0, "realisation", "imu", 0))
    return ImuSimulator(real, dev.thermal.network.node_names, seed=7, unit=2, rate_hz=100.0,
                        step_s=1.0, prefetch=False, compiled=compiled)


@pytest.mark.parametrize("m", [0, 1, 7, 600])
def test_the_slow_noise_and_uhfo_drives_are_numpys_float64_draws(m):
    """The IMU's per-block drives (flicker bank, random walk, UHFO wander and read-out: one
    :func:`fill_streams` call each, PCG64 seeded in the kernel) against numpy's own draws from
    the tree's generators, over blocks of the same tree (64 blocks share a seed table)."""
    from rlgsim.sim.sensors import imu
    assert imu._compiled("fill_streams") is not None            # else both sides would be numpy's
    ours, theirs = _drive_simulator(True), _drive_simulator(False)
    assert ours.r.uhfo is not None and ours.slow.has_flicker and ours.slow.has_walk
    tails = 0
    for b in (0, 1, 63, 64, 700):
        got, ref = ours._drive_draws(b, m), theirs._drive_draws(b, m)
        arrays = [*got["slow_draws"], *got["uhfo_draws"]]
        refs = [*ref["slow_draws"], *ref["uhfo_draws"]]
        for x, y in zip(arrays, refs):
            assert x.shape == y.shape and x.flags.c_contiguous
            assert x.tobytes() == y.tobytes(), b
            tails += int(np.count_nonzero(np.abs(y) > 3.6541528853610088))
    if m == 600:        # ~216 000 draws: ~56 expected beyond the float64 ziggurat's last strip
        assert tails > 20


def test_fill_streams_refuses_what_it_cannot_draw():
    base = np.zeros((4, 5))
    words = np.zeros((1, 4), dtype=np.uint64)
    with pytest.raises(ValueError, match="float64 array"):
        _normal_kernel.fill_streams(words, base[:, ::2], np.zeros((1, 5), dtype=np.int64))
    with pytest.raises(ValueError, match="words must be"):
        _normal_kernel.fill_streams(words, base, np.zeros((2, 5), dtype=np.int64))
    for view in [(0, 1, 0, 21, 1), (-1, 1, 0, 2, 1), (19, 2, 1, 1, 1), (5, 2, 5, 3, -3)]:
        with pytest.raises(ValueError, match="inside base"):
            _normal_kernel.fill_streams(words, base, np.array([view], dtype=np.int64))
    _normal_kernel.fill_streams(words, base, np.array([(7, 0, 5, 3, 1)], dtype=np.int64))
    assert not base.any()                   # an empty view draws nothing


def test_the_float64_draw_has_no_fused_multiply_add():
    """The wedge test (f[i−1] − f[i])·u + f[i] must round the product before the sum, as
    numpy's x86-64 build does (no fastmath: LLVM does not contract)."""
    import re

    from numba_asm import FMA, compiled_asm
    _normal_kernel.fill_streams(np.zeros((1, 4), dtype=np.uint64), np.zeros(4),
                                np.array([(0, 1, 0, 2, 1)], dtype=np.int64))
    kernel = _normal_kernel._fill_seeded
    assert not re.search(FMA, compiled_asm(kernel, kernel.signatures[0]))
