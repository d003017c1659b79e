"""Compiled float32 standard normals (numba, ``nogil``): ``Generator.standard_normal(n,
dtype=np.float32, out=row)`` for each of a triad's generators in one call — numpy's numbers bit
for bit, in ~60 % of numpy's time.

Why hand-written: the white-noise normals are the largest single cost of a simulation (six
float32 normals per epoch: ~2 s of CPU in paper000's 43 million epochs, about half the run).
NumPy draws each through ``random_standard_normal_f``
(numpy/random/src/distributions/distributions.c: Marsaglia & Tsang's ziggurat with 256 float
strips, "The Ziggurat Method for Generating Random Variables", J. Stat. Softw. 5(8), 2000), a
function the fill loop calls through a pointer for every value and that calls the bit
generator through another. numba compiles its own ``Generator.standard_normal`` with both
inlined, but its float32 version evaluates the wedge test's exp(−x²/2) in float32 where NumPy's
C evaluates it in double, so a draw that lands in a wedge may be accepted by one and rejected
by the other and the two streams part for good (seen once in ~1.4 million draws). That one
function is written out here with NumPy's types, on numba's access to the bit generator
(``numba.np.random.generator_core.next_uint32``: PCG64's own ``next_uint32`` through its ctypes
interface, so the generator's state advances exactly as numpy's would) and numba's copies of
NumPy's ziggurat tables (``numba.np.random._constants``).

Per draw, as in NumPy's C (float where it has ``float``, double where it promotes)::

    r = next_uint32();  i = r & 0xff;  s = (r >> 8) & 1;  a = (r >> 9) & 0x7fffff
    x = float(a) · wi[i];  x = −x if s                                           (float)
    a < ki[i]                                   → x                               (99.3 %)
    i = 0 (the tail):  repeat  X = −(1/r)·log1pf(−u₁), Y = −log1pf(−u₂) (float, u = next_float)
                       until Y + Y > X·X        → ±(r + X)  (sign: bit 8 of a)
    i > 0 (a wedge):   (fi[i−1] − fi[i])·u + fi[i]  (float)  <  exp(−0.5·x·x)  (double)  → x
    otherwise draw again

with ``next_float`` = (next_uint32() >> 8) · 2⁻²⁴. No ``fastmath``: LLVM neither contracts a
product and a sum into a fused multiply-add nor reassociates (numpy's x86-64 wheels are built
without FMA, which is why ``available()`` checks the result on the running machine).

:func:`available` runs a self-check once per process — 2¹⁸ draws from each of four generators
both ways, which reach the wedges ~1 800 times and the tail a few times — and the caller keeps
numpy's draw unless it passes. tests/test_normal_kernel.py compares the two over ~50 million
draws of the simulator's own streams and counts the branches they took.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from numba import float32, float64, njit
from numba.np.random._constants import (fi_float, ki_float, wi_float, ziggurat_nor_inv_r_f,
                                        ziggurat_nor_r_f)
from numba.np.random.generator_core import next_uint32

#: 2⁻²⁴ as float32: ``next_float`` = (32 random bits >> 8)·2⁻²⁴, in [0, 1)
_INV_2_24 = np.float32(1.0 / 16777216.0)


@njit(nogil=True, cache=True)
def _next_float(bitgen):                                      # pragma: no cover (compiled)
    return float32(next_uint32(bitgen) >> 8) * _INV_2_24


@njit(nogil=True, cache=True)
def _standard_normal_f(bitgen):                               # pragma: no cover (compiled)
    """One float32 standard normal: NumPy's ``random_standard_normal_f`` (module docstring)."""
    while True:
        r = next_uint32(bitgen)
        idx = r & 0xff
        rabs = (r >> 9) & 0x7fffff
        x = float32(float32(rabs) * wi_float[idx])
        if (r >> 8) & 0x1:
            x = -x
        if rabs < ki_float[idx]:
            return x
        if idx == 0:
            while True:
                xx = float32(-ziggurat_nor_inv_r_f * float32(np.log1p(-_next_float(bitgen))))
                yy = float32(-float32(np.log1p(-_next_float(bitgen))))
                if float32(yy + yy) > float32(xx * xx):
                    if (rabs >> 8) & 0x1:
                        return -float32(ziggurat_nor_r_f + xx)
                    return float32(ziggurat_nor_r_f + xx)
        else:
            left = float32(float32(float32(fi_float[idx - 1] - fi_float[idx])
                                   * _next_float(bitgen)) + fi_float[idx])
            xd = float64(x)
            if float64(left) < math.exp(-0.5 * xd * xd):
                return x


@njit(nogil=True, cache=True)
def _fill_row(generator, out):                                # pragma: no cover (compiled)
    bitgen = generator.bit_generator
    for i in range(out.shape[0]):
        out[i] = _standard_normal_f(bitgen)


@njit(nogil=True, cache=True)
def _fill3(g0, g1, g2, out):                                  # pragma: no cover (compiled)
    _fill_row(g0, out[0])
    _fill_row(g1, out[1])
    _fill_row(g2, out[2])


def fill(generators: Sequence[np.random.Generator], out: np.ndarray) -> None:
    """``generators[c].standard_normal(n, dtype=np.float32, out=out[c])`` for every ``c``:
    ``out`` (C, n) C-contiguous float32; a triad in one compiled call (the GIL released),
    other counts channel by channel. Advances each generator as numpy's call would."""
    if len(generators) == 3 and out.shape[0] == 3:
        _fill3(generators[0], generators[1], generators[2], out)
        return
    for g, row in zip(generators, out):
        _fill_row(g, row)


_state: dict[str, bool] = {}


def _self_check() -> bool:
    """Four fixed generators, 2¹⁸ draws each, both ways: the same bits, and each generator left
    in the same state."""
    n = 1 << 18
    ours = [np.random.default_rng(seed) for seed in (1, 2, 3, 4)]
    theirs = [np.random.default_rng(seed) for seed in (1, 2, 3, 4)]
    a = np.empty((3, n), dtype=np.float32)
    b = np.empty((3, n), dtype=np.float32)
    fill(ours[:3], a)
    for g, row in zip(theirs[:3], b):
        g.standard_normal(n, dtype=np.float32, out=row)
    one_a = np.empty((1, n), dtype=np.float32)
    fill(ours[3:], one_a)
    one_b = theirs[3].standard_normal(n, dtype=np.float32)
    same_state = all(x.bit_generator.state == y.bit_generator.state
                     for x, y in zip(ours, theirs))
    return (a.tobytes() == b.tobytes() and one_a[0].tobytes() == one_b.tobytes()
            and same_state)


def available() -> bool:
    """Whether :func:`fill` gives numpy's draws in this process (checked once)."""
    if "ok" not in _state:
        try:
            _state["ok"] = _self_check()
        except Exception:                       # pragma: no cover - optional speed-up only
            _state["ok"] = False
    return _state["ok"]
