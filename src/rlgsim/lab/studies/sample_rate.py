"""The Allan-deviation figures of the study reports: a test run's measured gyro rate at the IMU
sample rate (at the window length, 100 s, the angle random walk is already averaged away; from
the sample rate on, the curve shows pulse quantisation (slope −1) and angle random walk
(slope −½) first), and the curves of a run's residual before and after each compensation
(:func:`allan_curves`, shared by the recipes' figures)."""

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


def allan_curves(ax, rs, gyro: str | None, window_s: float, curves, **line) -> float | None:
    """Plot on ``ax`` the overlapping Allan deviation (allantools, octave τ; °/h against s) of
    the residual y − ŷ of run ``rs`` for each ``(label, ŷ per window, style)`` in ``curves``:
    at the sample rate (:func:`sample_rate_series`, ŷ held over each window) when the run's
    dataset gives it, else of the window series. A residual shorter than 8 values or with a
    non-finite one (no oracle on a recording) is left out. ``line``: more plot keywords for
    every curve. Returns the sample rate [Hz] used, or None for the window series."""
    from rlgsim.estimators import metrics as M
    fast = sample_rate_series(rs, gyro, window_s)
    rate = 1.0 / window_s if fast is None else fast[0]
    buf = None if fast is None else np.empty((fast[1].size // fast[2], fast[2]))
    for label, pred, style in curves:
        if fast is None:
            x = rs.y - pred
        else:           # y − ŷ held over each window: np.repeat's values, without its copy
            x = np.subtract(fast[1].reshape(buf.shape), np.asarray(pred, float)[:, None],
                            out=buf).reshape(-1)
        if x.size >= 8 and np.all(np.isfinite(x)):
            ad = M.allan_deviation(x, rate, "octave")
            ax.loglog(ad.tau_s, ad.adev, marker="o", label=label, **line, **style)
    return None if fast is None else rate
