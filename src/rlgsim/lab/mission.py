"""Scores of a vehicle mission: what each variant of the IMU's data gives through the aided
navigator, outage by outage (issue 26: compensators scored by the coasting error they give).

On a dataset of a ``[trajectory]`` run (docs/trajectories.md) the navigator
(:func:`rlgsim.estimators.ins.aided.aided_navigation`) starts from the true state at the first
powered sample and is aided by GNSS-like position fixes — the route's truth plus white noise
(σ_h, σ_u) once a second where its sky is visible (the ``trajectory`` group's ``gnss_visible``)
— and by zero-velocity updates where the vehicle stands. Variants (as the free-inertial scores
of :mod:`rlgsim.lab.navigation`):

* ``raw``: the pulses through the nominal pulse weights;
* one per compensator: raw minus its gyro-bias prediction (a function of time [s] → (k, 3)
  rad/s);
* ``oracle``: the true temperature laws of the gyro and accelerometer biases removed;
* ``truth``: the route's exact increments (the floor: the filter's and navigator's own error).

Every variant sees the same fixes (one seed). Scores per variant: for every outage the largest
horizontal error inside it [m] (the coasting error), the heading error RMS [arcsec] over the
mission, and the estimated gyro biases at the end against the truth's [°/h].
"""

from __future__ import annotations

import math
import pathlib
from typing import Callable, Mapping

import numpy as np

from rlgsim.estimators.ins.aided import AidingModel, aided_navigation
from rlgsim.estimators.ins.alignment import attitude_error
from rlgsim.estimators.ins.mechanization import InsState
from rlgsim.ground.earth import radii_of_curvature_rad
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import quat_to_dcm
from rlgsim.ground.units import DEG

#: the filter's model of the simulated RLG-IMU's errors (a navigation-grade judgement: the
#: preset's white noise is smaller, its temperature-driven bias change is what it learns)
MISSION_MODEL = AidingModel(arw=0.003 * DEG / 60.0, vrw=30e-6 * 9.80665,
                            gyro_bias_sigma=0.01 * DEG / 3600.0,
                            accel_bias_sigma=100e-6 * 9.80665, gyro_bias_rw=1e-9,
                            accel_bias_rw=1e-6, position_sigma=(1.0, 1.0, 1.0),
                            velocity_sigma=(0.01, 0.01, 0.01), attitude_sigma=(2e-5, 2e-5, 2e-4))


def _runs(flag: np.ndarray) -> list[tuple[int, int]]:
    """(lo, hi) of the runs where ``flag`` is true."""
    d = np.diff(np.r_[0, flag.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def score_mission(path: str | pathlib.Path, *,
                  models: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None,
                  model: AidingModel = MISSION_MODEL, seed: int = 0, update_every_s: float = 1.0
                  ) -> dict[str, dict]:
    """Per variant: ``outage_error_m`` (one per outage), ``heading_rms_arcsec``,
    ``gyro_bias_est_deg_h`` and ``gyro_bias_true_deg_h`` (3,) at the end, ``t_s`` and
    ``horizontal_m`` (the error at every epoch). Module docstring."""
    import h5py

    from rlgsim.lab.navigation_source import open_source
    p = pathlib.Path(path)
    with h5py.File(p, "r") as f:
        if "trajectory" not in f:
            raise UserInputError(f"{p}: no trajectory group; the mission scores need a run on a "
                                 f"vehicle ([trajectory], docs/trajectories.md)")
        g = f["trajectory"]
        lat = np.radians(g["latitude"][...])
        lon = np.radians(g["longitude"][...])
        hgt = np.asarray(g["height"][...])
        vel = np.asarray(g["velocity"][...])
        q = np.asarray(g["attitude"][...])
        visible = np.asarray(g["gnss_visible"][...]).astype(bool)
        rate = float(f.attrs["sample_rate_hz"])
        step_s = float(f.attrs["thermal_step_s"])
        power = np.asarray(f["thermal/power_on"][...])
        tr = f["truth"]
        law_g = np.asarray(tr["gyro_bias"][...]) - np.asarray(tr["gyro_bias_random"][...])
        law_a = np.asarray(tr["accel_bias"][...]) - np.asarray(tr["accel_bias_random"][...])
        true_bias_end = np.asarray(tr["gyro_bias"][-1])
        text, source = str(f.attrs["scenario_text"]), str(f.attrs["scenario_source"])
    src = _source(p, open_source)
    on = np.flatnonzero(power >= 1)
    start = int(math.ceil(on[0] * step_s * rate)) if on.size else 0
    every = max(1, int(round(update_every_s * rate)))
    n = (lat.size - start) // every * every
    k = np.arange(start, start + n)
    mid = np.minimum(((k + 0.5) / rate // step_s).astype(np.intp), law_g.shape[0] - 1)
    ng, na = src.read(start, start + n)
    raw = (ng * src.gyro_weight, na * src.accel_weight)
    variants = {"raw": raw}
    for name, pred in (models or {}).items():
        variants[name] = (raw[0] - np.asarray(pred((k + 0.5) / rate), float) / rate, raw[1])
    variants["oracle"] = (raw[0] - law_g[mid] / rate, raw[1] - law_a[mid] / rate)
    variants["truth"] = _truth_increments(text, source, start, n, rate)
    src.close()
    # the fixes, the stops, the start (sample `start − 1` ends where the navigation starts)
    rng = np.random.default_rng(seed)
    epochs = start + np.arange(every, n + 1, every) - 1          # sample ending each epoch
    rm, rn = radii_of_curvature_rad(lat[epochs])
    noise = rng.normal(0.0, [model.fix_sigma_h_m, model.fix_sigma_h_m, model.fix_sigma_u_m],
                       (epochs.size, 3))
    fix = visible[epochs]
    t_rel = (epochs - start + 1) / rate
    s0 = max(start - 1, 0)
    init = InsState(q[s0].copy(), vel[s0].copy(), float(lat[s0]), float(lon[s0]),
                    float(hgt[s0]))
    stopped = np.linalg.norm(vel[start:start + n], axis=1) == 0.0
    out = {}
    for name, (dth, dv) in variants.items():
        sol = aided_navigation(
            init, dth, dv, 1.0 / rate, model, fix_t_s=t_rel[fix],
            fix_lat=(lat[epochs] + noise[:, 1] / (rm + hgt[epochs]))[fix],
            fix_lon=(lon[epochs] + noise[:, 0] / ((rn + hgt[epochs])
                                                  * np.cos(lat[epochs])))[fix],
            fix_h=(hgt[epochs] + noise[:, 2])[fix], stopped=stopped, update_every=every)
        horiz = np.hypot((sol.lat - lat[epochs]) * (rm + hgt[epochs]),
                         (sol.lon - lon[epochs]) * (rn + hgt[epochs]) * np.cos(lat[epochs]))
        heading = attitude_error(quat_to_dcm(sol.q), quat_to_dcm(q[epochs]))[:, 2]
        out[name] = {"t_s": t_rel, "horizontal_m": horiz,
                     "outage_error_m": [float(horiz[a:b].max()) for a, b in _runs(~fix)],
                     "heading_rms_arcsec": float(np.sqrt(np.mean(heading ** 2)) / DEG * 3600),
                     "gyro_bias_est_deg_h": sol.gyro_bias[-1] / DEG * 3600,
                     "gyro_bias_true_deg_h": true_bias_end / DEG * 3600}
    return out


def _source(path: pathlib.Path, open_source):
    """The pulses and nominal pulse weights (the free-inertial scores' reader refuses a vehicle
    run for its alignment; its pulse reading is what is needed here)."""
    import h5py

    from rlgsim.lab.navigation_source import NavSource, _text, _weight
    f = h5py.File(path, "r")
    imu, tr = f["imu"], f["truth"]
    coef = {_text(n): (float(v), _text(u)) for n, v, u in zip(
        tr["coefficient"][...], tr["coefficient_value"][...], tr["coefficient_units"][...])}
    k_g = np.array([_weight(coef, f"gyro.k0[{a}]", "pulses/rad", path) for a in "xyz"])
    k_a = np.array([_weight(coef, f"accel.k0[{a}]", "pulses/(m/s)", path) for a in "xyz"])

    def read(k0: int, k1: int):
        return (np.asarray(imu["gyro_pulses"][k0:k1], dtype=float),
                np.asarray(imu["accel_pulses"][k0:k1], dtype=float))
    return NavSource(path.name, float(f.attrs["sample_rate_hz"]), 0.0, 0.0,
                     int(imu["gyro_pulses"].shape[0]), 1.0 / k_g, 1.0 / k_a, 0, 0, read,
                     lambda t: None, closers=[f.close])


def _truth_increments(text: str, source: str, start: int, n: int, rate: float):
    """The route's exact increments of samples start..start+n−1, from the dataset's scenario."""
    from rlgsim.sim.run.scenario import parse_scenario
    src = pathlib.Path(source)
    sc = parse_scenario(text, source, base_dir=src.parent if src.is_file() else None)
    route = sc.trajectory.build(sc.duration_s)
    per = int(round(600 * rate))
    parts = [route.increments((start + k) / rate, min(per, n - k), rate, angles=False)
             for k in range(0, n, per)]
    return (np.concatenate([p.dtheta_rad for p in parts]),
            np.concatenate([p.dv_m_per_s for p in parts]))
