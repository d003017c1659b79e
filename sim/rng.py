"""The random-number tree.

Every random draw in ``sim`` comes from a :class:`numpy.random.Generator` built from a
:class:`numpy.random.SeedSequence` keyed by (scenario seed, unit index, purpose, channel, block
index) — docs/design.md, "Determinism". A block is a fixed stretch of simulated time, independent of
how the run is chunked for writing, so the same scenario and seed give identical bytes whatever
the chunk size, worker count or executor.

Building a generator: a run asks for ~25 per 600 s block (white noise, slow noise, UHFO per
channel), and numpy's ``PCG64(SeedSequence(...))`` costs ~10 µs of interpreter time each, most
of it SeedSequence hashing its entropy words one by one. :func:`generator` gives the same
generator (the same PCG64 state, bit for bit) from the same hash computed for 64 consecutive
blocks of one (seed, unit, purpose, channel) at once with NumPy's uint32 arithmetic
(:func:`_block_words`): SeedSequence's mixing is O'Neill's ``seed_seq_fe`` (M. E. O'Neill,
"Developing a seed_seq alternative", pcg-random.org blog, 2015; numpy/random/bit_generator.pyx
``hashmix``, ``mix``, ``mix_entropy``, ``generate_state``), and the words before the block
index — the seed padded to the pool size, the unit, purpose and channel — mix into the pool the
same way for every block. PCG64 seeds itself from ``generate_state(4, uint64)`` of the sequence
it is given, which numpy allows to be any :class:`numpy.random.bit_generator.ISeedSequence`;
tests/test_rng.py compares the states with numpy's own construction.
"""

from __future__ import annotations

import zlib
from functools import lru_cache

import numpy as np
from numpy.random.bit_generator import ISpawnableSeedSequence

# SeedSequence's constants (numpy/random/bit_generator.pyx)
_POOL = 4
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_MASK = 0xFFFFFFFF
#: Simulated length of one block [s]: the unit of time of the tree's leaves. A run advances
#: block by block (:mod:`rlgsim.sim.run.simulate`); fixed, so that no byte depends on the chunk
#: size. The scenario loader checks that thermal steps and samples tile it.
BLOCK_S = 600.0

#: consecutive blocks of one stream whose PCG64 seeds are hashed together
_CHUNK = 64


def word(name: str | int) -> int:
    """The 32-bit key of a purpose or channel name in the tree (crc32; Python's hash() is
    salted); a number is its own key (its low 32 bits)."""
    if isinstance(name, (int, np.integer)):
        return int(name) & 0xFFFFFFFF
    return zlib.crc32(str(name).encode("utf-8"))


def seed_sequence(seed: int, unit: int = 0, purpose: str = "", channel: str | int = "",
                  block: int = 0) -> np.random.SeedSequence:
    """The :class:`~numpy.random.SeedSequence` for one (seed, unit, purpose, channel, block)."""
    return np.random.SeedSequence(
        entropy=int(seed), spawn_key=(int(unit), word(purpose), word(channel), int(block)))


def generator(seed: int, unit: int = 0, purpose: str = "", channel: str | int = "",
              block: int = 0) -> np.random.Generator:
    """A PCG64 generator for one leaf of the tree: ``Generator(PCG64(seed_sequence(...)))``,
    seeded from :func:`seed_words` (the same state, bit for bit)."""
    key = (int(seed), int(unit), word(purpose), word(channel), int(block))
    return np.random.Generator(np.random.PCG64(_Seeded(seed_words(*key), key)))


def seed_words(seed: int, unit: int = 0, purpose: str | int = "", channel: str | int = "",
               block: int = 0) -> np.ndarray:
    """``seed_sequence(seed, unit, purpose, channel, block).generate_state(4, np.uint64)``: the
    words :func:`generator`'s PCG64 seeds itself from, (4,) uint64 (a compiled draw that seeds
    its own PCG64 needs no generator object: rlgsim.sim.sensors._normal_kernel.fill_streams).
    ``purpose``/``channel`` may be given as their 32-bit words already (:func:`word`)."""
    seed, unit, block = int(seed), int(unit), int(block)
    if seed < 0 or not 0 <= unit <= _MASK or not 0 <= block <= _MASK:
        return seed_sequence(seed, unit, purpose, channel, block).generate_state(4, np.uint64)
    return _block_words(seed, unit, word(purpose), word(channel), block // _CHUNK)[block % _CHUNK]


def block_seed_words(seed: int, unit: int, keys: "list[tuple[int, int]]", block: int
                     ) -> np.ndarray:
    """:func:`seed_words` (K, 4) uint64 of block ``block``'s streams ``keys`` — (purpose,
    channel) pairs, names or their words."""
    out = np.empty((len(keys), 4), dtype=np.uint64)
    for k, (purpose, channel) in enumerate(keys):
        out[k] = seed_words(seed, unit, purpose, channel, block)
    return out


class _Seeded(ISpawnableSeedSequence):
    """A leaf's SeedSequence as PCG64 uses it: ``generate_state(4, np.uint64)`` precomputed
    (:func:`_block_words`); anything else — other state sizes, ``spawn``, ``entropy``,
    ``spawn_key`` — from numpy's own :class:`~numpy.random.SeedSequence` of the same key, built
    on first use and kept (so successive ``spawn`` calls give new children, as numpy's do)."""

    __slots__ = ("_state", "_key", "_seq")

    def __init__(self, state: np.ndarray, key: tuple[int, int, int, int, int]) -> None:
        self._state = state
        self._key = key                      # (seed, unit, purpose word, channel word, block)
        self._seq: np.random.SeedSequence | None = None

    @property
    def full(self) -> np.random.SeedSequence:
        """numpy's SeedSequence of this leaf (the same state words)."""
        if self._seq is None:
            self._seq = np.random.SeedSequence(entropy=self._key[0], spawn_key=self._key[1:])
        return self._seq

    def generate_state(self, n_words: int, dtype: type = np.uint32) -> np.ndarray:
        if n_words == 4 and np.dtype(dtype) == np.uint64:
            return self._state.copy()
        return self.full.generate_state(n_words, dtype)

    def spawn(self, n_children: int) -> list[np.random.SeedSequence]:
        return self.full.spawn(n_children)

    @property
    def entropy(self) -> int:
        return self.full.entropy

    @property
    def spawn_key(self) -> tuple[int, ...]:
        return self.full.spawn_key

    @property
    def pool_size(self) -> int:
        return self.full.pool_size

    @property
    def n_children_spawned(self) -> int:
        return self.full.n_children_spawned


def _int_words(n: int) -> list[int]:
    """SeedSequence's uint32 words of a non-negative int, least significant first."""
    words = []
    while True:
        words.append(n & _MASK)
        n >>= 32
        if not n:
            return words


@lru_cache(maxsize=64)
def _pool_before_block(seed: int, unit: int, purpose: int, channel: int
                       ) -> tuple[tuple[int, ...], int]:
    """SeedSequence's pool after every entropy word but the block index, and the hash
    constant at that point (mix_entropy: the first pool-size words hashed in, all mixed
    together, then each further word mixed into every pool word)."""
    run = _int_words(seed)
    entropy = run + [0] * max(0, _POOL - len(run)) + _int_words(unit) + [purpose, channel]
    hc = _INIT_A

    def hashmix(value: int) -> int:
        nonlocal hc
        value ^= hc
        hc = (hc * _MULT_A) & _MASK
        value = (value * hc) & _MASK
        return value ^ (value >> 16)

    pool = [hashmix(entropy[i]) for i in range(_POOL)]
    for src in range(_POOL):
        for dst in range(_POOL):
            if src != dst:
                pool[dst] = _mix(pool[dst], hashmix(pool[src]))
    for word in entropy[_POOL:]:
        for dst in range(_POOL):
            pool[dst] = _mix(pool[dst], hashmix(word))
    return tuple(pool), hc


def _mix(x, y):
    """SeedSequence's ``mix`` of two uint32 (Python ints or uint32 arrays)."""
    r = (_MIX_L * x - _MIX_R * y) & _MASK
    return r ^ (r >> 16)


def _hash_constants(start: int, count: int, mult: int) -> list[int]:
    out = [start]
    for _ in range(count):
        out.append((out[-1] * mult) & _MASK)
    return out


#: generate_state's hash constants (they do not depend on the pool): word i is
#: ((pool[i % 4] ^ c[i]) · c[i + 1]) folded
_STATE_CONSTANTS = _hash_constants(_INIT_B, 2 * _POOL, _MULT_B)


@lru_cache(maxsize=1024)
def _block_words(seed: int, unit: int, purpose: int, channel: int, chunk: int) -> np.ndarray:
    """``seed_sequence(seed, unit, purpose, channel, b).generate_state(4, np.uint64)`` for the
    blocks b of ``chunk`` (64 consecutive blocks), (64, 4) uint64."""
    pool0, hc = _pool_before_block(seed, unit, purpose, channel)
    block = np.arange(chunk * _CHUNK, (chunk + 1) * _CHUNK, dtype=np.uint64)
    hcs = _hash_constants(hc, _POOL, _MULT_A)
    pool = []
    for dst in range(_POOL):                   # the block word mixed into every pool word
        h = ((block ^ hcs[dst]) * hcs[dst + 1]) & _MASK
        pool.append(_mix(np.uint64(pool0[dst]), h ^ (h >> 16)))
    c = _STATE_CONSTANTS
    words = []
    for i in range(2 * _POOL):                 # generate_state: 8 uint32 words, cycling the pool
        w = ((pool[i % _POOL] ^ c[i]) * c[i + 1]) & _MASK
        words.append(w ^ (w >> 16))
    # pairs of little-endian uint32 words are the uint64 words
    out = np.stack([words[2 * k] | (words[2 * k + 1] << np.uint64(32)) for k in range(_POOL)],
                   axis=1)
    out.flags.writeable = False              # cached: a caller's write would reseed 64 blocks
    return out
