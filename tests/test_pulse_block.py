"""The one-call compiled counter (sim/sensors/_pulse_kernel.py ``count_block``) against the NumPy
reference path where its own structure could go wrong: steps longer than a chunk (a step's
samples split over several chunks, a partial last chunk), a step index per sample over many
chunks, every combination of white noise / K⁺K⁻ / power, one to three channels, and one channel
that fails the fast range test while the others pass (only that channel is recounted)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rlgsim.sim.sensors import pulses
from rlgsim.sim.sensors._pulse_kernel import CHUNK
from rlgsim.sim.sensors.sensor_triad import (count_pulses, installation_rows, sample_step_index,
                                     step_inputs)


def _block(seed: int, m: int, rate_hz: float, step_s: float, c: int, *, noise: bool,
           neg: bool, power_off: bool) -> dict:
    rng = np.random.default_rng(seed)
    n = int(np.floor(m * step_s * rate_hz + 1e-9))
    idx = sample_step_index(n, m, rate_hz, step_s)
    x = rng.normal(0.0, 1e-4, (3, n)) + rng.normal(0, 1e-5, (3, 1))
    if isinstance(idx, int):                        # every other step at rest
        xs = x.reshape(3, m, idx)
        for i in range(0, m, 2):
            xs[:, i, :] = xs[:, i, :1]
    axes = rng.permutation(3)[:c]
    power = None
    if power_off:
        power = np.ones(m)
        power[1:m:3] = 0.0
    return dict(remainder=rng.integers(0, pulses.ONE, c),
                scale_factor=2.0e5 * (1.0 + rng.normal(0, 1e-4, (m, c))),
                bias=rng.normal(0, 1e-5, (m, c)),
                installation=installation_rows(rng.normal(0, 1e-4, (m, 2 * c)), axes),
                x_t=np.ascontiguousarray(x),
                z=rng.standard_normal((c, n), dtype=np.float32) if noise else None,
                sigma=np.abs(rng.normal(0, 3e-6, c)), sample_dt=1.0 / rate_hz, idx=idx,
                power=power, own_axis=axes,
                scale_factor_neg=(2.0e5 * (1.0 + rng.normal(0, 1e-4, (m, c))) if neg
                                  else None),
                steps=step_inputs(np.ascontiguousarray(x), m, idx))


def _same(kw: dict) -> None:
    got, got_rem = count_pulses(**kw)
    ref, ref_rem = count_pulses(**kw, compiled=False)
    assert got.dtype == np.int32 and got.shape == ref.shape
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(got_rem, ref_rem)


LAYOUTS = [
    (5, 100.0, 13.0),      # 1300 samples per step: chunks of CHUNK and a partial last one
    (4, 2 * CHUNK, 1.0),   # exactly two chunks per step
    (3, 1000.0, 0.7),      # 700 per step
    (9, 333.3, 1.0),       # 333.3 per step: a step index per sample, over several chunks
]


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("noise,neg,power_off", list(itertools.product([False, True],
                                                                       repeat=3)))
def test_block_kernel_equals_the_numpy_path(layout, noise, neg, power_off):
    m, rate, step = layout
    for c in (1, 2, 3):
        kw = _block(c + 10 * m, m, rate, step, c, noise=noise, neg=neg, power_off=power_off)
        _same(kw)
        _same({**kw, "steps": None})


def test_only_the_channel_beyond_the_fast_range_test_is_recounted(monkeypatch):
    """One sample of channel 1 near the per-sample limit: the peak × n test fails although
    the block total is within range, so the NumPy path counts that channel (no error) and the
    kernel's counts stand for the others."""
    kw = _block(4, 4, 100.0, 1.0, 3, noise=True, neg=False, power_off=False)
    k = kw["scale_factor"][0, 1]
    kw["x_t"] = kw["x_t"].copy()
    kw["x_t"][kw["own_axis"][1], 150] = 0.5 * pulses.MAX_SAMPLE_PULSES / k   # step 1 moves
    kw["steps"] = step_inputs(kw["x_t"], 4, 100)
    recounted = []
    count_scaled = pulses.count_scaled

    def spy(u, r, out):
        recounted.append(r)
        return count_scaled(u, r, out)
    monkeypatch.setattr(pulses, "count_scaled", spy)
    got, rem = count_pulses(**kw)
    assert len(recounted) == 1                  # channel 1 only
    monkeypatch.undo()
    ref, ref_rem = count_pulses(**kw, compiled=False)
    assert got[150, 1] > 2**29
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(rem, ref_rem)


@pytest.mark.parametrize("r", [1, 7, 500, 1300])
def test_compiled_step_scan_equals_the_numpy_one(r):
    """steps_at_rest: the same steps at rest and first samples as the NumPy comparison, with
    differences that only the bits see (+0 / −0, NaN payloads) and in any sample or axis."""
    rng = np.random.default_rng(r)
    m = 12
    xs = np.repeat(rng.normal(0, 1e-6, (3, m, 1)), r, axis=2)
    if r > 1:
        xs[0, 1, -1] = np.nextafter(xs[0, 1, -1], 1.0)       # last sample, last bit
        xs[2, 2, r // 2] *= 1.0 + 2**-52
        xs[:, 3] = 0.0
        xs[1, 3, 1] = -0.0                                    # equal as floats, not as bits
        xs[:, 4] = np.nan
        xs[2, 5, 0] = np.inf                                  # the first sample differs
        xs[:, 6] = rng.normal(0, 1e-6, (3, r))                # turning
    x_t = np.ascontiguousarray(xs.reshape(3, m * r))
    ref_u, ref_f = step_inputs(x_t, m, r, compiled=False)
    got_u, got_f = step_inputs(x_t, m, r, compiled=True)
    np.testing.assert_array_equal(got_u, ref_u)
    assert got_f.tobytes() == ref_f.tobytes() and got_f.flags.c_contiguous
    if r > 1:
        assert ref_u.tolist() == [True, False, False, False, True, False, False] + [True] * 5
    assert step_inputs(x_t, m, r + 1, compiled=True) is None


def test_step_scan_imports_no_compiled_code_by_itself(monkeypatch):
    """Auto mode: without the compiled counter loaded the NumPy scan runs and the kernel module
    is not imported (a short run never imports numba for the scan); once it is loaded, the
    compiled scan runs."""
    import sys

    import rlgsim.sim.sensors._pulse_kernel as kernel
    x_t = np.zeros((3, 40))
    calls = []
    real = kernel.steps_at_rest

    def spy(*args):
        calls.append(1)
        real(*args)
    monkeypatch.setattr(kernel, "steps_at_rest", spy)
    monkeypatch.delitem(sys.modules, "rlgsim.sim.sensors._pulse_kernel")
    uniform, _ = step_inputs(x_t, 4, 10)
    assert "rlgsim.sim.sensors._pulse_kernel" not in sys.modules and uniform.all() and not calls
    monkeypatch.setitem(sys.modules, "rlgsim.sim.sensors._pulse_kernel", kernel)
    step_inputs(x_t, 4, 10)
    assert calls == [1]
