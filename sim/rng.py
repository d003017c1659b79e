"""The random-number tree.

Every random draw in ``sim`` comes from a :class:`numpy.random.Generator` built from a
:class:`numpy.random.SeedSequence` keyed by (scenario seed, unit index, purpose, channel, block
index) — docs/design.md, "Determinism". A block is a fixed stretch of simulated time, independent of
how the run is chunked for writing, so the same scenario and seed give identical bytes whatever
the chunk size, worker count or executor.
"""

from __future__ import annotations

import zlib

import numpy as np


def _word(name: str | int) -> int:
    """A stable 32-bit key for a purpose/channel name (crc32; Python's hash() is salted)."""
    if isinstance(name, (int, np.integer)):
        return int(name) & 0xFFFFFFFF
    return zlib.crc32(str(name).encode("utf-8"))


def seed_sequence(seed: int, unit: int = 0, purpose: str = "", channel: str | int = "",
                  block: int = 0) -> np.random.SeedSequence:
    """The :class:`~numpy.random.SeedSequence` for one (seed, unit, purpose, channel, block)."""
    return np.random.SeedSequence(
        entropy=int(seed), spawn_key=(int(unit), _word(purpose), _word(channel), int(block)))


def generator(seed: int, unit: int = 0, purpose: str = "", channel: str | int = "",
              block: int = 0) -> np.random.Generator:
    """A PCG64 generator for one leaf of the tree."""
    return np.random.Generator(np.random.PCG64(seed_sequence(seed, unit, purpose, channel, block)))
