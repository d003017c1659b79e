"""Out-of-range shares (src/rlgsim/lab/studies/input_range.py) against hand-counted cases and a
brute-force count over random data."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.estimators.columns import Columns
from rlgsim.lab.studies.input_range import outside_range, range_note


def test_hand_counted():
    tr = Columns({"T": [0.0, 1.0, 0.5], "U": [5.0, 6.0, 5.5]})
    te = Columns({"T": [-0.5, 0.5, 1.2, 0.2], "U": [5.5, 5.5, 5.5, 6.5]})
    share, excess, name = outside_range(tr, te, ["T", "U"])
    assert share == pytest.approx(75.0)           # windows 0, 2 (T) and 3 (U)
    assert excess == pytest.approx(50.0) and name in ("T", "U")   # 0.5 of a span of 1 each
    share_t, excess_t, name_t = outside_range(tr, te, ["T"])
    assert (share_t, name_t) == (pytest.approx(50.0), "T") and excess_t == pytest.approx(50.0)
    assert outside_range(tr, tr, ["T", "U"]) == (0.0, 0.0, "")


def test_against_brute_force():
    rng = np.random.default_rng(1)
    tr = rng.normal(size=(200, 3))
    te = rng.normal(scale=1.5, size=(300, 3))
    names = ["a", "b", "c"]
    share, excess, _ = outside_range(Columns(dict(zip(names, tr.T))),
                                     Columns(dict(zip(names, te.T))), names)
    lo, hi = tr.min(axis=0), tr.max(axis=0)
    count = sum(any(not lo[j] <= te[i, j] <= hi[j] for j in range(3)) for i in range(300))
    assert share == pytest.approx(100.0 * count / 300)
    worst = max(max(lo[j] - te[i, j], te[i, j] - hi[j], 0.0) / (hi[j] - lo[j])
                for i in range(300) for j in range(3))
    assert excess == pytest.approx(100.0 * worst)


def test_note_names_the_worst_pair():
    recs = [{"test run": "r1", "compensator": "A", "windows outside the training range %": 0.0,
             "largest excess % of span": 0.0, "input": "—"},
            {"test run": "r2", "compensator": "B", "windows outside the training range %": 12.5,
             "largest excess % of span": 40.0, "input": "T"}]
    note = range_note(recs)
    assert "1 of 2" in note and "12.5 %" in note and "r2" in note and "(B," in note
    assert "inside" in range_note(recs[:1])
