"""The compiled pulse counter (sim/sensors/_pulse_kernel.py) gives the NumPy reference path's pulses
and remainders bit for bit: both step layouts (r samples per step, or an index per sample),
steps at rest, white noise on/off, one scale factor or K⁺/K⁻, unpowered samples, carried
remainders; and a channel out of the counter's range raises the same one-line error."""

from __future__ import annotations

import re
import numpy as np
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.sensors import pulses
from rlgsim.sim.sensors.sensor_triad import (count_pulses, installation_rows, sample_step_index,
                                     step_inputs)


def block(seed: int, m: int, rate_hz: float, step_s: float, *, rest: bool, noise: bool,
          neg: bool, power_off: bool, c: int = 3):
    """A random block: laws on the step grid, increments with some steps at rest."""
    rng = np.random.default_rng(seed)
    n = int(np.floor(m * step_s * rate_hz + 1e-9))
    idx = sample_step_index(n, m, rate_hz, step_s)
    dt = 1.0 / rate_hz
    x = rng.normal(0.0, 1e-4, (3, n)) + rng.normal(0, 1e-5, (3, 1))
    if rest and isinstance(idx, int):               # every other step at rest (one increment)
        xs = x.reshape(3, m, idx)
        for i in range(0, m, 2):
            xs[:, i, :] = xs[:, i, :1]
    x_t = np.ascontiguousarray(x)
    k = 2.0e5 * (1.0 + rng.normal(0, 1e-4, (m, c)))
    kn = 2.0e5 * (1.0 + rng.normal(0, 1e-4, (m, c))) if neg else None
    bias = rng.normal(0, 1e-5, (m, c))
    inst = installation_rows(rng.normal(0, 1e-4, (m, 2 * c)), np.arange(c))
    z = rng.standard_normal((c, n), dtype=np.float32) if noise else None
    sigma = np.abs(rng.normal(0, 3e-6, c))
    power = None
    if power_off:
        power = np.ones(m)
        power[: m // 3] = 0.0
    rem = rng.integers(0, pulses.ONE, c)
    steps = step_inputs(x_t, m, idx)
    return dict(remainder=rem, scale_factor=k, bias=bias, installation=inst, x_t=x_t, z=z,
                sigma=sigma, sample_dt=dt, idx=idx, power=power, own_axis=np.arange(c),
                scale_factor_neg=kn, steps=steps)


CASES = [
    # (m, rate, step, rest, noise, neg, power_off)
    (50, 100.0, 1.0, True, True, False, False),
    (50, 100.0, 1.0, True, True, True, True),
    (40, 10.0, 2.0, False, False, False, False),
    (40, 10.0, 2.0, True, False, True, False),
    (37, 73.0, 1.0, False, True, True, True),        # 73 samples per s: an index per sample
    (30, 7.3, 1.0, False, True, False, False),       # 7.3 per step: an index per sample
]


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_counter_equals_the_numpy_path(case, seed):
    m, rate, step, rest, noise, neg, off = case
    kw = block(seed, m, rate, step, rest=rest, noise=noise, neg=neg, power_off=off)
    got, got_rem = count_pulses(**kw)
    ref, ref_rem = count_pulses(**kw, compiled=False)
    assert got.dtype == np.int32 and got.shape == ref.shape
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(got_rem, ref_rem)
    # and without the steps-at-rest hint (every sample evaluated)
    got2, rem2 = count_pulses(**{**kw, "steps": None})
    np.testing.assert_array_equal(got2, ref)
    np.testing.assert_array_equal(rem2, ref_rem)


def test_half_integer_increments_round_to_even_as_numpy():
    """u·2^30 exactly k + 1/2 (the fixed point's ties): rint rounds to even in both paths."""
    n, m = 40, 4
    x_t = np.zeros((3, n))
    x_t[0] = (np.arange(n) - 20 + 0.5) * 2.0 ** -30        # k + 1/2 in 2^-30 units
    kw = dict(remainder=np.array([5]), scale_factor=np.ones((m, 1)), bias=np.zeros((m, 1)),
              installation=installation_rows(np.zeros((m, 2)), np.array([0])), x_t=x_t,
              z=None, sigma=np.zeros(1), sample_dt=0.01, idx=10, own_axis=np.array([0]))
    got, rem = count_pulses(**kw)
    ref, ref_rem = count_pulses(**kw, compiled=False)
    np.testing.assert_array_equal(got, ref)
    assert rem[0] == ref_rem[0]
    q = np.rint(x_t[0] * 2.0 ** 30).astype(np.int64)
    assert rem[0] == 5 + q.sum()                             # below one pulse: all carried


@pytest.mark.parametrize("bad", [np.nan, 1e12])
def test_out_of_range_channel_raises_the_counter_error(bad):
    kw = block(3, 10, 100.0, 1.0, rest=False, noise=True, neg=False, power_off=False)
    kw["bias"][4, 1] = bad
    with pytest.raises(UserInputError, match="pulse counter") as compiled:
        count_pulses(**kw)
    with pytest.raises(UserInputError, match="pulse counter") as numpy_path:
        count_pulses(**kw, compiled=False)
    assert str(compiled.value) == str(numpy_path.value)


@pytest.mark.parametrize("scenario", ["quickstart", "demo_cycle"])
def test_a_run_stores_the_same_bytes_with_either_counter(tmp_path, monkeypatch, scenario):
    """End to end: the whole dataset (every array and attribute; the file byte for byte) of a
    run on the compiled paths (pulse counter, normals) equals the NumPy path's — whatever this
    process has loaded."""
    import rlgsim.sim.sensors.imu as imu
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate

    orig = imu.ImuSimulator.__init__
    paths = {}
    for compiled in (True, False):
        def init(self, *a, _c=compiled, **k):
            orig(self, *a, **{**k, "compiled": _c})
        monkeypatch.setattr(imu.ImuSimulator, "__init__", init)
        sc = load_scenario(scenario)
        paths[compiled] = simulate(sc, tmp_path / f"{compiled}.h5", progress=False,
                                   chunk_s=1800.0 if compiled else None)
    assert paths[True].read_bytes() == paths[False].read_bytes()


def test_the_counter_is_chosen_by_run_length_when_numba_is_not_loaded(monkeypatch):
    import sys

    import rlgsim.sim.sensors.imu as imu
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.schedule import build_timeline
    from rlgsim.sim.sensors.imu_model import ImuModel
    from rlgsim.sim.stages.imu import ImuStage

    sc = load_scenario("quickstart")                      # 2 h at 100 Hz: 720 000 epochs
    tl = build_timeline(sc)
    monkeypatch.delitem(sys.modules, "numba", raising=False)
    assert ImuStage(sc, tl, ImuModel.from_device(sc.device)).sim.compiled is False
    monkeypatch.setattr(imu, "COMPILED_MIN_EPOCHS", 700_000)
    assert ImuStage(sc, tl, ImuModel.from_device(sc.device)).sim.compiled is True


def test_the_kernel_has_no_fused_multiply_add():
    """No fastmath: LLVM may not contract a product and a sum into an FMA (a different
    rounding than numpy's separate multiply and add), and rint stays round-half-to-even."""
    from numba_asm import FMA, compiled_asm

    import rlgsim.sim.sensors._pulse_kernel as kernel
    kw = block(0, 4, 100.0, 1.0, rest=True, noise=True, neg=True, power_off=True)
    n, c = kw["x_t"].shape[1], 3
    kernel_args = (kw["x_t"], kw["installation"], kw["bias"], 0.01, kw["z"], kw["sigma"],
                   kw["scale_factor"], kw["scale_factor_neg"], float(pulses.ONE), 100,
                   np.zeros(0, np.int64), kw["steps"][0], kw["steps"][1], np.arange(c),
                   kw["power"], kw["remainder"], np.empty((n, c), np.int32),
                   np.empty(c, np.int64), np.empty(c, np.int64))
    kernel.count_block(*kernel_args)                 # compiles / loads the signature
    sig = next(s for s in kernel.count_block.signatures
               if s == tuple(kernel.count_block.typeof_pyval(a) for a in kernel_args))
    asm = compiled_asm(kernel.count_block, sig)
    assert not re.search(FMA, asm)


def test_heap_thresholds_are_set_once_and_change_no_value(tmp_path):
    """sim/run/_heap.py: on Linux with glibc the thresholds are set (True), elsewhere nothing is
    done (False); a run with them stores the same bytes as a run in a fresh process without
    them (the quickstart)."""
    import subprocess
    import sys

    from rlgsim.sim.run._heap import keep_freed_memory
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    first = keep_freed_memory()
    assert keep_freed_memory() is first
    if sys.platform.startswith("linux"):
        import ctypes
        try:
            ctypes.CDLL(None).gnu_get_libc_version
            assert first is True
        except AttributeError:
            assert first is False
    a = simulate(load_scenario("quickstart"), tmp_path / "a.h5", progress=False)
    code = ("import rlgsim.sim.run._heap as h; h._applied = False; "
            "from rlgsim.sim.run.scenario import load_scenario; "
            "from rlgsim.sim.run.simulate import simulate; "
            f"simulate(load_scenario('quickstart'), {str(tmp_path / 'b.h5')!r}, progress=False)")
    subprocess.run([sys.executable, "-c", code], check=True)
    assert a.read_bytes() == (tmp_path / "b.h5").read_bytes()
