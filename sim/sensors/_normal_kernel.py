"""Compiled standard normals (numba, ``nogil``): ``Generator.standard_normal(n,
dtype=np.float32, out=row)`` for each of a triad's PCG64 generators in one call — numpy's
numbers bit for bit, in ~55 % of numpy's time — and float64 ones (:func:`fill_streams`).

Why hand-written: the white-noise normals are the largest single cost of a simulation (six
float32 normals per epoch: ~2 s of CPU in paper000's 43 million epochs, about half the run).
NumPy draws each through ``random_standard_normal_f``
(numpy/random/src/distributions/distributions.c: Marsaglia & Tsang's ziggurat with 256 float
strips, "The Ziggurat Method for Generating Random Variables", J. Stat. Softw. 5(8), 2000), a
function its fill loop calls through a pointer for every value and that calls the bit generator
through another. numba has its own ``Generator.standard_normal``, but (1) its float32 version
evaluates the wedge test's exp(−x²/2) in float32 where NumPy's C evaluates it in double, so a
draw that lands in a wedge may be accepted by one and rejected by the other and the two streams
part for good (seen once in ~1.4 million draws), and (2) typing its Generator objects costs
~0.25 s once per process. So both halves are written out here, with NumPy's types:

* the bit generator, PCG64 (M. E. O'Neill, "PCG: A Family of Simple Fast Space-Efficient
  Statistically Good Algorithms for Random Number Generation", HMC-CS-2014-0905; numpy's
  pcg64.h): the 128-bit LCG step s ← s·M + inc (mod 2¹²⁸, in 64-bit halves) and the XSL-RR
  output rotr64(hi ⊕ lo, hi >> 58); ``next_uint32`` hands out the low half of a 64-bit output
  and keeps the high half for the next call (``has_uint32``/``uinteger``), as numpy's does. The
  state is read from, and optionally written back to, the generator's ``bit_generator.state``;
* the normal, per draw as in NumPy's C (float where it has ``float``, double where it
  promotes)::

    r = next_uint32();  i = r & 0xff;  s = (r >> 8) & 1;  a = (r >> 9) & 0x7fffff
    x = float(a) · wi[i];  x = −x if s                                           (float)
    a < ki[i]                                   → x                               (99.3 %)
    i = 0 (the tail):  repeat  X = −(1/r)·log1pf(−u₁), Y = −log1pf(−u₂) (float, u = next_float)
                       until Y + Y > X·X        → ±(r + X)  (sign: bit 8 of a)
    i > 0 (a wedge):   (fi[i−1] − fi[i])·u + fi[i]  (float)  <  exp(−0.5·x·x)  (double)  → x
    otherwise draw again

  with ``next_float`` = (next_uint32() >> 8) · 2⁻²⁴ and NumPy's ziggurat tables (numba's copies,
  ``numba.np.random._constants``).

No ``fastmath``: LLVM neither contracts a product and a sum into a fused multiply-add nor
reassociates, and numpy's x86-64 wheels are built without FMA. Elsewhere numpy's C may be
compiled with contraction (GCC on aarch64, clang by default): a fused
(fi[i−1] − fi[i])·u + fi[i] would flip a wedge comparison about once in 10⁹ draws, too rarely for
any check to see, so :func:`available` is False off x86-64 (numpy's draw is used). On x86-64 it
runs a self-check once per process — 2¹⁸ draws from each of four generators both ways (~7 300
wedge tests, ~270 tail draws) and the generators' states after — and the caller keeps numpy's
draw unless it passes (a guard against other tables, another libm, another numba).
tests/test_normal_kernel.py compares the two over ~29 million draws of the simulator's own
streams.

:func:`fill_streams` draws float64 normals the same way — NumPy's ``random_standard_normal``: 64
bits a try (index = the low 8 bits, then a sign bit and a 52-bit ``rabs``), the double tables,
``next_double`` = (64 bits >> 11)·2⁻⁵³ — from PCG64s it seeds itself from their
``generate_state(4, uint64)`` words (numpy's ``pcg64_set_seed``), for the IMU's slow-noise and
UHFO drives (18 streams a block, J·m per flicker channel and m per other: 8 640 draws for
paper000_ramp's 120 steps): one call a block, no generator object, instead of a generator,
numpy's call and a copy per stream — each of which released and took back the GIL while the
simulator's other threads wanted it (36 hand-off chances a block -> 2). paper000_ramp's drives
in one thread, medians of 6: 0.10 s a run with numpy -> 0.065 s (a first version that read the
states of numpy generators took 0.14 s: the per-generator Python outweighed the draws).
The self-check covers it too.
"""

from __future__ import annotations

import math
import platform
import threading
from typing import Sequence

import numpy as np
from numba import float32, float64, njit
from numba.np.random._constants import (fi_double, fi_float, ki_double, ki_float, wi_double,
                                        wi_float, ziggurat_nor_inv_r, ziggurat_nor_inv_r_f,
                                        ziggurat_nor_r, ziggurat_nor_r_f)

#: 2⁻²⁴ as float32: ``next_float`` = (32 random bits >> 8)·2⁻²⁴, in [0, 1)
_INV_2_24 = np.float32(1.0 / 16777216.0)
#: 2⁻⁵³: ``next_double`` = (64 random bits >> 11)·2⁻⁵³, in [0, 1)
_INV_2_53 = 1.0 / 9007199254740992.0
_MASK52 = np.uint64(0x000FFFFFFFFFFFFF)
_U8, _U11 = np.uint64(8), np.uint64(11)
#: PCG64's 128-bit multiplier (numpy's pcg64.h PCG_DEFAULT_MULTIPLIER_HIGH/LOW), in halves
_M_HI = np.uint64(0x2360ED051FC65DA4)
_M_LO = np.uint64(0x4385DF649FCCF645)
_MASK32 = np.uint64(0xFFFFFFFF)
_U0, _U1, _U32, _U58, _U63, _U64 = (np.uint64(k) for k in (0, 1, 32, 58, 63, 64))
_MASK64 = (1 << 64) - 1

#: a generator's state as the kernel holds it: one uint64 row of six words per generator
_STATE_HI, _STATE_LO, _INC_HI, _INC_LO, _HAS_UINT32, _UINTEGER = range(6)


@njit(inline="always")
def _mulhi(a, b):                                             # pragma: no cover (compiled)
    """The high 64 bits of the 128-bit product of two uint64 (four 32-bit products)."""
    a0, a1 = a & _MASK32, a >> _U32
    b0, b1 = b & _MASK32, b >> _U32
    p00, p01, p10, p11 = a0 * b0, a0 * b1, a1 * b0, a1 * b1
    mid = (p00 >> _U32) + (p01 & _MASK32) + (p10 & _MASK32)
    return p11 + (p01 >> _U32) + (p10 >> _U32) + (mid >> _U32)


@njit(inline="always")
def _next64(st):                                              # pragma: no cover (compiled)
    """PCG64: s ← s·M + inc (mod 2¹²⁸), then rotr64(hi ⊕ lo, hi >> 58) of the new state."""
    hi, lo = st[_STATE_HI], st[_STATE_LO]
    lo_m = lo * _M_LO
    hi_m = _mulhi(lo, _M_LO) + hi * _M_LO + lo * _M_HI
    lo_n = lo_m + st[_INC_LO]
    hi_n = hi_m + st[_INC_HI] + (_U1 if lo_n < lo_m else _U0)
    st[_STATE_HI] = hi_n
    st[_STATE_LO] = lo_n
    rot = hi_n >> _U58
    x = hi_n ^ lo_n
    return (x >> rot) | (x << ((_U64 - rot) & _U63))


@njit(inline="always")
def _next_uint32(st):                                         # pragma: no cover (compiled)
    """numpy's pcg64_next32: the kept high half if there is one, else the low half of a new
    64-bit output (its high half kept)."""
    if st[_HAS_UINT32] != _U0:
        st[_HAS_UINT32] = _U0
        return np.uint32(st[_UINTEGER])
    nxt = _next64(st)
    st[_HAS_UINT32] = _U1
    st[_UINTEGER] = nxt >> _U32
    return np.uint32(nxt & _MASK32)


@njit(inline="always")
def _next_float(st):                                          # pragma: no cover (compiled)
    return float32(_next_uint32(st) >> np.uint32(8)) * _INV_2_24


@njit(nogil=True, cache=True)
def _standard_normal_f(st):                                   # pragma: no cover (compiled)
    """One float32 standard normal: NumPy's ``random_standard_normal_f`` (module docstring)."""
    while True:
        r = _next_uint32(st)
        idx = r & 0xff
        rabs = (r >> 9) & 0x7fffff
        x = float32(float32(rabs) * wi_float[idx])
        if (r >> 8) & 0x1:
            x = -x
        if rabs < ki_float[idx]:
            return x
        if idx == 0:
            while True:
                xx = float32(-ziggurat_nor_inv_r_f * float32(np.log1p(-_next_float(st))))
                yy = float32(-float32(np.log1p(-_next_float(st))))
                if float32(yy + yy) > float32(xx * xx):
                    if (rabs >> 8) & 0x1:
                        return -float32(ziggurat_nor_r_f + xx)
                    return float32(ziggurat_nor_r_f + xx)
        else:
            left = float32(float32(float32(fi_float[idx - 1] - fi_float[idx])
                                   * _next_float(st)) + fi_float[idx])
            xd = float64(x)
            if float64(left) < math.exp(-0.5 * xd * xd):
                return x


@njit(nogil=True, cache=True)
def _fill(states, out):                                       # pragma: no cover (compiled)
    """Row ``c`` of ``out`` (C, n) float32 from the generator state ``states[c]`` (advanced)."""
    for c in range(out.shape[0]):
        st = states[c]
        for i in range(out.shape[1]):
            out[c, i] = _standard_normal_f(st)


@njit(inline="always")
def _next_double(st):                                         # pragma: no cover (compiled)
    return float64(_next64(st) >> _U11) * _INV_2_53


@njit(inline="always")
def _standard_normal_d(st):                                   # pragma: no cover (compiled)
    """One float64 standard normal: NumPy's ``random_standard_normal`` (64 bits a try; the
    module docstring's steps in double, with its 52-bit ``rabs`` and double tables)."""
    while True:
        r = _next64(st)
        idx = r & np.uint64(0xff)
        r = r >> _U8
        rabs = (r >> _U1) & _MASK52
        x = float64(rabs) * wi_double[idx]
        if r & _U1:
            x = -x
        if rabs < ki_double[idx]:
            return x
        if idx == 0:
            while True:
                xx = -ziggurat_nor_inv_r * np.log1p(-_next_double(st))
                yy = -np.log1p(-_next_double(st))
                if yy + yy > xx * xx:
                    if (rabs >> _U8) & _U1:
                        return -(ziggurat_nor_r + xx)
                    return ziggurat_nor_r + xx
        elif ((fi_double[idx - 1] - fi_double[idx]) * _next_double(st)
              + fi_double[idx]) < math.exp(-0.5 * x * x):
            return x


@njit(inline="always")
def _seed(st, w):                                             # pragma: no cover (compiled)
    """numpy's ``PCG64`` seeded with the words ``w`` (4,) of ``generate_state(4, uint64)``:
    pcg64_set_seed — inc = (w₂w₃ << 1) | 1, state 0, a step, state += w₀w₁, a step — and no
    32-bit half kept."""
    st[_STATE_HI] = _U0
    st[_STATE_LO] = _U0
    st[_INC_HI] = (w[2] << _U1) | (w[3] >> _U63)
    st[_INC_LO] = (w[3] << _U1) | _U1
    _next64(st)
    lo = st[_STATE_LO] + w[1]
    st[_STATE_HI] = st[_STATE_HI] + w[0] + (_U1 if lo < w[1] else _U0)
    st[_STATE_LO] = lo
    _next64(st)
    st[_HAS_UINT32] = _U0
    st[_UINTEGER] = _U0


@njit(nogil=True, cache=True)
def _fill_seeded(words, base, views):                         # pragma: no cover (compiled)
    """For each stream ``k``: a PCG64 seeded with ``words[k]`` draws n0·n1 float64 normals
    into ``base[off + i·s0 + j·s1]`` in C order, ``views[k]`` = (off, n0, s0, n1, s1)."""
    st = np.empty(6, dtype=np.uint64)
    for k in range(views.shape[0]):
        _seed(st, words[k])
        off, n0, s0, n1, s1 = views[k, 0], views[k, 1], views[k, 2], views[k, 3], views[k, 4]
        for i in range(n0):
            at = off + i * s0
            for j in range(n1):
                base[at + j * s1] = _standard_normal_d(st)


def _states(generators: Sequence[np.random.Generator]) -> np.ndarray:
    """The PCG64 states (C, 6) uint64 of ``generators`` (from ``bit_generator.state``)."""
    out = np.empty((len(generators), 6), dtype=np.uint64)
    for c, g in enumerate(generators):
        st = g.bit_generator.state
        s, inc = st["state"]["state"], st["state"]["inc"]
        out[c] = (s >> 64, s & _MASK64, inc >> 64, inc & _MASK64, st["has_uint32"],
                  st["uinteger"])
    return out


def _write_back(generators: Sequence[np.random.Generator], states: np.ndarray) -> None:
    for g, (s_hi, s_lo, i_hi, i_lo, has, uint) in zip(generators, states.tolist()):
        g.bit_generator.state = {"bit_generator": "PCG64",
                                 "state": {"state": (s_hi << 64) | s_lo,
                                           "inc": (i_hi << 64) | i_lo},
                                 "has_uint32": has, "uinteger": uint}


_scratch_of = threading.local()


def _scratch(rows: int, n: int) -> np.ndarray:
    """This thread's scratch (rows, n) float32, the same memory from call to call.

    The kernel draws into it and numpy copies it into the caller's array in one pass. Drawing
    straight into a fresh array is ~2.6× slower when another core reads those arrays (the
    simulator's main thread reads each block's normals): the freed memory comes back with its
    cache lines held by that core, and every store of the draw loop waits for its line to be
    taken back, one by one, while a bulk copy asks for many lines at once (paper000: the
    worker's normals took 1.8 ms per triad instead of 0.8 ms in such runs; both ways timed
    with a throwaway script, not one in benchmarks/)."""
    buf = getattr(_scratch_of, "buf", None)
    if buf is None or buf.size < rows * n:
        buf = _scratch_of.buf = np.empty(rows * n, dtype=np.float32)
    return buf[:rows * n].reshape(rows, n)


def fill(generators: Sequence[np.random.Generator], out: np.ndarray, *,
         advance: bool = True) -> None:
    """``generators[c].standard_normal(n, dtype=np.float32, out=out[c])`` for every ``c``:
    ``out`` (C, n) C-contiguous float32, the PCG64 generators' rows in one compiled call (the
    GIL released), any other bit generator's row by numpy. ``advance``: leave each generator in
    the state numpy's call would (False: the caller discards them, as the simulator does its
    per-block generators — saves writing the states back)."""
    if (out.ndim != 2 or out.dtype != np.float32 or not out.flags.c_contiguous
            or out.shape[0] != len(generators)):
        raise ValueError(f"out must be a C-contiguous float32 array of {len(generators)} rows, "
                         f"got {out.dtype} {out.shape}")
    if len({id(g) for g in generators}) != len(generators):
        raise ValueError("each row needs its own generator (numpy would draw the rows of a "
                         "repeated generator one after another)")
    pcg = [type(g.bit_generator) is np.random.PCG64 for g in generators]
    rows = [c for c, ok in enumerate(pcg) if ok]
    for c, ok in enumerate(pcg):
        if not ok:
            generators[c].standard_normal(out.shape[1], dtype=np.float32, out=out[c])
    if not rows:
        return
    ours = [generators[c] for c in rows]
    states = _states(ours)
    drawn = _scratch(len(rows), out.shape[1])
    _fill(states, drawn)
    if len(rows) == len(pcg):
        np.copyto(out, drawn)
    else:
        out[rows] = drawn
    if advance:
        _write_back(ours, states)


def fill_streams(words: np.ndarray, base: np.ndarray, views: np.ndarray) -> None:
    """``Generator(PCG64(seq)).standard_normal((n0, n1))`` into a strided view of ``base`` for
    each stream, in one compiled call (the GIL released once), for sequences ``seq`` whose
    ``generate_state(4, np.uint64)`` are the rows of ``words`` (K, 4) uint64
    (:func:`rlgsim.sim.rng.seed_words`): no generator object is made. ``base`` a writeable
    C-contiguous float64 array; ``views`` (K, 5) int64 rows (offset, n0, s0, n1, s1) in
    elements of ``base`` — stream k's draw (i, j) goes to ``base.flat[offset + i·s0 + j·s1]``
    (the views apart). Raises ValueError for a view outside ``base``."""
    if base.dtype != np.float64 or not base.flags.c_contiguous or not base.flags.writeable:
        raise ValueError("base must be a writeable C-contiguous float64 array")
    if (words.dtype != np.uint64 or views.dtype != np.int64 or words.ndim != 2
            or words.shape[1] != 4 or views.shape != (words.shape[0], 5)
            or not (words.flags.c_contiguous and views.flags.c_contiguous)):
        raise ValueError("words must be (K, 4) uint64 and views (K, 5) int64, C-contiguous")
    reach = (views[:, [1, 3]] - 1) * views[:, [2, 4]]           # (n0 − 1)·s0, (n1 − 1)·s1
    lo = views[:, 0] + np.minimum(reach, 0).sum(axis=1)
    hi = views[:, 0] + np.maximum(reach, 0).sum(axis=1)
    empty = (views[:, 1] <= 0) | (views[:, 3] <= 0)
    if np.any(~empty & ((lo < 0) | (hi >= base.size))):
        raise ValueError("views must lie inside base")
    _fill_seeded(words, base.reshape(-1), views)


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
            and same_state and _self_check_views())


def _self_check_views() -> bool:
    """:func:`fill_streams` against numpy: 2¹⁶ and 2¹⁷ float64 draws of two fixed seed
    sequences into a strided 1-D and a transposed 2-D view of one base (~1 400 wedge tests,
    ~50 tail draws)."""
    n = 1 << 16
    base, want = np.zeros((n, 3)), np.zeros((n, 3))
    seqs = [np.random.SeedSequence(5), np.random.SeedSequence(6)]
    fill_streams(np.stack([q.generate_state(4, np.uint64) for q in seqs]), base,
                 np.array([(0, 1, 0, n, 3), (1, 2, 1, n, 3)], dtype=np.int64))
    want[:, 0] = np.random.Generator(np.random.PCG64(seqs[0])).standard_normal(n)
    want[:, 1:].T[...] = np.random.Generator(np.random.PCG64(seqs[1])).standard_normal((2, n))
    return base.tobytes() == want.tobytes()


def available() -> bool:
    """Whether :func:`fill` and :func:`fill_streams` give numpy's draws in this process: on
    x86-64 only (module docstring), and after the self-check of both (once per process; a
    failure of either turns both off)."""
    if "ok" not in _state:
        if platform.machine().lower() not in ("x86_64", "amd64"):
            _state["ok"] = False
            return False
        try:
            _state["ok"] = _self_check()
        except Exception:                       # pragma: no cover - optional speed-up only
            _state["ok"] = False
    return _state["ok"]
