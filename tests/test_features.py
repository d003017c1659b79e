"""Features: the named-column table, window means, dT/dt slopes, probe-pair gradients."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rlgsim.estimators.columns import Columns, resolve_input_names, select_inputs
from rlgsim.estimators.features import (pairwise_gradients, samples_per_window, temperature_rate,
                                 window_average, window_end_times, window_features)

RNG = np.random.default_rng(20240605)


# --- Columns -----------------------------------------------------------------------------

def test_columns_dict_and_array_views():
    t = Columns({"T": [1, 2, 3], "U": [4.0, 5.0, 6.5]})
    assert t.names == ("T", "U") and list(t) == ["T", "U"] and len(t) == 2
    assert t.shape == (3, 2) and t.n_samples == 3
    np.testing.assert_array_equal(np.asarray(t), [[1, 4], [2, 5], [3, 6.5]])
    assert np.asarray(t).dtype == np.float64
    np.testing.assert_array_equal(t["U"], [4, 5, 6.5])
    assert t.select(["U", "T"]).names == ("U", "T")
    assert t.rows(slice(1, None))["T"].tolist() == [2.0, 3.0]
    assert t.rows(np.array([True, False, True]))["U"].tolist() == [4.0, 6.5]
    assert t.with_columns({"B": [0, 0, 1]}).names == ("T", "U", "B")
    assert "T" in t and "B" not in t


def test_columns_are_immutable_copies():
    src = np.array([1.0, 2.0])
    t = Columns({"a": src})
    src[0] = 99.0
    assert t["a"][0] == 1.0
    with pytest.raises(ValueError):
        t["a"][0] = 5.0
    with pytest.raises(ValueError):
        t.values[0, 0] = 5.0


@pytest.mark.parametrize("columns, message", [
    ({"a": [1, 2, 3], "b": [1, 2]}, "mismatched column lengths: 'a' has 3 values, 'b' has 2"),
    ({"a": [[1, 2], [3, 4]]}, "must be 1-D"),
    ({"": [1]}, "non-empty strings"),
    ({}, "at least one column"),
])
def test_columns_reject_bad_tables(columns, message):
    with pytest.raises(ValueError, match=message):
        Columns(columns)


def test_columns_duplicate_and_missing_names():
    with pytest.raises(ValueError, match="duplicate column name 'a'"):
        Columns([("a", [1]), ("a", [2])])
    with pytest.raises(KeyError, match="no column 'z'"):
        Columns({"a": [1]})["z"]


def test_input_names_resolution():
    t = Columns({"T": [1, 2], "U": [3, 4]})
    assert resolve_input_names(t, None, 2) == ("T", "U")
    assert resolve_input_names(np.zeros((2, 2)), None, 2) == ("x0", "x1")
    assert resolve_input_names(np.zeros((2, 2)), ["a", "b"], 2) == ("a", "b")
    with pytest.raises(ValueError, match="feature_names has 1 names but X has 2 columns"):
        resolve_input_names(np.zeros((2, 2)), ["a"], 2)
    with pytest.raises(ValueError, match="disagree"):
        resolve_input_names(t, ["U", "T"], 2)
    with pytest.raises(ValueError, match="lacks the input.*U"):
        select_inputs(Columns({"T": [1.0]}), ("T", "U"))


# --- windows -------------------------------------------------------------------------------

def test_samples_per_window():
    assert samples_per_window(100.0, 100.0) == 10_000
    assert samples_per_window(0.01, 100.0) == 1
    with pytest.raises(ValueError, match="whole number of samples"):
        samples_per_window(3.0, 0.5)
    with pytest.raises(ValueError, match="rate_hz must be positive"):
        samples_per_window(0.0, 100.0)


def test_window_average_drops_partial_window():
    x = RNG.normal(size=(2550, 3))
    means = window_average(x, rate_hz=10.0, window_s=100.0)       # 1000 samples / window
    assert means.shape == (2, 3)
    np.testing.assert_allclose(means[0], x[:1000].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(means[1], x[1000:2000].mean(axis=0), rtol=1e-12)
    # the partial window (550 samples) cannot influence the result
    x[2000:] = 1e9
    np.testing.assert_allclose(window_average(x, 10.0, 100.0), means, rtol=1e-12)
    np.testing.assert_array_equal(window_end_times(2550, 10.0, 100.0), [100.0, 200.0])


def test_window_average_of_table_keeps_names():
    t = Columns({"T": np.arange(20.0), "UHFO": np.ones(20)})
    out = window_average(t, rate_hz=1.0, window_s=5.0)
    assert out.names == ("T", "UHFO")
    np.testing.assert_allclose(out["T"], [2.0, 7.0, 12.0, 17.0])


def test_window_average_bad_input():
    with pytest.raises(ValueError, match="NaN"):
        window_average([1.0, np.nan, 2.0, 3.0], 1.0, 2.0)
    with pytest.raises(ValueError, match="infinity"):
        window_average([1.0, np.inf, 2.0, 3.0], 1.0, 2.0)
    with pytest.raises(ValueError, match="fewer than one window"):
        window_average(np.ones(5), 1.0, 10.0)


# --- temperature rate ---------------------------------------------------------------------

def test_temperature_rate_of_a_ramp_is_exact():
    rate_hz, rate_k_per_s = 10.0, 1.0 / 60.0                  # 1 °C/min chamber ramp
    t = np.arange(5000) / rate_hz
    T = -40.0 + rate_k_per_s * t
    np.testing.assert_allclose(temperature_rate(T, rate_hz, 100.0), rate_k_per_s, rtol=1e-9)


def test_temperature_rate_matches_scipy_linregress_per_window():
    rate_hz, window_s = 4.0, 25.0
    m = int(rate_hz * window_s)
    t = np.arange(1050) / rate_hz
    T = 20 + 3 * np.sin(t / 40.0) + RNG.normal(0, 0.05, t.size)
    got = temperature_rate(T, rate_hz, window_s)
    assert got.shape == (1050 // m,)
    want = [stats.linregress(t[j * m:(j + 1) * m], T[j * m:(j + 1) * m]).slope
            for j in range(1050 // m)]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def test_temperature_rate_of_table_and_2d():
    t = np.arange(200) / 2.0
    table = Columns({"T": 0.1 * t, "T_B": -0.02 * t})
    out = temperature_rate(table, 2.0, 10.0)
    assert out.names == ("dT/dt", "dT_B/dt")
    np.testing.assert_allclose(out["dT/dt"], 0.1, rtol=1e-9)
    np.testing.assert_allclose(temperature_rate(table.values, 2.0, 10.0)[:, 1], -0.02,
                               rtol=1e-9)
    with pytest.raises(ValueError, match="at least 2 samples per window"):
        temperature_rate(t, 1.0, 1.0)


# --- gradients and the model table -------------------------------------------------------

def test_pairwise_gradients_eight_probes_give_28_pairs():
    probes = "ABCDEFGH"
    temps = Columns({p: 20 + i + RNG.normal(0, 0.1, 50) for i, p in enumerate(probes)})
    grads = pairwise_gradients(temps)
    assert len(grads) == 28 == len(probes) * (len(probes) - 1) // 2
    assert grads.names[:3] == ("A-B", "A-C", "A-D") and grads.names[-1] == "G-H"
    np.testing.assert_allclose(grads["C-F"], temps["C"] - temps["F"], rtol=1e-12)
    # order fixes the sign; arrays need names
    arr = pairwise_gradients(temps.values[:, :2], names=["B", "A"])
    np.testing.assert_allclose(arr["B-A"], temps["A"] - temps["B"], rtol=1e-12)
    with pytest.raises(ValueError, match="at least 2 probes"):
        pairwise_gradients({"A": [1.0, 2.0]})
    with pytest.raises(ValueError, match="needs names"):
        pairwise_gradients(np.zeros((3, 2)))


def test_window_features_builds_paper_tables():
    rate_hz, n = 1.0, 1000
    t = np.arange(n) / rate_hz
    T = 25 + 0.5 * t / 60.0
    raw = Columns({"T": T, "UHFO": 4 + 0.001 * T, "B": 0.01 + 1e-4 * T,
                   "A": T + 0.3, "C": T - 0.1})
    table = window_features(raw, rate_hz, 100.0, rate_of=["T"], gradients_of=["A", "T", "C"])
    assert table.names == ("T", "UHFO", "B", "A", "C", "dT/dt", "A-T", "A-C", "T-C")
    assert table.n_samples == 10
    np.testing.assert_allclose(table["dT/dt"], 0.5 / 60.0, rtol=1e-9)
    np.testing.assert_allclose(table["A-C"], 0.4, rtol=1e-9)
    np.testing.assert_allclose(table["UHFO"], window_average(raw["UHFO"], rate_hz, 100.0))
