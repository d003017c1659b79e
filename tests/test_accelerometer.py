"""Accelerometer model (sim/sensors/accelerometer.py): gravity to pulse resolution, K+/K− chosen by
the sign of the input, temperature laws, velocity random walk through the pulse chain."""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest

from _imu_helpers import SITE, cat, make_sim, run
from rlgsim.ground import units
from rlgsim.sim.sensors import pulses
from rlgsim.sim.sensors.accelerometer import AccelerometerModel
from rlgsim.sim.config import Ctx
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.motion.kinematics import body_to_enu
from rlgsim.sim.motion.turntable import TurntableProgram

KA = 5000.0 / units.G0                          # pulses/(m/s): 5000 pulses/s at 1 g0


def test_zero_error_static_accelerometers_measure_gravity():
    """Perfect accelerometers at a tilted orientation for 1 h: Σpulses/K over the run equals the
    specific force (−gravity) projected on each body axis × time, to one pulse."""
    outer, inner = 35.0, -60.0
    sim = make_sim({"gyro": {}, "accelerometer": {}},
                   program=TurntableProgram.static(outer, inner), duration_s=3600.0)
    rows, state = run(sim, 6)
    p = cat(rows, "imu", "sample", "accel_pulses")
    assert p.dtype == np.int32 and p.shape == (360_000, 3)
    f_body = body_to_enu(outer, inner).T @ SITE.specific_force_enu
    expected = KA * f_body * 3600.0
    total = p.sum(axis=0)
    assert np.all(np.abs(total - expected) <= 1.0)
    phase = pulses.total_phase(state.accel_remainder, total)
    assert np.all(total == np.floor(phase))
    # gravity itself, from the pulses, to pulse resolution
    g_hat = np.linalg.norm(total / KA / 3600.0)
    assert g_hat == pytest.approx(SITE.gravity, abs=math.sqrt(3) / KA / 3600.0)


@pytest.mark.parametrize("inner", [0.0])
@pytest.mark.parametrize("outer,sign", [(0.0, +1), (180.0, -1)])
def test_positive_and_negative_scale_factors(outer, inner, sign):
    """z up (+g) counts with K+, z down (−g) with K−: +800 ppm vs −600 ppm are told apart."""
    tables = {"gyro": {}, "accelerometer": {"scale_factor_pos": {"value_ppm": 800.0},
                                            "scale_factor_neg": {"value_ppm": -600.0}}}
    sim = make_sim(tables, program=TurntableProgram.static(outer, inner), duration_s=600.0)
    rows, _ = run(sim, 1)
    p = cat(rows, "imu", "sample", "accel_pulses")[:, 2]
    k = KA * (1 + (800e-6 if sign > 0 else -600e-6))
    expected = k * sign * SITE.gravity * 600.0
    assert abs(p.sum() - expected) <= 1.0
    wrong = KA * (1 + (-600e-6 if sign > 0 else 800e-6)) * sign * SITE.gravity * 600.0
    assert abs(p.sum() - wrong) > 100.0


def test_temperature_coefficients_in_truth():
    """Bias 30 µg/K and scale factors +20/+25 ppm/K on the accelerometer node: the truth rows
    follow the node temperature (a 1 K/min ramp)."""
    tables = {"gyro": {}, "accelerometer": {
        "bias": {"value_ug": 50.0, "c1_ug_per_k": 30.0},
        "scale_factor_pos": {"c1_ppm_per_k": 20.0}, "scale_factor_neg": {"c1_ppm_per_k": 25.0}}}
    sim = make_sim(tables, program=TurntableProgram.static(), duration_s=600.0)
    rows, _ = run(sim, 1, temp_f=lambda t, j: 20.0 + t / 60.0)
    tr = rows[0]["truth"]["time"]
    temp = 20.0 + tr["time"] / 60.0
    np.testing.assert_allclose(tr["accel_bias"][:, 0] / units.MICRO_G,
                               50.0 + 30.0 * (temp - 20.0), rtol=1e-12)
    np.testing.assert_allclose(tr["accel_scale_factor_pos"][:, 1] / KA - 1,
                               20e-6 * (temp - 20.0), atol=1e-15)
    np.testing.assert_allclose(tr["accel_scale_factor_neg"][:, 2] / KA - 1,
                               25e-6 * (temp - 20.0), atol=1e-15)


def test_vrw_through_pulse_chain():
    """Velocity random walk alone (horizontal x accelerometer, K raised so the pulse step is
    negligible): ADEV of pulses/(K·Δt) is VRW/√τ at τ = 1 s within 10 %, slope −1/2."""
    vrw_ug = 20.0
    k_hi = 1.0e7     # pulses/s at 1 g: z sees 6e9 pulses per 600 s block, under the 2^33 limit
    tables = {"gyro": {}, "accelerometer": {"scale_factor_pulses_per_s_per_g": k_hi},
              "noise": {"accel_vrw_ug_per_sqrt_hz": vrw_ug}}
    sim = make_sim(tables, program=TurntableProgram.static(), duration_s=6000.0)
    rows, _ = run(sim, 10)
    p = cat(rows, "imu", "sample", "accel_pulses")[:, 0].astype(float)
    acc = p / (k_hi / units.G0) * 100.0
    tau, ad, _, _ = allantools.oadev(acc, rate=100.0, data_type="freq",
                                     taus=np.array([0.3, 1.0, 3.0, 10.0, 30.0]))
    assert ad[1] == pytest.approx(vrw_ug * units.MICRO_G, rel=0.10)
    assert np.polyfit(np.log10(tau), np.log10(ad), 1)[0] == pytest.approx(-0.5, abs=0.05)


def test_accelerometer_bias_instability_through_truth():
    """Bias instability alone: the true bias (flicker part) on the thermal grid has a flat
    ADEV floor of 0.664·B over τ ∈ [30, 3000] s (1 Hz samples, 2e5 s)."""
    tables = {"gyro": {}, "accelerometer": {},
              "noise": {"accel_bias_instability_ug": 8.0, "flicker_tau_max_s": 1e5}}
    sim = make_sim(tables, program=TurntableProgram.static(), duration_s=200_000.0,
                   rate_hz=1.0, step_s=1.0)
    rows, _ = run(sim, 334)
    bias = cat(rows, "truth", "time", "accel_bias")[:, 1]
    tau, ad, _, _ = allantools.oadev(bias, rate=1.0, data_type="freq",
                                     taus=np.logspace(np.log10(30), np.log10(3000), 7))
    assert ad.mean() / 0.664 == pytest.approx(8.0 * units.MICRO_G, rel=0.10)
    assert abs(np.polyfit(np.log10(tau), np.log10(ad), 1)[0]) < 0.1


def test_accelerometer_table_errors():
    ctx = Ctx("dev.toml", "accelerometer")
    with pytest.raises(UserInputError, match="nodes: expected 3 node names"):
        AccelerometerModel.from_config({"nodes": ["ax"]}, ctx)
    with pytest.raises(UserInputError, match="scale_factor_pulses_per_s_per_g"):
        AccelerometerModel.from_config({"scale_factor_pulses_per_s_per_g": 0}, ctx)
    with pytest.raises(UserInputError, match=r"accelerometer\.bias\.value_ppm: unknown key "
                                             r"\(did you mean 'value_ug'"):
        AccelerometerModel.from_config({"bias": {"value_ppm": 1.0}}, ctx)
