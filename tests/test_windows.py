"""The one window builder (src/rlgsim/lab/windows.py) against independent references: the Earth
rate on a static mount against WGS-84's published Ω and the ENU projection, the bias formula
against the hand computation, and the gap-tolerant window mean and slope against numpy's
nanmean and a least-squares line fitted by numpy.polyfit to each window's valid samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rlgsim.estimators.features import temperature_rate, window_average
from rlgsim.lab.windows import (DEG_PER_H_PER_RAD_PER_S, bias_deg_per_h, earth_on_axis,
                                gap_windows)

#: WGS-84's Earth rotation rate as NIMA TR8350.2 (3rd ed., table 3.1) prints it [rad/s]
OMEGA_WGS84 = 7.292115e-5


@pytest.mark.parametrize("lat", [-61.5, 0.0, 34.0, 89.0])
def test_earth_rate_on_each_axis_of_a_static_mount(lat):
    L = math.radians(lat)
    expected = {"x": 0.0, "y": OMEGA_WGS84 * math.cos(L), "z": OMEGA_WGS84 * math.sin(L)}
    for axis, value in expected.items():
        # one multiplication and a cosine apart: a few ulps of Ω
        assert earth_on_axis(lat, axis) == pytest.approx(value, rel=1e-15, abs=1e-20)
    assert earth_on_axis(lat, "gyro7") == 0.0


def test_bias_is_rate_minus_earth_in_degrees_per_hour():
    rate = np.array([1e-4, -2e-5, 7.3e-5])
    earth = 4.0e-5
    got = bias_deg_per_h(rate, earth)
    want = (rate - earth) * 180.0 / math.pi * 3600.0
    np.testing.assert_allclose(got, want, rtol=1e-15)
    assert DEG_PER_H_PER_RAD_PER_S == pytest.approx(206264.80624709636, rel=1e-15)


def test_gap_windows_mean_and_slope_of_the_valid_samples():
    rng = np.random.default_rng(7)
    rate_hz, window_s = 1.0, 20.0
    m = 20
    t = np.arange(5 * m) / rate_hz
    x = 25.0 + 0.01 * t + rng.normal(0.0, 0.02, t.size)
    x[3:7] = np.nan                      # window 0: 4 of 20 missing, kept
    x[m + 2:m + 13] = np.nan             # window 1: 11 of 20 missing, dropped
    x[4 * m + 19] = np.nan               # window 4: its last sample missing, kept
    mean = gap_windows(window_average, x, rate_hz, window_s)
    slope = gap_windows(temperature_rate, x, rate_hz, window_s)
    for w in range(5):
        seg = x[w * m:(w + 1) * m]
        ok = np.isfinite(seg)
        if ok.sum() * 2 <= m:
            assert np.isnan(mean[w]) and np.isnan(slope[w])
            continue
        tw = np.arange(m)[ok] / rate_hz
        # a mean of 20 values and a 2-point-conditioned line fit: well inside 1e-12 relative
        assert mean[w] == pytest.approx(np.nanmean(seg), rel=1e-13)
        assert slope[w] == pytest.approx(np.polyfit(tw, seg[ok], 1)[0], rel=1e-9)
    # a complete channel goes straight through the plain window functions
    full = 20.0 + np.sin(np.arange(3 * m) / 7.0)
    np.testing.assert_array_equal(gap_windows(window_average, full, rate_hz, window_s),
                                  window_average(full, rate_hz, window_s))
