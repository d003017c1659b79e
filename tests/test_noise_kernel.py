"""The compiled slow noise (sim/sensors/_noise_kernel.py) equals the NumPy path (scipy's lfilter per
flicker process, numpy's cumsum for the walk) bit for bit: flicker and walk together and each
alone, channels without either term, blocks carried one after another, one-step blocks."""

from __future__ import annotations

import numpy as np
import pytest

import rlgsim.sim.sensors.noise as noise
from rlgsim.sim.sensors.noise import NoiseModel, SlowNoise

pytest.importorskip("rlgsim.sim.sensors._noise_kernel")


def run(slow: SlowNoise, lengths: list[int], compiled: bool, monkeypatch) -> list:
    if not compiled:
        monkeypatch.setattr(noise, "_compiled_slow_block", lambda: None)
    else:
        monkeypatch.setattr(noise, "_compiled_slow_block",
                            lambda: __import__("rlgsim.sim.sensors._noise_kernel",
                                               fromlist=["slow_block"]).slow_block)
    state = slow.initial_state()
    out = []
    for b, m in enumerate(lengths):
        x, state = slow.block(state, b, m)
        out.append((x, state[0].copy(), state[1].copy()))
    monkeypatch.undo()
    return out


@pytest.mark.parametrize("bi, rrw", [
    ([1e-7, 2e-7, 0.0, 3e-5, 1e-5, 0.0], [1e-9, 0.0, 2e-9, 1e-7, 0.0, 0.0]),
    ([1e-7, 2e-7, 5e-7, 3e-5, 1e-5, 2e-5], [0.0] * 6),
    ([0.0] * 6, [1e-9, 3e-9, 2e-9, 1e-7, 2e-7, 3e-7]),
    ([0.0] * 6, [0.0] * 6),
])
def test_compiled_slow_noise_is_bit_identical(bi, rrw, monkeypatch):
    slow = SlowNoise(np.array(bi), np.array(rrw), 1.0, NoiseModel(),
                     ("x", "y", "z", "x", "y", "z"), seed=11, unit=2,
                     purpose=("gyro",) * 3 + ("accel",) * 3)
    lengths = [600, 600, 1, 37, 600]
    ref = run(slow, lengths, False, monkeypatch)
    new = run(slow, lengths, True, monkeypatch)
    for (x0, f0, w0), (x1, f1, w1) in zip(ref, new):
        assert x0.shape == x1.shape
        assert x0.tobytes() == x1.tobytes()
        assert f0.tobytes() == f1.tobytes()
        assert w0.tobytes() == w1.tobytes()
    if any(bi) or any(rrw):
        assert np.any(ref[0][0] != 0.0)          # the comparison compared noise


def test_no_fused_multiply_add_in_the_compiled_slow_noise():
    """The kernel must round each product before the sum, as numpy and scipy do here."""
    import re

    from numba_asm import FMA, compiled_asm

    import rlgsim.sim.sensors._noise_kernel as kernel
    slow = SlowNoise(np.array([1e-7] * 2), np.array([1e-9] * 2), 1.0, NoiseModel(), ("x", "y"),
                     seed=1, unit=0, purpose="gyro")
    kernel.slow_block(*_kernel_args(slow, 5))              # compiles / loads the signature
    asm = compiled_asm(kernel.slow_block, kernel.slow_block.signatures[0])
    assert not re.search(FMA, asm)


def _kernel_args(slow: SlowNoise, m: int) -> tuple:
    fs, ws = slow.initial_state()
    wf, wr = slow.draws(0, m)
    c = len(slow.axes)
    return (wf, slow.flicker.phi, slow.flicker.q, fs, wr,
            slow.walk.k * np.sqrt(slow.walk.dt), ws, True, True, np.empty((m, c)),
            np.empty_like(fs), np.empty_like(ws))
