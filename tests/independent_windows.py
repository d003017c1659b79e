"""Independent re-reading of a single-gyro dataset for the study tests: h5py and numpy only,
none of the code under test (rlgsim.lab.studies.runs.read_run, rlgsim.estimators.features).

Window means over ``window_s`` (100 s, as papers 001-003) of the measured bias y — pulses over
the nominal scale factor minus the table's known input rate (Earth rate on the gyro axis), °/h
— the true bias b and its random part r (°/h), every probe (°C), and the least-squares slope of
one probe (K/s). Windows that start before ``skip_s`` or are not powered throughout are dropped.
"""

from __future__ import annotations

import math
import pathlib

import h5py
import numpy as np

DEG_PER_H = 180.0 / math.pi * 3600.0


def _split(x: np.ndarray, m: int, n: int) -> np.ndarray:
    return x[: n * m].reshape(n, m, *x.shape[1:])


def read_windows(path: pathlib.Path, window_s: float = 100.0, *, skip_s: float = 0.0,
                 slope_of: str | None = None) -> dict:
    """{"y", "b", "r": (n,) °/h; "probes": {name: (n,) °C}; "slope": (n,) K/s of ``slope_of``}."""
    with h5py.File(path, "r") as f:
        rate = float(f["imu"].attrs["sample_rate_hz"])
        step = float(f.attrs["thermal_step_s"])
        axis = f["imu/gyro"][0].decode()
        names = [n.decode() for n in f["truth/coefficient"][:]]
        k0 = float(f["truth/coefficient_value"][names.index(f"gyro.k0[{axis}]")])
        pulses = f["imu/gyro_pulses"][:, 0].astype(np.int64)
        body = [n.decode() for n in f["truth/body"][:]]
        dtheta = f["truth/dtheta_step"][:, body.index(axis)]
        probes = [p.decode() for p in f["probes/probe"][:]]
        temps = f["probes/temperature"][:].astype(float)
        b = f["truth/gyro_bias"][:, 0] * DEG_PER_H
        r = f["truth/gyro_bias_random"][:, 0] * DEG_PER_H
        power = f["thermal/power_on"][:]
    ms, mt = round(window_s * rate), round(window_s / step)
    n = min(pulses.shape[0] // ms, temps.shape[0] // mt)
    y = (_split(pulses, ms, n).sum(axis=1) / (k0 * window_s)
         - _split(dtheta, mt, n).sum(axis=1) / window_s) * DEG_PER_H
    keep = (_split(power, mt, n).min(axis=1) > 0) & (np.arange(n) * window_s >= skip_s)
    P = _split(temps, mt, n)
    out = {"y": y[keep], "b": _split(b, mt, n).mean(axis=1)[keep],
           "r": _split(r, mt, n).mean(axis=1)[keep],
           "probes": {p: P[:, :, i].mean(axis=1)[keep] for i, p in enumerate(probes)}}
    if slope_of is not None:
        t = np.arange(mt) * step
        w = P[:, :, probes.index(slope_of)]
        out["slope"] = np.polyfit(t, w.T, 1)[0][keep]
    return out
