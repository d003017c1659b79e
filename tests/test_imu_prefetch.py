"""The IMU stage's inputs: the per-step sums taken from the motion's runs of one increment
(against their plain definition, bit for bit), and blocks computed with their normals drawn
ahead in the worker thread against blocks computed in place (every array identical, a shorter
last block included, and with a copy of the carried state); a run that ends early stops the
thread."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from _imu_helpers import SITE, Trace, temperatures
from rlgsim.sim.sensors.imu import ImuSimulator, _held_steps, _step_sums, steps_held
from rlgsim.sim.sensors.imu_model import ImuModel
from rlgsim.sim.motion.kinematics import Motion, segments_from_program
from rlgsim.sim.rng import generator
from rlgsim.sim.run.scenario import load_device
from rlgsim.sim.sensors.sensor_triad import step_inputs
from rlgsim.sim.motion.turntable import Hold, Rotate, TurntableProgram


def plain_sums(x_t: np.ndarray, idx, m: int) -> np.ndarray:
    """The per-step sums as the stage computed them before: one reduction over all steps."""
    k, n = x_t.shape
    if isinstance(idx, int):
        return x_t.reshape(k, m, idx).sum(axis=2).T.copy()
    out = np.zeros((m, k))
    np.add.at(out, idx, x_t.T)
    return out


def same_bits(x: np.ndarray, y: np.ndarray) -> bool:
    x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
    return x.shape == y.shape and x.dtype == y.dtype and np.array_equal(
        x.view(np.uint8), y.view(np.uint8))


def held_block(rng: np.random.Generator, m: int, idx: int) -> tuple[np.ndarray, list]:
    """(3, m·idx) values with runs of one repeated column (values of every magnitude, ±0),
    and those runs, as a motion block reports them."""
    n = m * idx
    x = rng.standard_normal((3, n)) * 10.0 ** rng.integers(-12, 3, (3, 1))
    runs, lo = [], int(rng.integers(0, idx + 1))
    while lo < n:
        hi = min(n, lo + int(rng.integers(1, 5 * idx)))
        v = rng.choice([0.0, -0.0, 1e-300, rng.standard_normal() * 1e-7], 3)
        x[:, lo:hi] = v[:, None]
        runs.append((lo, hi))
        lo = hi + int(rng.integers(0, 2 * idx))      # turning samples between the runs
    return x, runs


@pytest.mark.parametrize("idx", [1, 2, 7, 8, 9, 73, 100, 128, 129, 1000])
def test_held_step_sums_are_the_plain_sums(idx):
    rng = np.random.default_rng(idx)
    for _ in range(10):
        m = int(rng.integers(1, 40))
        x, runs = held_block(rng, m, idx)
        held = _held_steps(runs, m, idx)
        assert same_bits(_step_sums(x, idx, m, held), plain_sums(x, idx, m))
        # the held runs are at rest by the bits too
        uniform, first = step_inputs(x, m, idx, compiled=False)
        for lo, hi in held:
            assert uniform[lo:hi].all()
        # known from the runs: at rest only where the bits say so, with the same sample
        u_held, f_held = steps_held(x, m, idx, held)
        assert not (u_held & ~uniform).any() and same_bits(f_held, first)


def test_uneven_steps_keep_the_plain_sums():
    x = np.random.default_rng(0).standard_normal((3, 73 * 5 + 2))
    idx = np.minimum(np.arange(x.shape[1]) // 73, 4)
    assert _held_steps([(0, 100)], 5, idx) is None
    assert same_bits(_step_sums(x, idx, 5, None), plain_sums(x, idx, 5))


def _simulator(prefetch: bool, n_steps: int, rate_hz: float) -> ImuSimulator:
    dev = load_device("rlg_imu_000")
    real = ImuModel.from_device(dev).realise(generator(3, 0, "realisation", "imu", 0))
    prog = TurntableProgram([Hold(150.3), Rotate("outer", 90.0, 20.0), Hold(90.0),
                             Rotate("inner", -180.0, 15.0), Hold(200.0)],
                            start_outer_deg=0.0, start_inner_deg=30.0)
    motion = Motion(segments_from_program(prog, n_steps + 600.0), SITE)
    return ImuSimulator(real, dev.thermal.network.node_names, seed=7, unit=0, rate_hz=rate_hz,
                        step_s=1.0, motion=motion, prefetch=prefetch, n_steps=n_steps)


@pytest.mark.parametrize("rate_hz, copied", [(100.0, False), (7.3, False), (100.0, True)])
def test_prefetched_blocks_are_the_blocks_computed_in_place(rate_hz, copied):
    """``copied``: each block gets a copy of the carried state, not the object the previous
    block returned."""
    n_steps, m = 1000, 300                      # three full blocks and a short last one
    names = load_device("rlg_imu_000").thermal.network.node_names
    out = []
    for prefetch in (True, False):
        sim = _simulator(prefetch, n_steps, rate_hz)
        state, rows = sim.initial_state(), []
        for b, k0 in enumerate(range(0, n_steps, m)):
            if copied and prefetch:
                state = copy.deepcopy(state)
            mb = min(m, n_steps - k0)
            t = (k0 + np.arange(1, mb + 1)) * 1.0
            nodes = temperatures(t, names, lambda t, j: 20.0 + 0.01 * t + j)
            start = temperatures(np.array([k0 * 1.0]), names, lambda t, j: 20.0 + 0.01 * t + j)[0]
            r, state = sim.block(state, b, Trace(t, 1.0, np.ones(mb), nodes, start))
            rows.append(r)
        assert sim._pool is None and not sim._ahead        # closed after the last block
        out.append(rows)
    compared = 0
    for got, ref in zip(*out):
        for group in ref:
            for dim in ref[group]:
                for var, arr in ref[group][dim].items():
                    assert same_bits(np.asarray(got[group][dim][var]), np.asarray(arr)), var
                    compared += 1
    assert compared > 40
    # the chain's slow noise is nothing but the drives of each block from the state before
    assert any(np.any(r["truth"]["time"]["gyro_bias_random"] != 0) for r in out[0])


def test_a_stopped_run_stops_the_prefetch_thread(tmp_path):
    """A run stopped after its first block (the worker started, blocks queued) stops the
    worker too."""
    import itertools
    import threading

    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate

    asked = itertools.count()
    with pytest.raises(KeyboardInterrupt):
        simulate(load_scenario("quickstart"), tmp_path / "x.h5", progress=False,
                 should_stop=lambda: next(asked) >= 1)
    assert next(asked) == 2                     # one block ran
    assert not [t for t in threading.enumerate() if t.name.startswith("rlgsim-imu")]
    assert not (tmp_path / "x.h5").exists()
