"""Test helper: turntable pulses through the paper-000 measurement equations.

Exact kinematics from :mod:`rlgsim.sim.motion.kinematics`, then per sample
N_g = K_g (D_g Δt + E_g Δθ + n_g), N_a = K_a^± (D_a Δt + E_a Δv + n_a) with white angle /
velocity random walk n and, optionally, integer pulses counted with the remainder carried
(no pulse lost). The estimators' tests use it so that they do not depend on the sensor
engineer's full IMU model (sim/sensors/imu.py), whose temperature laws they do not need.
"""

from __future__ import annotations

import math

import numpy as np

from rlgsim.estimators.kalman_calibration import CommandedMotion
from rlgsim.estimators.strapdown import ARCSEC, SensorModel
from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.kinematics import Motion, segments_from_program
from rlgsim.sim.motion.turntable import TurntableProgram

KG = 2.14 / ARCSEC                  # pulses/rad (paper 000: 2.14 pulses/arcsec)
KA = 5000.0 / 9.80665               # pulses/(m/s): 5000 pulses/s at 1 g
DEG_H = math.pi / 180 / 3600
UG = 9.80665e-6
SITE = Site(34.0, 0.0)


def nominal() -> SensorModel:
    return SensorModel.nominal(KG, KA)


def random_truth(rng: np.random.Generator, *, bias_deg_h=0.02, sf_ppm=50.0, mis_arcsec=20.0,
                 abias_ug=100.0, asf_ppm=100.0) -> SensorModel:
    """A device whose errors are drawn around the nominal one (accelerometer misalignment
    lower-triangular: the body frame is the accelerometer frame)."""
    off = 1 - np.eye(3)
    return SensorModel(
        k_g=KG * (1 + rng.normal(0, sf_ppm * 1e-6, 3)), d_g=rng.normal(0, bias_deg_h, 3) * DEG_H,
        e_g=np.eye(3) + rng.normal(0, mis_arcsec, (3, 3)) * ARCSEC * off,
        k_a_pos=KA * (1 + rng.normal(0, asf_ppm * 1e-6, 3)),
        k_a_neg=KA * (1 + rng.normal(0, asf_ppm * 1e-6, 3)),
        d_a=rng.normal(0, abias_ug, 3) * UG,
        e_a=np.eye(3) + np.tril(rng.normal(0, mis_arcsec, (3, 3)) * ARCSEC, -1))


def commanded(segments, t0_s: float = 0.0) -> list[CommandedMotion]:
    return [CommandedMotion(s.t0_s - t0_s, s.t1_s - t0_s, s.attrs["kind"], s.attrs["axis"],
                            s.attrs["rate_deg_s"], s.attrs["outer_deg"], s.attrs["inner_deg"],
                            s.attrs["position"], s.label) for s in segments]


def window(truth: SensorModel, program: TurntableProgram | None = None, *, rate_hz=100.0,
           duration_s: float | None = None, arw_deg_sqrt_h=0.0, vrw_ug_sqrt_hz=0.0,
           quantise=False, seed=0):
    """Pulses (gyro, accel) for one window of ``program`` (default: the 40-min 19-position
    sequence) and the commanded motions."""
    program = program or TurntableProgram.calibration19()
    duration_s = duration_s or program.duration_s
    segs = segments_from_program(program, duration_s)
    n = int(round(duration_s * rate_hz))
    blk = Motion(segs, SITE).increments(0.0, n, rate_hz)
    dt = 1.0 / rate_hz
    rng = np.random.default_rng(seed)
    dth = blk.dtheta_rad
    dv = blk.dv_m_per_s
    if arw_deg_sqrt_h:
        dth = dth + rng.normal(0, arw_deg_sqrt_h * math.pi / 180 / 60 * math.sqrt(dt), dth.shape)
    if vrw_ug_sqrt_hz:
        dv = dv + rng.normal(0, vrw_ug_sqrt_hz * UG * math.sqrt(dt), dv.shape)
    ng, na = truth.pulses(dth, dv, dt)
    if quantise:
        ng = count(ng, rng.uniform(0, 1, 3))
        na = count(na, rng.uniform(0, 1, 3))
    return ng, na, commanded(segs), blk


def window_slow_noise(truth: SensorModel, program: TurntableProgram, *, rate_hz=100.0,
                      arw_deg_sqrt_h=0.0, vrw_ug_sqrt_hz=0.0, gyro_bi_deg_h=0.0,
                      gyro_rrw_deg_h_sqrt_h=0.0, accel_bi_ug=0.0, accel_rrw_ug_sqrt_s=0.0,
                      seed=0, step_s=1.0):
    """As :func:`window` with integer pulses, plus bias instability (flicker, the simulator's
    :class:`rlgsim.sim.sensors.noise.FlickerBank`) and rate random walk on every bias, held per ``step_s``
    like the simulator's thermal step. Returns pulses, motions and the model whose biases are
    the true window means."""
    from rlgsim.sim.sensors.noise import FlickerBank, RandomWalk
    segs = segments_from_program(program, program.duration_s)
    n = int(round(program.duration_s * rate_hz))
    blk = Motion(segs, SITE).increments(0.0, n, rate_hz)
    dt = 1.0 / rate_hz
    rng = np.random.default_rng(seed)
    m = int(round(program.duration_s / step_s))
    per = n // m
    bias = {}
    for name, bi, rrw, unit in (("g", gyro_bi_deg_h, gyro_rrw_deg_h_sqrt_h / 60.0, DEG_H),
                                ("a", accel_bi_ug, accel_rrw_ug_sqrt_s, UG)):
        fb = FlickerBank(np.full(3, bi * unit), step_s)
        fl, _ = fb.block(fb.initial_state(rng), rng, m)
        rw, _ = RandomWalk(np.full(3, rrw * unit), step_s).block(np.zeros(3), rng, m)
        bias[name] = np.repeat(fl + rw, per, axis=0)                 # (n, 3) per sample
    dth = blk.dtheta_rad + rng.normal(0, arw_deg_sqrt_h * math.pi / 180 / 60 * math.sqrt(dt),
                                      (n, 3)) + bias["g"] * dt
    dv = blk.dv_m_per_s + rng.normal(0, vrw_ug_sqrt_hz * UG * math.sqrt(dt), (n, 3)) \
        + bias["a"] * dt
    # biases enter before E (sim: u = D·Δt + E·Δθ): move the extra increments through E⁻¹
    dth = dth + (np.linalg.solve(truth.e_g, (bias["g"] * dt).T).T - bias["g"] * dt)
    dv = dv + (np.linalg.solve(truth.e_a, (bias["a"] * dt).T).T - bias["a"] * dt)
    ng, na = truth.pulses(dth, dv, dt)
    ng, na = count(ng, rng.uniform(0, 1, 3)), count(na, rng.uniform(0, 1, 3))
    mean = truth.with_(d_g=truth.d_g + bias["g"].mean(0), d_a=truth.d_a + bias["a"].mean(0))
    return ng, na, commanded(segs), mean


def count(inc: np.ndarray, remainder0: np.ndarray) -> np.ndarray:
    """Integer pulses from real-valued increments, fractional remainder carried."""
    total = np.floor(np.cumsum(inc, axis=0) + remainder0)
    return np.diff(np.vstack([np.floor(remainder0)[None], total]), axis=0)


def write_dataset(path, truth: SensorModel, program: TurntableProgram, duration_s: float, *,
                  rate_hz=100.0, arw_deg_sqrt_h=0.0, vrw_ug_sqrt_hz=0.0, quantise=True, seed=0,
                  probes=("gx", "ax"), probe_c=lambda t: 20.0 + t / 3600.0,
                  device_text=None) -> None:
    """A small rlgsim-layout dataset (docs/dataset.md groups timeline, imu, probes, truth) of a
    constant-parameter device on ``program`` — for the campaign tests, independent of the full
    simulator."""
    import json
    import h5py
    segs = segments_from_program(program, duration_s)
    cal = []
    for s in segs:
        w = s.attrs["window"]
        if w is None:
            continue
        if cal and cal[-1]["window"] == w:
            cal[-1]["t1"] = s.t1_s
        else:
            cal.append(dict(window=w, t0=s.t0_s, t1=s.t1_s))
    n = int(round(duration_s * rate_hz))
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    blk = Motion(segs, SITE).increments(0.0, n, rate_hz)
    dth = blk.dtheta_rad + rng.normal(0, arw_deg_sqrt_h * math.pi / 180 / 60 * math.sqrt(dt),
                                      (n, 3))
    dv = blk.dv_m_per_s + rng.normal(0, vrw_ug_sqrt_hz * UG * math.sqrt(dt), (n, 3))
    ng, na = truth.pulses(dth, dv, dt)
    if quantise:
        ng, na = count(ng, rng.uniform(0, 1, 3)), count(na, rng.uniform(0, 1, 3))
    t_th = np.arange(1, int(duration_s) + 1, dtype=float)
    with h5py.File(path, "w") as f:
        f.attrs.update(rlgsim_format="rlgsim dataset", rlgsim_format_version=1,
                       latitude_deg=SITE.latitude_deg, height_m=SITE.height_m,
                       sample_rate_hz=rate_hz, duration_s=duration_s,
                       device_text=device_text or (
                           "[gyro]\nscale_factor_pulses_per_arcsec = 2.14\n"
                           "[accelerometer]\nscale_factor_pulses_per_s_per_g = 5000.0\n"
                           f"[noise]\ngyro_arw_deg_per_sqrt_h = {arw_deg_sqrt_h or 0.002}\n"
                           f"accel_vrw_ug_per_sqrt_hz = {vrw_ug_sqrt_hz or 10.0}\n"))
        tl = f.create_group("timeline")
        rows = ([(s.t0_s, s.t1_s, "turntable", s.label, json.dumps(s.attrs, default=float))
                 for s in segs]
                + [(c["t0"], c["t1"], "calibration", f"calibration window {c['window']}",
                    json.dumps({"window": c["window"]})) for c in cal])
        tl["t0"] = [r[0] for r in rows]
        tl["t1"] = [r[1] for r in rows]
        sd = h5py.string_dtype()
        for k, name in ((2, "track"), (3, "label"), (4, "attrs")):
            tl.create_dataset(name, data=[r[k] for r in rows], dtype=sd)
        imu = f.create_group("imu")
        imu.attrs["sample_rate_hz"] = rate_hz
        imu["gyro_pulses"] = ng.astype(np.int32) if quantise else ng
        imu["accel_pulses"] = na.astype(np.int32) if quantise else na
        pr = f.create_group("probes")
        pr["time"] = t_th
        pr.create_dataset("probe", data=list(probes), dtype=sd)
        pr["temperature"] = np.stack([probe_c(t_th) + i for i in range(len(probes))], axis=1)
        tr = f.create_group("truth")
        tr["time"] = t_th
        m = len(t_th)
        for name, val in (("gyro_scale_factor", truth.k_g), ("gyro_bias", truth.d_g),
                          ("gyro_installation", truth.e_g), ("accel_scale_factor_pos",
                                                             truth.k_a_pos),
                          ("accel_scale_factor_neg", truth.k_a_neg), ("accel_bias", truth.d_a),
                          ("accel_installation", truth.e_a)):
            tr[name] = np.broadcast_to(val, (m, *np.shape(val)))
