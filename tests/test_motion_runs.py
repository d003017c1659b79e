"""Motion._runs (the runs of sub-intervals lying in one turntable segment, found from the
segment starts) against its definition: the maximal runs of the per-sample segment index
clip(searchsorted(t0, a, "right") − 1, 0, m − 1), on the shipped calibration programme and on
times before, across and beyond its segments."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.sim.motion.kinematics import Motion
from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.schedule import build_timeline


@pytest.fixture(scope="module")
def motion() -> Motion:
    sc = load_scenario("paper000_short")
    tl = build_timeline(sc)
    return Motion([s for s in tl.segments if s.track == "turntable"], sc.site)


def runs_by_definition(motion: Motion, a: np.ndarray) -> list[tuple[int, int, int]]:
    seg = np.clip(np.searchsorted(motion._t0, a, side="right") - 1, 0, motion._m - 1)
    cut = np.flatnonzero(np.diff(seg)) + 1
    return [(int(lo), int(hi), int(seg[lo]))
            for lo, hi in zip(np.r_[0, cut], np.r_[cut, a.size])]


@pytest.mark.parametrize("seed", range(6))
def test_runs_are_the_runs_of_the_per_sample_segment_index(motion, seed):
    rng = np.random.default_rng(seed)
    t0 = motion._t0
    for _ in range(40):
        lo = rng.uniform(t0[0] - 5.0, t0[-1] + 5.0)
        span = rng.choice([0.01, 1.0, 60.0, 600.0, 5000.0])
        a = np.sort(rng.uniform(lo, lo + span, int(rng.integers(1, 3000))))
        if rng.random() < 0.3:                  # samples starting exactly on segment starts
            k = rng.integers(0, t0.size, 5)
            a = np.sort(np.concatenate([a, t0[k]]))
        assert motion._runs(a) == runs_by_definition(motion, a)
