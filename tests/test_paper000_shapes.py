"""benchmarks/paper000_shapes.py: the beyond-cubic structure and the calibration noise it reads
from a paper000 report, checked on synthetic data whose parts are known."""

from __future__ import annotations

import importlib.util
import math
import pathlib

import numpy as np
import pandas as pd
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("paper000_shapes",
                                                  ROOT / "benchmarks" / "paper000_shapes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_ratio_for_gain_inverts_the_ceiling():
    mod = _module()
    for gain in (5.0, 35.27, 80.12):
        r = mod.ratio_for_gain(gain)
        assert 100.0 * (1.0 - 1.0 / math.hypot(1.0, r)) == pytest.approx(gain, rel=1e-12)
    assert mod.ratio_for_gain(35.27) == pytest.approx(1.178, abs=1e-3)


def test_shapes_recovers_known_noise_and_structure():
    """Truth = cubic + a 2.5 K-period ripple of std 0.5 (a cubic cannot follow it over 70 K);
    estimate = truth + white noise of std 1.0; 4000 windows: σ_e and n within 4 % (their
    sampling errors are ≈ 1 %), the ceiling from them, and a model equal to the truth scores
    what the ceiling says (RMSE against the estimates)."""
    mod = _module()
    rng = np.random.default_rng(7)
    t = np.linspace(-5.0, 65.0, 4000)
    ripple = 0.5 * math.sqrt(2.0) * np.sin(2 * np.pi * t / 2.5)
    truth = 1e-4 * (t - 30.0) ** 3 + 0.02 * t + ripple
    est = truth + rng.normal(0.0, 1.0, t.size)
    cubic = np.polyval(np.polyfit(t, truth, 3), t)
    table = pd.DataFrame({"parameter": "p", "window": np.arange(t.size), "temperature_c": t,
                          "estimate": est, "truth": truth, "hho_rvr": truth, "lsm": cubic})
    row = mod.shapes(table).iloc[0]
    assert row["noise σ_e"] == pytest.approx(1.0, rel=0.04)
    assert row["beyond cubic n"] == pytest.approx(0.5, rel=0.04)
    assert row["ceiling %"] == pytest.approx(100 * (1 - 1 / math.hypot(1, 0.5)), rel=0.1)
    assert row["ours %"] == pytest.approx(row["ceiling %"], abs=2.0)
