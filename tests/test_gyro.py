"""Gyro model (sim/sensors/gyro.py, sim/sensors/pulses.py, sim/sensors/temperature_laws.py): Earth rate, a 360° turn, pulse
conservation, temperature laws, white-noise ADEV through the whole pulse chain."""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest

from _imu_helpers import SITE, cat, make_sim, run
from rlgsim.ground import units
from rlgsim.sim.sensors import pulses
from rlgsim.sim.config import Ctx
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.sensors.gyro import GyroModel
from rlgsim.sim.sensors.sensor_triad import installation_rows, sample_step_index
from rlgsim.sim.motion.kinematics import Motion, body_to_enu, segments_from_program
from rlgsim.sim.motion.turntable import Hold, Rotate, TurntableProgram

K_ARCSEC = 2.14
K = K_ARCSEC / units.ARCSEC                                  # pulses/rad


def test_zero_error_static_gyros_measure_earth_rate():
    """A perfect gyro triad held at a tilted orientation for 2 h: Σpulses/K over the run equals
    the Earth rate projected on each body axis × time, to one pulse."""
    outer, inner = 20.0, 30.0
    sim = make_sim({"gyro": {}}, program=TurntableProgram.static(outer, inner),
                   duration_s=7200.0)
    rows, state = run(sim, 12)
    p = cat(rows, "imu", "sample", "gyro_pulses")
    assert p.dtype == np.int32 and p.shape == (720_000, 3)
    w_body = body_to_enu(outer, inner).T @ SITE.earth_rate_enu             # rad/s
    expected = K * w_body * 7200.0                                          # pulses
    total = p.sum(axis=0)
    assert np.all(np.abs(total - expected) <= 1.0)
    # conservation: Σ pulses = floor(total phase) exactly (remainder ∈ [0, 1) pulse)
    phase = pulses.total_phase(state.gyro_remainder, total)
    assert np.all(total == np.floor(phase))
    # the fixed-point phase rounds each increment to 2^-30 pulse: ≤ 2^-31 per sample, so at
    # most 720 000 · 2^-31 ≈ 3.4e-4 pulse over the run
    np.testing.assert_allclose(phase, expected, rtol=0, atol=720_000 / 2**31 + 1e-6)


def test_zero_error_360_degree_turn_within_one_pulse():
    """Static 10 s, one 360° inner-axis turn at 20 °/s (18 s), static: the z gyro's pulses over
    the turn equal K·(2π + the Earth rate's ∫ over the turn) within one pulse."""
    prog = TurntableProgram((Hold(10.0), Rotate("inner", 360.0, 20.0), Hold(math.inf)))
    sim = make_sim({"gyro": {}}, program=prog, duration_s=600.0)
    rows, _ = run(sim, 1)
    p = cat(rows, "imu", "sample", "gyro_pulses")
    turn = slice(1000, 2800)                                  # samples of [10 s, 28 s)
    blk = Motion(segments_from_program(prog, 600.0), SITE).increments(0.0, 60_000, 100.0)
    earth_part = blk.dtheta_rad[turn, 2].sum() - 2 * math.pi
    assert abs(earth_part) < 2e-3                           # the turn itself is 2π exactly
    assert abs(p[turn, 2].sum() - K * (2 * math.pi + earth_part)) <= 1.0
    # and the turn is 360° to one pulse once the Earth part is removed
    assert abs((p[turn, 2].sum() - K * earth_part) / K - 2 * math.pi) <= 1.0 / K


@pytest.mark.parametrize("splits", [[1], [7, 13, 999], [5000], [1, 1, 1, 2, 3, 5, 8]])
def test_pulse_conservation_any_chunking(splits):
    """Counting in pieces (remainder carried) gives the same pulses as in one go, and
    Σ pulses == floor(total phase) exactly, for positive, negative and mixed increments."""
    rng = np.random.default_rng(len(splits))
    inc = np.concatenate([rng.normal(0.31, 0.05, 4000), rng.normal(-1541.3, 3.0, 500),
                          rng.normal(0.0, 0.02, 3000)])
    q_all = pulses.quantise(inc.copy())
    total_fixed = int(q_all.sum())
    whole, rem = pulses.count_fixed(q_all.copy(), 0)
    parts, r, pos = [], 0, 0
    cuts = np.cumsum(splits)
    for end in [*cuts[cuts < inc.size], inc.size]:
        p, r = pulses.count_fixed(pulses.quantise(inc[pos:end].copy()), r)
        parts.append(p)
        pos = end
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert r == rem and 0 <= r < pulses.ONE
    assert whole.sum() == total_fixed >> pulses.FRACTION_BITS       # floor(total phase)
    assert whole.sum() == math.floor(total_fixed / pulses.ONE)


def test_sample_step_mapping():
    assert sample_step_index(60_000, 600, 100.0, 1.0) == 100
    idx = sample_step_index(600, 1200, 1.0, 0.5)                 # two steps per sample
    np.testing.assert_array_equal(idx[:3], [1, 3, 5])
    idx = sample_step_index(1500, 600, 2.5, 1.0)                 # 2.5 samples per step
    assert idx[0] == 0 and idx[2] == 1 and idx[-1] == 599


def test_installation_rows():
    mis = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    rows = installation_rows(mis, np.array([0, 1, 2]))
    np.testing.assert_array_equal(rows, [[1, 1, 2], [3, 1, 4], [5, 6, 1]])


def _law_table():
    return {"bias": {"value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 2e-4,
                     "c2_deg_per_h_per_k2": -3e-6, "knee_deg_per_h": 0.004, "knee_c": 35.0,
                     "knee_width_k": 3.0, "step_deg_per_h": -0.003, "step_c": 50.0,
                     "step_width_k": 1.0, "rate_deg_per_h_per_c_per_min": -0.01,
                     "leg_imbalance_ma_per_k": 0.5,
                     "gradients": [{"a": "A", "b": "G", "coeff_deg_per_h_per_k": 0.002}]}}


def test_bias_law_terms_and_not_a_cubic():
    """The realised bias law evaluates term by term as documented, and a cubic in T cannot
    reproduce it (paper 000's premise)."""
    model = GyroModel.from_config({"axes": ["z"], "blocks": ["g"], **_law_table()},
                                  Ctx("t.toml", "gyro"))
    gy = model.realise(lambda name, shape: np.zeros(shape))
    names = [f"g.{n}" for n in [*"ABCDEFGH", "discharge", "preamp", "ballast_D", "ballast_E"]]
    gy.bind(names)
    temps = np.linspace(-40.0, 70.0, 1101)
    nodes = np.repeat(temps[:, None], len(names), axis=1)
    nodes[:, names.index("g.G")] -= 0.5                          # A − G = 0.5 K
    nodes[:, names.index("g.E")] -= 0.2                          # D − E = 0.2 K
    dt = 60.0
    start = nodes[0] - 0.1                                       # 0.1 K per minute in row 0
    bias = gy.bias.evaluate(nodes, start, dt)[:, 0] / units.deg_per_h_to_rad_per_s(1.0)
    x = temps - 20.0
    rate = np.r_[0.1, np.full(temps.size - 1, 0.1)] * 60.0 / dt   # °C/min
    expected = (0.01 + 2e-4 * x - 3e-6 * x ** 2 + 0.004 * np.tanh((temps - 35) / 3)
                - 0.003 / (1 + np.exp(-(temps - 50) / 1.0)) - 0.01 * rate + 0.002 * 0.5
                + 0.0066 * 0.5 * 0.2)
    np.testing.assert_allclose(bias, expected, rtol=1e-12, atol=1e-15)
    cubic = np.polyval(np.polyfit(temps, bias, 3), temps)
    resid = bias - cubic
    assert np.sqrt(np.mean(resid ** 2)) > 5e-4               # °/h: far above float error
    assert np.abs(resid).max() > 1e-3


def test_langmuir_default_relates_arm_gradient_to_imbalance():
    model = GyroModel.from_config({}, Ctx("t.toml", "gyro"))
    gy = model.realise(lambda name, shape: np.zeros(shape))
    assert gy.bias.coef["langmuir"][0] == pytest.approx(0.0066)
    assert gy.bias.coef["leg_imbalance"][0] == pytest.approx(0.033)
    assert model.k0 == pytest.approx(K)


def test_gyro_table_errors():
    ctx = Ctx("dev.toml", "gyro")
    with pytest.raises(UserInputError, match=r"dev.toml: gyro.axes: value 'w' not allowed"):
        GyroModel.from_config({"axes": ["w"]}, ctx)
    with pytest.raises(UserInputError, match="blocks: expected 3 block names"):
        GyroModel.from_config({"blocks": ["g"]}, ctx)
    with pytest.raises(UserInputError, match="did you mean 'c1_deg_per_h_per_k'"):
        GyroModel.from_config({"bias": {"c1_deg_per_h_per_kk": 1.0}}, ctx)
    with pytest.raises(UserInputError, match="knee_width_k"):
        GyroModel.from_config({"bias": {"knee_width_k": 0.0}}, ctx)
    with pytest.raises(UserInputError, match="expected one number or 3 numbers"):
        GyroModel.from_config({"scale_factor": {"value_ppm": [1.0, 2.0]}}, ctx)


def test_arw_through_pulse_chain():
    """ARW alone through the whole chain (static gyro, zero Earth rate on x: East axis;
    K raised to 2000 pulses/arcsec so quantisation is negligible): the ADEV of pulses/(K·Δt)
    is ARW/√τ, read at τ = 1 s within 10 %, slope −1/2."""
    arw = 0.002
    tables = {"gyro": {"scale_factor_pulses_per_arcsec": 2000.0},
              "noise": {"gyro_arw_deg_per_sqrt_h": arw}}
    sim = make_sim(tables, program=TurntableProgram.static(), duration_s=6000.0)
    rows, _ = run(sim, 10)
    p = cat(rows, "imu", "sample", "gyro_pulses")[:, 0].astype(float)
    rate = p / (2000.0 / units.ARCSEC) * 100.0
    tau, ad, _, _ = allantools.oadev(rate, rate=100.0, data_type="freq",
                                     taus=np.array([0.3, 1.0, 3.0, 10.0, 30.0]))
    n = units.deg_per_sqrt_h_to_rad_per_sqrt_s(arw)
    assert ad[1] == pytest.approx(n, rel=0.10)
    assert np.polyfit(np.log10(tau), np.log10(ad), 1)[0] == pytest.approx(-0.5, abs=0.05)
