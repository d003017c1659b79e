"""The compiled probe readings (sim/thermal/_probe_kernel.py) equal the NumPy path's bit for bit:
several lag groups and probes without lag, with and without quantisation (all, some, none),
noise-free probes, temperatures through zero, blocks carried one after another, and the
strided node-temperature view the simulator passes."""

from __future__ import annotations

import re
import numpy as np
import pytest

from rlgsim.sim.thermal.thermometers import ProbeSet

pytest.importorskip("rlgsim.sim.thermal._probe_kernel")


def probes(resolution: list[float]) -> ProbeSet:
    n = len(resolution)
    tau = [5.0, 5.0, 20.0, 0.0, 5.0, 0.7, 20.0, 0.0][:n]
    sigma = [0.01, 0.0, 0.02, 0.01, 0.01, 0.03, 0.0, 0.0][:n]
    return ProbeSet(names=tuple(f"p{i}" for i in range(n)),
                    node_index=np.array([0, 3, 1, 2, 3, 4, 0, 1][:n]),
                    tau_s=np.array(tau), noise_sigma_c=np.array(sigma),
                    resolution_c=np.array(resolution))


@pytest.mark.parametrize("resolution", [[0.0625] * 8, [0.0625, 0.0, 0.01, 0.0, 0.5, 0.0625,
                                                       0.0, 0.1], [0.0] * 8])
def test_compiled_readings_are_bit_identical(resolution):
    p = probes(resolution)
    m_total = 700
    # a full state array as the simulator holds it: column 0 the air, nodes a strided view
    states = np.empty((m_total, 1 + 5))
    t = np.arange(m_total)[:, None] * 5.0
    states[:, 1:] = 3.0 * np.sin(t / np.array([300.0, 70.0, 900.0, 40.0, 11.0])) - 0.5
    states[100:110, 1:] = 0.0                        # exact zeros (signed-zero arithmetic)
    states[:, 0] = 20.0
    nodes = states[:, 1:]
    out = {}
    for compiled in (False, True):
        st = p.initial_state(nodes[0])
        readings, k = [], 1
        for m in (1, 119, 120, 0, 300, 159):
            gen = np.random.default_rng(k)
            r, st = p.read(st, nodes[k:k + m], 5.0, gen, compiled=compiled)
            readings.append(r)
            k += m
        out[compiled] = (np.concatenate(readings), st)
    assert out[True][0].tobytes() == out[False][0].tobytes()
    assert out[True][1].tobytes() == out[False][1].tobytes()


def test_compiled_readings_with_a_contiguous_trace():
    p = probes([0.0625] * 8)
    T = np.random.default_rng(3).normal(25.0, 4.0, (240, 5))
    st = p.initial_state(T[0] + 1.0)
    a = p.read(st, T, 2.5, np.random.default_rng(1), compiled=False)
    b = p.read(st, T, 2.5, np.random.default_rng(1), compiled=True)
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()


def test_the_probe_kernel_has_no_fused_multiply_add():
    from numba import njit

    import rlgsim.sim.thermal._probe_kernel as kernel
    p = probes([0.0625] * 8)
    T = np.ones((10, 5))
    p.read(p.initial_state(T[0]), T, 5.0, np.random.default_rng(1), compiled=True)
    fresh = njit(nogil=True)(kernel.read_block.py_func)          # uncached: inspectable
    sig = kernel.read_block.signatures[0]
    fresh.compile(sig)
    asm = fresh.inspect_asm(sig).lower()
    assert not re.search(r"f(n)?m(add|sub)|fml[as]", asm)     # x86 vf[n]m…, aarch64 fml[as]
