"""A test run's measured gyro rate at the IMU sample rate, for the Allan-deviation figures: at
the window length (100 s) the angle random walk is already averaged away; from the sample rate
on, the curve shows pulse quantisation (slope −1) and angle random walk (slope −½) first."""

from __future__ import annotations

import numpy as np

#: Samples read at a time (memory stays bounded whatever the run's length).
_BLOCK = 1 << 22
DEG_PER_H_PER_RAD_PER_S = 180.0 / np.pi * 3600.0


def sample_rate_series(rs, gyro: str | None, window_s: float
                       ) -> tuple[float, np.ndarray, int] | None:
    """``(rate_hz, y, m)``: the gyro rate (pulses × rate / nominal scale factor, °/h; no Earth
    rate removed — a constant does not change an Allan deviation) of every sample of the kept
    windows of run ``rs`` (a ``RunSeries``), ``m`` samples per window, in window order. None
    for a recording or a dataset that cannot be read that way (the caller falls back to the
    window series)."""
    from rlgsim.ground.dataset_format import IMU, open_dataset
    try:
        with open_dataset(rs.path) as ds:
            gyros = ds.strings(IMU, "gyro")
            axis = gyro or gyros[0]
            col = gyros.index(axis)
            rate = float(ds.group_attrs(IMU)["sample_rate_hz"])
            m = int(round(window_s * rate))
            k0 = float(rs.coefficients[f"gyro.k0[{axis}]"])
            windows = np.rint(np.asarray(rs.time_s) / window_s).astype(np.int64) - 1
            if m < 1 or windows.size == 0 or windows.min() < 0:
                return None
            y = np.empty(windows.size * m)
            for start in range(0, windows.size, max(1, _BLOCK // m)):
                w = windows[start:start + max(1, _BLOCK // m)]
                lo, hi = int(w.min()) * m, (int(w.max()) + 1) * m
                p = ds.read(IMU, "gyro_pulses", slice(lo, hi), col).astype(np.float64)
                rows = p.reshape(-1, m)[w - int(w.min())]
                y[start * m:(start + w.size) * m] = rows.ravel() * (rate / k0
                                                                    * DEG_PER_H_PER_RAD_PER_S)
            return rate, y, m
    except Exception:           # noqa: BLE001 — a recording or another layout: window series
        return None
