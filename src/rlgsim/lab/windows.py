"""The window series of one run — the one builder the studies (:mod:`rlgsim.lab.studies.runs`,
:mod:`rlgsim.lab.studies.recording_runs`), the digital twin's recordings
(:mod:`rlgsim.lab.identify.recording_data`) and the public API
(:func:`rlgsim.lab.api.window_table`) build their bias windows with.

Per non-overlapping window of W seconds (paper 001 §3 and §4.1):

* the gyro's rate is its pulse count in the window divided by the nominal scale factor K and W
  (a dataset: K = the truth's drawn ``gyro.k0``; a recording: the sidecar's scale factor, or the
  mean of its rate column);
* the measured bias is that rate minus the Earth-rate projection on the gyro axis,
  :func:`bias_deg_per_h`: for a dataset the exact input the truth stores
  (``truth/dtheta_step`` summed over the window, divided by W; Ω·sin L for an up-pointing gyro
  on a static mount), for a recording or a dataset without truth the site's latitude and the
  mount (:func:`rlgsim.ground.earth.earth_rate_enu`, Titterton & Weston §3.4.3);
* inputs are window means of the probe readings and the UHFO and the least-squares slope of a
  temperature (:mod:`rlgsim.estimators.features`); the truth's window means of
  ``truth/gyro_bias`` and its flicker + random-walk part ``truth/gyro_bias_random``.

A dataset is read through the one dataset reader (:func:`rlgsim.ground.dataset_format.open_dataset`)
a block of whole windows at a time, so memory does not grow with the run's duration and every
window comes from its own samples only (the result does not depend on the block size).

Missing readings (NaN: a probe dropout of a simulated anomaly, a dropout row of a recording): a
study refuses them in a dataset and drops the window in a recording; :func:`window_table` (the
API) keeps a window missing at most half of a channel's readings (:func:`gap_windows`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from rlgsim.ground.dataset_format import (IMU, PROBES, THERMAL, TRUTH, Dataset, check_finite,
                                          open_dataset)
from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG, earth_rate_enu
from rlgsim.ground.errors import UserInputError

__all__ = ["DEG_PER_H_PER_RAD_PER_S", "READ_BLOCK_SAMPLES", "Where", "bias_deg_per_h",
           "dataset_windows", "earth_on_axis", "gap_windows", "recording_windows",
           "window_table"]

#: °/h per rad/s.
DEG_PER_H_PER_RAD_PER_S = 180.0 / math.pi * 3600.0
#: Samples read at a time from a dataset (memory stays bounded whatever the run's duration).
READ_BLOCK_SAMPLES = 1 << 22


def bias_deg_per_h(rate_rad_s: np.ndarray, earth_rad_s: np.ndarray | float) -> np.ndarray:
    """The measured bias [°/h] of window rates [rad/s]: the rate minus the Earth-rate projection
    on the gyro axis [rad/s] (paper 001 §4.1)."""
    return (rate_rad_s - earth_rad_s) * DEG_PER_H_PER_RAD_PER_S


def earth_on_axis(latitude_deg: float, axis: str) -> float:
    """The Earth rate [rad/s] along body axis ``axis`` ("x", "y", "z") of a static mount with
    the body axes east, north, up (ω_ie^n of :func:`rlgsim.ground.earth.earth_rate_enu`); 0 for
    an axis of another name."""
    return float(earth_rate_enu(latitude_deg)["xyz".index(axis)]) if axis in ("x", "y", "z") \
        else 0.0


def gap_windows(func: Callable, x, rate_hz: float, window_s: float) -> np.ndarray:
    """``func`` (window mean or least-squares slope) per window of a slow channel with missing
    readings (NaN): a window missing more than half of its samples is NaN (the window is then
    left out), otherwise the value of its valid samples. A complete channel goes straight
    through ``func``."""
    from rlgsim.estimators.features import samples_per_window
    x = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(x)
    if ok.all():
        return func(x, rate_hz, window_s)
    m = samples_per_window(rate_hz, window_s)
    n_win = x.size // m
    xw = x[:n_win * m].reshape(n_win, m)
    okw = ok[:n_win * m].reshape(n_win, m)
    cnt = okw.sum(axis=1)
    x0 = np.where(okw, xw, 0.0)
    mean = x0.sum(axis=1) / np.maximum(cnt, 1)
    if func.__name__ == "window_average":
        out = mean
    else:                               # slope of x against time over the valid samples
        t = np.broadcast_to(np.arange(m, dtype=np.float64) / rate_hz, xw.shape)
        tm = np.where(okw, t, 0.0).sum(axis=1) / np.maximum(cnt, 1)
        dt = np.where(okw, t - tm[:, None], 0.0)
        den = (dt * dt).sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            out = (dt * (x0 - mean[:, None] * okw)).sum(axis=1) / den
    return np.where(cnt * 2 > m, out, np.nan)


# ------------------------------------------------------------------------------ datasets
@dataclass(frozen=True)
class Where:
    """Which columns of a dataset a run's series needs."""

    gyro: int                       # column of the gyro in imu/* and truth/gyro_*
    body: int | None                # column of its axis in truth/dtheta_step (None: no truth)
    probes: dict[str, int]          # probe name → column of probes/temperature (window means)
    uhfo: bool
    slopes: tuple[str, ...] = ()    # the probes whose window slope is wanted (of ``probes``)
    gaps: bool = False              # tolerate missing readings (:func:`gap_windows`)


def _window_block(ds: Dataset, i: int, j: int, m_s: int, m_t: int, step: float, W: float,
                  where: Where) -> dict[str, np.ndarray]:
    """Per-window sums and means of windows ``i … j−1`` (rad for dtheta, rad/s for b and r,
    °C, K/s, V): only these windows' samples are read."""
    from rlgsim.estimators.features import temperature_rate, window_average
    n = j - i
    t0, t1 = i * m_t, j * m_t
    thermal_rate = 1.0 / step
    rows, grid = slice(i * m_s, j * m_s), slice(t0, t1)

    def mean(group: str, name: str, x: np.ndarray) -> np.ndarray:
        if where.gaps:
            return gap_windows(window_average, x, thermal_rate, W)
        return window_average(check_finite(ds.path, group, name, x, t0), thermal_rate, W)

    out = {"counts": ds.read(IMU, "gyro_pulses", rows, where.gyro).astype(np.int64)
           .reshape(n, m_s).sum(axis=1)}
    if where.body is not None:
        out.update(
            dtheta=ds.read(TRUTH, "dtheta_step", grid, where.body).reshape(n, m_t).sum(axis=1),
            b=window_average(ds.read(TRUTH, "gyro_bias", grid, where.gyro), thermal_rate, W),
            r=window_average(ds.read(TRUTH, "gyro_bias_random", grid, where.gyro),
                             thermal_rate, W))
    out["power"] = (ds.read(THERMAL, "power_on", grid).reshape(n, m_t).min(axis=1) > 0
                    if ds.has(THERMAL, "power_on") else np.ones(n, dtype=bool))
    if where.probes:
        cols = sorted(set(where.probes.values()))
        temps = ds.read(PROBES, "temperature", grid, cols).astype(np.float64)
        if not where.gaps:
            temps = check_finite(ds.path, PROBES, "temperature", temps, t0)
        for name, c in where.probes.items():
            out[f"mean:{name}"] = mean(PROBES, "temperature", temps[:, cols.index(c)])
        for name in where.slopes:
            T = temps[:, cols.index(where.probes[name])]
            out[f"slope:{name}"] = (gap_windows(temperature_rate, T, thermal_rate, W)
                                    if where.gaps else temperature_rate(T, thermal_rate, W))
    if where.uhfo:
        out["uhfo"] = mean(IMU, "uhfo", ds.read(IMU, "uhfo", grid, where.gyro).astype(np.float64))
    return out


def dataset_windows(ds: Dataset, where: Where, n_win: int, m_s: int, m_t: int, window_s: float
                    ) -> dict[str, np.ndarray]:
    """Per-window ``counts`` (pulses), ``power`` (powered throughout), and with truth
    ``dtheta`` [rad], ``b``, ``r`` [rad/s], ``mean:<probe>`` [°C], ``slope:<probe>`` [K/s],
    ``uhfo`` [V] of the first ``n_win`` (at least one: the callers say why there is none)
    windows of an open dataset (module docstring)."""
    step = float(ds.attrs["thermal_step_s"])
    per_block = max(1, READ_BLOCK_SAMPLES // max(m_s, m_t))
    blocks = [_window_block(ds, i, min(n_win, i + per_block), m_s, m_t, step, window_s, where)
              for i in range(0, n_win, per_block)]
    return {k: np.concatenate([blk[k] for blk in blocks]) for k in blocks[0]}


# ------------------------------------------------------------------------------ recordings
def recording_windows(rec: Any, axis: str, window_s: float, probes: tuple[str, ...],
                      slopes: tuple[str, ...], uhfo: str | None, *, gaps: bool = False
                      ) -> dict[str, Any]:
    """The window series of a loaded recording (:class:`rlgsim.ground.recording.Recording`):
    ``n_win``; ``y`` the measured bias [°/h] (mean rate minus the Earth rate on the gyro axis,
    site latitude and ``[orientation]``); ``earth`` [°/h]; ``mean:<probe>`` [°C],
    ``slope:<probe>`` [K/s], ``uhfo`` [V] (the column ``uhfo``), ``power`` (window mean of
    ``power_on``, when logged) and ``dropout`` (a dropout row inside the window)."""
    from rlgsim.estimators.features import samples_per_window, temperature_rate, window_average
    W = window_s
    i = rec.gyro_axes.index(axis)
    f = rec.sample_rate_hz
    fs = rec.sidecar.temperature_rate_hz or f
    m_s, m_t = samples_per_window(f, W), samples_per_window(fs, W)
    t_slow, temps = rec.probes()
    n_win = min(rec.n_samples // m_s, len(t_slow) // m_t if rec.slow_rows is not None
                else rec.n_samples // m_s)
    out: dict[str, Any] = {"n_win": n_win}
    if n_win == 0:
        return out
    rate = rec.gyro_rate_deg_per_h()[:n_win * m_s, i].reshape(n_win, m_s).mean(axis=1)
    earth = float(rec.earth_rate_deg_per_h()[i])
    out.update(y=rate - earth, earth=earth)
    names = rec.probe_names

    def mean(v):
        if gaps:
            return gap_windows(window_average, v[:n_win * m_t], fs, W)[:n_win]
        return window_average(v[:n_win * m_t], fs, W)[:n_win]

    for name in probes:
        out[f"mean:{name}"] = mean(temps[:, names.index(name)])
    for name in slopes:
        T = temps[:n_win * m_t, names.index(name)]
        out[f"slope:{name}"] = (gap_windows(temperature_rate, T, fs, W) if gaps
                                else temperature_rate(T, fs, W))[:n_win]
    if uhfo is not None:
        out["uhfo"] = mean(rec.slow(uhfo)[1])
    if "power_on" in rec.columns:
        out["power"] = mean(rec.slow("power_on")[1])
    out["dropout"] = rec.dropout[:n_win * m_s].reshape(n_win, m_s).any(axis=1)
    return out


def uhfo_column(rec: Any, axis: str) -> str | None:
    """The recording's UHFO column for gyro ``axis`` (its own or the one of all axes), or None."""
    uh = [n for n, (k, _, g) in rec.kinds.items() if k == "uhfo" and g.get("axis") in (None, axis)]
    return uh[0] if uh else None


# ------------------------------------------------------------------------------ the API's table
def _axis(axes: list[str], gyro: str | None, source) -> str:
    from rlgsim.ground.gyro_axis import choose_gyro
    return choose_gyro(axes, gyro, where=source,
                       unknown="{where}: gyro {gyro!r} not allowed; the gyro axes are {axes}",
                       several="{where}: several gyros ({axes}); say which one with gyro=")


def _dataset_table(source, window_s: float, gyro: str | None) -> dict[str, np.ndarray]:
    """The columns of :func:`window_table` for a dataset, and which windows to keep."""
    from rlgsim.estimators.features import samples_per_window
    W = window_s
    with open_dataset(source) as ds:
        axes = ds.strings(IMU, "gyro")
        axis = _axis(axes, gyro, source)
        f = float(ds.group_attrs(IMU)["sample_rate_hz"])
        m_s = samples_per_window(f, W)
        m_t = samples_per_window(1.0 / float(ds.attrs["thermal_step_s"]), W)
        truth = ds.has(TRUTH, "dtheta_step")
        coeffs = ds.coefficients() if ds.has(TRUTH, "coefficient") else {}
        k = coeffs.get(f"gyro.k0[{axis}]")
        if k is None:
            import tomllib

            from rlgsim.ground.units import ARCSEC
            from rlgsim.sim.sensors.gyro import pulses_per_arcsec
            k = pulses_per_arcsec(tomllib.loads(str(ds.attrs.get("device_text", "")) or "")
                                  ) / ARCSEC
        names = ds.strings(PROBES, "probe") if ds.has(PROBES, "probe") else []
        n_win = ds.length(IMU, "gyro_pulses") // m_s
        if ds.has(THERMAL, "time"):
            n_win = min(n_win, ds.length(THERMAL, "time") // m_t)
        where = Where(gyro=axes.index(axis),
                      body=ds.strings(TRUTH, "body").index(axis) if truth else None,
                      probes={n: c for c, n in enumerate(names)}, uhfo=ds.has(IMU, "uhfo"),
                      slopes=tuple(names), gaps=True)
        if n_win < 1:                   # window_table says so
            return {"n_win": 0, "seconds": ds.length(IMU, "gyro_pulses") / m_s * W,
                    "what": "run", "where": ds.path}
        w = dataset_windows(ds, where, n_win, m_s, m_t, W)
        latitude = float(ds.attrs.get("latitude_deg", DEFAULT_LATITUDE_DEG))
    earth = w["dtheta"] / W if truth else earth_on_axis(latitude, axis)
    cols: dict[str, Any] = {"time_s": (np.arange(n_win) + 1) * W,
                            "bias_deg_per_h": bias_deg_per_h(w["counts"] / (k * W), earth)}
    if truth:
        cols["true_bias_deg_per_h"] = w["b"] * DEG_PER_H_PER_RAD_PER_S
        cols["true_random_deg_per_h"] = w["r"] * DEG_PER_H_PER_RAD_PER_S
    for name in names:
        cols[f"probe_{name}_c"] = w[f"mean:{name}"]
        cols[f"dTdt_{name}_k_per_s"] = w[f"slope:{name}"]
    if where.uhfo:
        cols["uhfo_v"] = w["uhfo"]
    return {"cols": cols, "keep": w["power"], "n_win": n_win}


def _recording_table(source, window_s: float, gyro: str | None) -> dict[str, Any]:
    """The columns of :func:`window_table` for a recording, and which windows to keep."""
    from rlgsim.ground.recording import load_recording
    rec = load_recording(source)
    from rlgsim.ground.recording_sidecar import need_fixed_site
    need_fixed_site(rec.sidecar, "the window table (identify, the studies, navigate --models)")
    axis = _axis(rec.gyro_axes, gyro, source)
    names = tuple(rec.probe_names)
    w = recording_windows(rec, axis, window_s, names, names, uhfo_column(rec, axis), gaps=True)
    n_win = w["n_win"]
    if n_win < 1:                       # window_table says so
        return {"n_win": 0, "seconds": rec.n_samples / rec.sample_rate_hz, "what": "recording",
                "where": source}
    cols: dict[str, Any] = {"time_s": (np.arange(n_win) + 1) * window_s,
                            "bias_deg_per_h": w.get("y", np.zeros(0))}
    for name in names:
        cols[f"probe_{name}_c"] = w[f"mean:{name}"]
        cols[f"dTdt_{name}_k_per_s"] = w[f"slope:{name}"]
    if "uhfo" in w:
        cols["uhfo_v"] = w["uhfo"]
    keep = ~w["dropout"] if n_win else np.zeros(0, dtype=bool)
    if "power" in w:
        keep &= w["power"] >= 1.0
    return {"cols": cols, "keep": keep, "n_win": n_win}


def window_table(source: str | os.PathLike, window_s: float = 100.0, *,
                 gyro: str | None = None):
    """The window series of a dataset or recording as a :class:`pandas.DataFrame` (one row per
    kept window, columns named with their units; :func:`rlgsim.lab.api.window_table` documents
    them): windows not powered throughout, holding a gyro dropout, or missing more than half of
    a channel's readings are left out."""
    import pandas as pd

    from rlgsim.ground.recording import is_recording
    source = os.fspath(source)
    got = (_recording_table if is_recording(source) else _dataset_table)(source, window_s, gyro)
    if got["n_win"] < 1:                # the one check of both kinds (the studies' runs say it
        what = got["what"]              # with their study key: rlgsim.lab.studies.runs)
        raise UserInputError(f"{got['where']}: {got['seconds']:g} s of data hold no complete "
                             f"{window_s:g}-s window; a window must fit in the {what} (a "
                             f"shorter window or a longer {what})")
    df = pd.DataFrame(got["cols"])
    keep = got["keep"] & np.all(np.isfinite(df.to_numpy(dtype=float)), axis=1)
    return df[keep].reset_index(drop=True)
