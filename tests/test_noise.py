"""Noise generators (sim/sensors/noise.py): Allan-deviation recovery of each term alone, carried state.

Conventions (IEEE Std 952-1997 Annex C), stated once for all tests here:
* ARW N: the Allan deviation of the rate follows N/√τ; N is read at τ = 1 s.
* Bias instability B: the flicker floor of the Allan deviation is B·√(2 ln2/π) = 0.664·B;
  B = floor / 0.664, the floor taken as the mean ADEV over τ ∈ [30, 3000] s, well inside the
  flicker bank's band (τ_min = 2 s, τ_max = 1e5 s).
* RRW K: the Allan deviation follows K·√(τ/3); K is read at τ = 3 s on the fitted +1/2 line.
Allan deviations come from allantools.oadev(..., data_type="freq") on rate samples.
"""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest

from rlgsim.ground import units
from rlgsim.sim.config import Ctx
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.sensors.noise import (FLICKER_FLOOR, FlickerBank, NoiseModel, RandomWalk, SlowNoise,
                       white_increments)


def _adev(rate: np.ndarray, fs: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tau, ad, _, _ = allantools.oadev(rate, rate=fs, data_type="freq", taus=taus)
    return np.asarray(tau), np.asarray(ad)


def _slope(tau: np.ndarray, ad: np.ndarray) -> float:
    return float(np.polyfit(np.log10(tau), np.log10(ad), 1)[0])


def test_flicker_floor_constant():
    assert FLICKER_FLOOR == pytest.approx(0.664, abs=5e-4)


def test_angle_random_walk_recovered():
    n_arw = units.deg_per_sqrt_h_to_rad_per_sqrt_s(0.002)       # 0.002 °/√h
    fs = 100.0
    rng = np.random.default_rng(1)
    inc = white_increments(rng, 1_000_000, 1, np.array([n_arw]), 1.0 / fs)[:, 0]
    tau, ad = _adev(inc * fs, fs, np.array([0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0]))
    assert ad[tau == 1.0][0] == pytest.approx(n_arw, rel=0.10)
    assert _slope(tau, ad) == pytest.approx(-0.5, abs=0.05)


def test_bias_instability_recovered():
    b = units.deg_per_h_to_rad_per_s(0.003)
    fb = FlickerBank(np.array([b]), 1.0, 2.0, 1.0e5, 2)
    state = fb.initial_state(np.random.default_rng(0))
    parts = []
    for k in range(2000):                                         # 1.2e6 s at 1 Hz
        x, state = fb.block(state, np.random.default_rng([7, k]), 600)
        parts.append(x[:, 0])
    rate = np.concatenate(parts)
    tau, ad = _adev(rate, 1.0, np.logspace(np.log10(30), np.log10(3000), 9))
    assert ad.mean() / FLICKER_FLOOR == pytest.approx(b, rel=0.10)
    assert _slope(tau, ad) == pytest.approx(0.0, abs=0.1)


def test_rate_random_walk_recovered():
    k = units.deg_per_h_per_sqrt_h_to_rad_per_s_per_sqrt_s(0.001)
    rw = RandomWalk(np.array([k]), 1.0)
    state = rw.initial_state()
    parts = []
    for j in range(1000):                                         # 6e5 s at 1 Hz
        x, state = rw.block(state, np.random.default_rng([3, j]), 600)
        parts.append(x[:, 0])
    rate = np.concatenate(parts)
    tau, ad = _adev(rate, 1.0, np.logspace(1, 4, 10))
    slope = _slope(tau, ad)
    assert slope == pytest.approx(0.5, abs=0.05)
    # K on the fitted +1/2 line at τ = 3 s: σ(τ) = K √(τ/3)
    k_hat = float(np.exp(np.mean(np.log(ad / np.sqrt(tau / 3.0)))))
    assert k_hat == pytest.approx(k, rel=0.10)


def test_flicker_bank_psd_weights():
    """The bank's processes share q² = B²Δ/π (Keshner), halved at the two band edges."""
    fb = FlickerBank(np.array([2.0]), 1.0, 1.0, 1.0e4, 2)
    delta = math.log(fb.tau_s[1] / fb.tau_s[0])
    assert np.allclose(np.diff(np.log(fb.tau_s)), delta)
    assert fb.q[3, 0] ** 2 == pytest.approx(4.0 * delta / math.pi)
    assert fb.q[0, 0] ** 2 == pytest.approx(2.0 * delta / math.pi)


def test_carried_state_equals_one_long_run():
    """Splitting the drive into blocks (carried lfilter state / walk value) changes nothing."""
    fb = FlickerBank(np.array([1.0, 2.0]), 0.5, 1.0, 1.0e4, 2)
    rng = np.random.default_rng(5)
    s0 = fb.initial_state(rng)
    w = rng.standard_normal((fb.q.shape[0], 2, 900))
    whole, _ = fb.block_from(s0, w)
    a, s1 = fb.block_from(s0, w[:, :, :333])
    b, _ = fb.block_from(s1, w[:, :, 333:])
    np.testing.assert_array_equal(np.vstack([a, b]), whole)
    rw = RandomWalk(np.array([1.0, 3.0]), 2.0)
    v = rng.standard_normal((900, 2))
    whole, _ = rw.block_from(rw.initial_state(), v)
    a, s = rw.block_from(rw.initial_state(), v[:400])
    b, _ = rw.block_from(s, v[400:])
    np.testing.assert_allclose(np.vstack([a, b]), whole, rtol=0, atol=1e-12)


def test_slow_noise_keyed_by_block_and_axis():
    model = NoiseModel(flicker_tau_min_s=2.0, flicker_tau_max_s=1e4)
    sn = SlowNoise(np.array([1e-6, 2e-6]), np.array([1e-8, 0.0]), 1.0, model, ("x", "y"),
                   seed=11, unit=0, purpose="gyro")
    st = sn.initial_state()
    x0, st1 = sn.block(st, 0, 600)
    x1, _ = sn.block(st1, 1, 600)
    again, _ = sn.block(sn.initial_state(), 0, 600)
    np.testing.assert_array_equal(x0, again)
    assert not np.array_equal(x0, x1)
    # axis y alone gives the same y channel (per-axis keys)
    sy = SlowNoise(np.array([2e-6]), np.array([0.0]), 1.0, model, ("y",), seed=11, unit=0,
                   purpose="gyro")
    y0, _ = sy.block(sy.initial_state(), 0, 600)
    np.testing.assert_array_equal(y0[:, 0], x0[:, 1])


def test_noise_table_validation():
    ctx = Ctx("dev.toml", "noise")
    m = NoiseModel.from_config({"gyro_arw_deg_per_sqrt_h": 0.001,
                                "accel_vrw_ug_per_sqrt_hz": 10}, ctx)
    assert m.gyro_arw == pytest.approx(units.deg_per_sqrt_h_to_rad_per_sqrt_s(0.001))
    assert m.accel_vrw == pytest.approx(10 * units.MICRO_G)
    with pytest.raises(UserInputError, match="gyro_arw_deg_per_sqrt_h"):
        NoiseModel.from_config({"gyro_arw": 0.001}, ctx)
    with pytest.raises(UserInputError, match="must be >= 0"):
        NoiseModel.from_config({"gyro_bias_instability_deg_per_h": -1}, ctx)
    with pytest.raises(UserInputError, match="flicker_tau_max_s"):
        NoiseModel.from_config({"flicker_tau_min_s": 10, "flicker_tau_max_s": 5}, ctx)
