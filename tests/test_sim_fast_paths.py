"""The simulator's fast paths give exactly what the plain paths give:

* ``sensor_triad.count_pulses`` (one buffer per channel, 2^30 folded into the scale factor,
  steps at rest evaluated once per step) against the documented recipe —
  ``phase_increments`` then ``pulses.count_fixed(pulses.quantise(inc), remainder)`` per
  channel — bit for bit, with moving and resting steps, unpowered steps, two-sided scale
  factors and a sample rate that is not a whole multiple of the thermal step;
* ``step_inputs`` calls a step at rest only when every sample has the same bits (±0 differ);
* ``GroupWriter``'s chunk staging stores the same arrays whatever the sizes of the appends;
* an error in the writer thread stops the run with that error and leaves no file.
"""

from __future__ import annotations

import pathlib
import threading

import h5py
import numpy as np
import pytest

from rlgsim.sim.writer import dataset
from rlgsim.sim.sensors import pulses
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.sensors.sensor_triad import (count_pulses, installation_rows, phase_increments,
                                     sample_step_index, step_inputs)
from rlgsim.sim.run.simulate import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _case(rng: np.random.Generator, m: int, rate_hz: float, step_s: float, rest: float):
    """Random inputs of one block: m steps, some at rest (every sample the same increment)."""
    n = int(np.floor(m * step_s * rate_hz + 1e-9))
    idx = sample_step_index(n, m, rate_hz, step_s)
    x_t = rng.normal(0.0, 1e-4, (3, n))
    if isinstance(idx, int):
        xs = x_t.reshape(3, m, idx)
        at_rest = rng.random(m) < rest
        xs[:, at_rest, :] = xs[:, at_rest, :1]
    own = np.array([0, 1, 2])
    inst = installation_rows(rng.normal(0.0, 1e-4, (m, 6)), own)
    k = 4.4e5 * (1.0 + rng.normal(0.0, 1e-4, (m, 3)))
    kn = 4.4e5 * (1.0 + rng.normal(0.0, 1e-4, (m, 3)))
    bias = rng.normal(0.0, 1e-6, (m, 3))
    z = rng.standard_normal((3, n), dtype=np.float32)
    sigma = np.array([1e-6, 2e-6, 0.0])
    power = (rng.random(m) > 0.1).astype(float)
    rem = rng.integers(0, pulses.ONE, 3)
    return x_t, idx, inst, k, kn, bias, z, sigma, power, own, rem


def _reference(rem, k, bias, inst, x_t, z, sigma, dt, idx, power, own, kn):
    inc = phase_increments(k, bias, inst, x_t, z, sigma, dt, idx, power, own,
                           scale_factor_neg=kn)
    out = np.empty((inc.shape[1], inc.shape[0]), dtype=np.int32)
    new = np.zeros(inc.shape[0], dtype=np.int64)
    for s in range(inc.shape[0]):
        out[:, s], new[s] = pulses.count_fixed(pulses.quantise(inc[s].copy()), int(rem[s]))
    return out, new


@pytest.mark.parametrize("rate_hz,step_s", [(100.0, 1.0), (7.0, 1.0), (50.0, 0.2)])
@pytest.mark.parametrize("two_sided", [False, True])
def test_count_pulses_is_the_documented_recipe(rate_hz, step_s, two_sided):
    rng = np.random.default_rng(int(rate_hz * 10 + two_sided))
    for trial in range(6):
        x_t, idx, inst, k, kn, bias, z, sigma, power, own, rem = _case(
            rng, 40, rate_hz, step_s, rest=(0.0, 0.5, 1.0)[trial % 3])
        kn = kn if two_sided else None
        dt = 1.0 / rate_hz
        want = _reference(rem, k, bias, inst, x_t, z, sigma, dt, idx, power, own, kn)
        steps = step_inputs(x_t, 40, idx)
        assert (steps is None) == (not isinstance(idx, int))
        for st in (steps, None):
            got = count_pulses(rem, k, bias, inst, x_t, z, sigma, dt, idx, power, own, kn,
                               steps=st)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])
        without_noise = count_pulses(rem, k, bias, inst, x_t, None, sigma, dt, idx, None,
                                     own, kn, steps=steps)
        np.testing.assert_array_equal(
            without_noise[0],
            _reference(rem, k, bias, inst, x_t, None, sigma, dt, idx, None, own, kn)[0])


def test_step_inputs_compares_bits():
    x = np.ones((3, 40))
    x[1, 13] = 1.0 + 2e-16                      # one sample of step 1 differs by one ulp
    x[2, 25:30] = 0.0
    x[2, 27] = -0.0                             # ±0: a different increment
    uniform, first = step_inputs(x, 4, 10)
    assert uniform.tolist() == [True, False, False, True]
    np.testing.assert_array_equal(first, x[:, ::10])
    assert step_inputs(x, 3, 10) is None        # n != m·idx
    assert step_inputs(x, 4, np.zeros(40, dtype=int)) is None


def test_chunk_staging_stores_the_same_arrays_for_any_appends(tmp_path):
    rng = np.random.default_rng(5)
    data = rng.integers(-1000, 1000, (20000, 3)).astype(np.int32)
    t = np.arange(20000, dtype=float)

    def write(path, sizes):
        with dataset.DatasetWriter(path, {}) as w:
            g = w.group("g", "test")
            g.dimension("sample")
            g.coordinate("axis", ["x", "y", "z"], description="axis")
            g.variable("p", ("sample", "axis"), units="1", dtype=np.int32, description="p",
                       storage={"scaleoffset": 0, "chunks": (4096, 3)})
            g.coordinate("time", growing=True, units="s", description="t")
            g.variable("f", ("time",), units="1", dtype=np.float32, description="f")
            pos = 0
            for k in sizes:
                g.append("sample", {"p": data[pos:pos + k]})
                g.append("time", {"time": t[pos:pos + k], "f": t[pos:pos + k] * 0.5})
                pos += k
        with h5py.File(path) as f:
            return f["g/p"][()], f["g/time"][()], f["g/f"][()], f["g/sample"].shape

    one = write(tmp_path / "one.h5", [20000])
    for i, sizes in enumerate(([1] * 5 + [4091, 4096, 8192, 3616], [7, 9000, 10993],
                               [4096] * 4 + [3616], [19999, 1])):
        assert sum(sizes) == len(data)
        got = write(tmp_path / f"{i}.h5", sizes)
        np.testing.assert_array_equal(got[0], data)
        for a, b in zip(got, one):
            np.testing.assert_array_equal(a, b)


def test_an_error_in_the_writer_thread_stops_the_run(tmp_path, monkeypatch):
    text = (ROOT / "scenarios" / "quickstart.toml").read_text().replace(
        "duration_h = 2.0", "duration_h = 1.0")
    sc = parse_scenario(text, "quick.toml")
    real = dataset.GroupWriter.append
    calls = []

    def failing(self, dim, rows):
        calls.append(dim)
        if len(calls) == 20:
            raise OSError("disk full (test)")
        return real(self, dim, rows)
    monkeypatch.setattr(dataset.GroupWriter, "append", failing)
    with pytest.raises(OSError, match="disk full"):
        simulate(sc, tmp_path / "run.h5", progress=False, chunk_s=600.0)
    assert list(tmp_path.iterdir()) == []
    assert not any(t.name == "rlgsim-writer" for t in threading.enumerate())
