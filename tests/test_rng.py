"""The seed tree's generators (sim/rng.py) against numpy's own construction,
``Generator(PCG64(SeedSequence(entropy=seed, spawn_key=(unit, purpose, channel, block))))``:
the same PCG64 state for seeds of one to four 32-bit words and more, units, names and
integer channels, blocks on both sides of a 64-block chunk and at the 32-bit limit, and the
keys outside the precomputed range (numpy's path)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from rlgsim.sim.rng import generator, seed_sequence


def numpy_generator(seed, unit, purpose, channel, block) -> np.random.Generator:
    return np.random.Generator(np.random.PCG64(
        seed_sequence(seed, unit, purpose, channel, block)))


SEEDS = [0, 1, 7, 12345, 2**31, 2**32 - 1, 2**32, 2**63 - 1, 2**64 + 3, 2**127 + 11, 2**140]
BLOCKS = [0, 1, 63, 64, 65, 127, 128, 723, 724, 10**6, 2**32 - 1]


@pytest.mark.parametrize("seed", SEEDS)
def test_generators_have_numpys_state(seed):
    rng = np.random.default_rng(seed % 2**32)
    for block in BLOCKS:
        unit = int(rng.choice([0, 1, 3, 2**32 - 1]))
        purpose = str(rng.choice(["gyro.white", "accel.flicker", "uhfo.readout", ""]))
        channel = rng.choice(["x", "y", "z", "", 0, 5])
        channel = int(channel) if str(channel).isdigit() else str(channel)
        got = generator(seed, unit, purpose, channel, block)
        ref = numpy_generator(seed, unit, purpose, channel, block)
        assert got.bit_generator.state == ref.bit_generator.state
        np.testing.assert_array_equal(got.standard_normal(5, dtype=np.float32),
                                      ref.standard_normal(5, dtype=np.float32))


def test_keys_outside_the_precomputed_range_take_numpys_path():
    for key in [(1, 0, "a", "x", 2**32), (1, 2**32, "a", "x", 0), (1, 0, "a", "x", 2**40)]:
        assert generator(*key).bit_generator.state == numpy_generator(*key).bit_generator.state
    with pytest.raises(ValueError):
        generator(-1, 0, "a", "x", 0)           # as SeedSequence refuses negative entropy


def test_numpy_integer_keys_and_pickling():
    got = generator(np.int64(9), np.int32(2), "probes", np.int64(4), np.int64(70))
    assert got.bit_generator.state == numpy_generator(9, 2, "probes", 4, 70).bit_generator.state
    again = pickle.loads(pickle.dumps(got))
    assert again.bit_generator.state == got.bit_generator.state


def test_a_leaf_generator_spawns_and_reports_its_key_as_numpy_does():
    """Everything beyond PCG64's own seeding comes from numpy's SeedSequence of the same key:
    children (twice: new ones the second time), entropy, spawn key, other state sizes."""
    from rlgsim.sim.rng import generator, seed_sequence
    g = generator(7, 1, "gyro.white", "x", 130)
    r = np.random.Generator(np.random.PCG64(seed_sequence(7, 1, "gyro.white", "x", 130)))
    for n in (2, 1):
        for cg, cr in zip(g.spawn(n), r.spawn(n)):
            assert cg.standard_normal(4).tobytes() == cr.standard_normal(4).tobytes()
    sg, sr = g.bit_generator.seed_seq, r.bit_generator.seed_seq
    assert (sg.entropy, sg.spawn_key, sg.pool_size) == (sr.entropy, sr.spawn_key, sr.pool_size)
    assert sg.generate_state(8).tobytes() == sr.generate_state(8).tobytes()
    assert g.standard_normal(6).tobytes() == r.standard_normal(6).tobytes()


def test_seed_words_are_the_words_a_generator_seeds_from():
    """What the compiled float64 draw seeds its own PCG64 from: generate_state(4, uint64) of
    the leaf's SeedSequence, in and out of the fast path's range (a negative seed, a block
    beyond 32 bits)."""
    from rlgsim.sim.rng import block_seed_words, seed_sequence, seed_words, word
    for key in [(7, 2, "gyro.rrw", "x", 0), (7, 2, "uhfo.wander", "z", 64 * 5 + 3),
                (2**40 + 1, 0, "accel.flicker", 1, 2**32 + 5)]:
        want = seed_sequence(*key).generate_state(4, np.uint64)
        assert seed_words(*key).tobytes() == want.tobytes()
        assert seed_words(key[0], key[1], word(key[2]), word(key[3]), key[4]).tobytes() \
            == want.tobytes()
    rows = block_seed_words(3, 1, [("a", "x"), (word("b"), word("y"))], 9)
    assert rows.tobytes() == np.stack([seed_words(3, 1, "a", "x", 9),
                                       seed_words(3, 1, "b", "y", 9)]).tobytes()
