"""The validated recording (:class:`Recording`) and its views: sensor outputs in pulses or
rates through the sidecar's nominal scale factors, the Earth rate along each gyro, the slow
(temperature-rate) channels, a pandas DataFrame and the summary ``rlgsim info`` prints.

Part of :mod:`rlgsim.ground.recording`; :func:`rlgsim.ground.recording.load_recording` makes
one. Nothing here imports ``rlgsim.sim``.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.recording_columns import is_slow_kind, rate_rad_per_s
from rlgsim.ground.recording_sidecar import RECORDING_FORMAT, Sidecar
from rlgsim.ground.units import ARCSEC, DEG, EARTH_RATE, G0, HOUR

__all__ = ["Recording"]


@dataclass
class Recording:
    """A validated recording. Arrays are float64; ``time_s`` (n,) is the end of each sample
    interval (sample k covers ``[time_s[k] − 1/f, time_s[k])``); ``columns`` maps the standard
    column name to its (n,) values (slow columns are NaN between their readings and
    ``slow_rows`` indexes the rows that carry them); ``dropout`` (n,) marks rows flagged as
    missing."""

    path: pathlib.Path
    sidecar: Sidecar
    kind: str                                 # csv | parquet | hdf5
    time_s: np.ndarray
    columns: dict[str, np.ndarray]
    dropout: np.ndarray
    slow_rows: np.ndarray | None = None
    kinds: dict[str, tuple[str, str, dict]] = field(default_factory=dict)
    #: ISO 8601 instant of ``time_s = 0`` when the table's time axis is timestamps, else None.
    time_origin: str | None = None

    # ---- metadata ----------------------------------------------------------------------
    @property
    def sample_rate_hz(self) -> float:
        return self.sidecar.sample_rate_hz

    @property
    def n_samples(self) -> int:
        return int(self.time_s.size)

    @property
    def start_s(self) -> float:
        """Start of the first sample interval (the run's time origin in the recording clock)."""
        return float(self.time_s[0] - 1.0 / self.sample_rate_hz) if self.time_s.size else 0.0

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.sample_rate_hz

    def _axes(self, kind: str) -> list[str]:
        out = []
        for name, (k, _, g) in self.kinds.items():
            if k == kind and g.get("axis") and g["axis"] not in out:
                out.append(g["axis"])
        return out

    @property
    def gyro_axes(self) -> list[str]:
        return self._axes("gyro")

    @property
    def accel_axes(self) -> list[str]:
        return self._axes("accel")

    @property
    def probe_names(self) -> list[str]:
        return [g["name"] for k, _, g in self.kinds.values() if k == "probe"]

    def _column_of(self, kind: str, axis: str) -> tuple[str, str]:
        for name, (k, unit, g) in self.kinds.items():
            if k == kind and g.get("axis") == axis:
                return name, unit
        raise KeyError(f"{self.path}: no {kind} column for axis {axis}")

    # ---- sensor outputs ----------------------------------------------------------------
    def _gyro_k_rad(self) -> float | None:
        k = self.sidecar.gyro_sf_pulse_per_arcsec
        return None if k is None else k / ARCSEC

    def gyro_pulses(self) -> np.ndarray:
        """Gyro pulses per sample (n, axes); from a rate column through the nominal scale
        factor (then not whole numbers)."""
        dt = 1.0 / self.sample_rate_hz
        cols = []
        for a in self.gyro_axes:
            name, unit = self._column_of("gyro", a)
            v = self.columns[name]
            if unit != "pulses":
                k = self._need_sf("gyro")
                v = rate_rad_per_s(v, unit) * k * dt
            cols.append(v)
        return np.column_stack(cols) if cols else np.zeros((self.n_samples, 0))

    def gyro_rate_deg_per_h(self) -> np.ndarray:
        """Mean gyro rate over each sample (n, axes) [°/h]; pulses through the nominal scale
        factor."""
        dt = 1.0 / self.sample_rate_hz
        cols = []
        for a in self.gyro_axes:
            name, unit = self._column_of("gyro", a)
            v = self.columns[name]
            rad = v / (self._need_sf("gyro") * dt) if unit == "pulses" else rate_rad_per_s(v, unit)
            cols.append(rad / (DEG / HOUR))
        return np.column_stack(cols) if cols else np.zeros((self.n_samples, 0))

    def accel_pulses(self) -> np.ndarray:
        """Accelerometer pulses per sample (n, axes)."""
        dt = 1.0 / self.sample_rate_hz
        cols = []
        for a in self.accel_axes:
            name, unit = self._column_of("accel", a)
            v = self.columns[name]
            if unit != "pulses":
                v = v * self._need_sf("accel") * dt
            cols.append(v)
        return np.column_stack(cols) if cols else np.zeros((self.n_samples, 0))

    def accel_m_per_s2(self) -> np.ndarray:
        """Mean specific force over each sample (n, axes) [m/s²]; pulse columns through the
        nominal scale factor (needed only for them)."""
        dt = 1.0 / self.sample_rate_hz
        cols = []
        for a in self.accel_axes:
            name, unit = self._column_of("accel", a)
            v = self.columns[name]
            cols.append(v / (self._need_sf("accel") * dt) if unit == "pulses" else v)
        return np.column_stack(cols) if cols else np.zeros((self.n_samples, 0))

    def _need_sf(self, which: str) -> float:
        if which == "gyro":
            k = self._gyro_k_rad()
            key = "[gyro] scale_factor_pulses_per_arcsec"
        else:
            k = (None if self.sidecar.accel_sf_pulse_per_s_per_g is None
                 else self.sidecar.accel_sf_pulse_per_s_per_g / G0)
            key = "[accelerometer] scale_factor_pulses_per_s_per_g"
        if k is None:
            raise UserInputError(f"{self.sidecar.path}: {key} missing; it is needed to convert "
                                 f"between pulses and rates")
        return k

    def earth_rate_deg_per_h(self) -> np.ndarray:
        """Earth rate along each gyro axis (axes,) [°/h] with the table at zero, from the site
        latitude and ``[orientation]`` (default: body x east, y north, z up)."""
        lat = self.sidecar.latitude_deg * DEG
        w_enu = EARTH_RATE * np.array([0.0, math.cos(lat), math.sin(lat)])
        default = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]),
                   "z": np.array([0, 0, 1.0])}
        out = []
        for a in self.gyro_axes:
            axis = self.sidecar.orientation.get(a, default.get(a))
            if axis is None:
                raise UserInputError(f"{self.sidecar.path}: orientation.{a} missing; give the "
                                     f"gyro {a}'s input axis as [east, north, up]")
            out.append(float(w_enu @ axis) / (DEG / HOUR))
        return np.array(out)

    # ---- temperatures and other slow channels -----------------------------------------------
    def _slow(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        rows = self.slow_rows if self.slow_rows is not None else np.arange(self.n_samples)
        vals = (np.column_stack([self.columns[n][rows] for n in names]) if names
                else np.zeros((rows.size, 0)))
        return self.time_s[rows], vals

    def probes(self) -> tuple[np.ndarray, np.ndarray]:
        """Probe readings: times (m,) and temperatures (m, probes) [°C]."""
        return self._slow([n for n, (k, _, _) in self.kinds.items() if k == "probe"])

    def slow(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Times (m,) and values (m,) of one slow column (probe, chamber, UHFO, angle)."""
        t, v = self._slow([name])
        return t, v[:, 0]

    def is_slow(self, name: str) -> bool:
        return self.slow_rows is not None and is_slow_kind(name, self.kinds[name][0])

    # ---- views -----------------------------------------------------------------------
    def to_dataframe(self):
        """The table as a pandas DataFrame with the standard column names (``time_s`` first)."""
        import pandas as pd
        data = {"time_s": self.time_s}
        data.update({k: v for k, v in self.columns.items()})
        if self.dropout.any():
            data["dropout"] = self.dropout.astype(np.int8)
        return pd.DataFrame(data)

    def summary(self) -> str:
        """What ``rlgsim info RECORDING`` prints."""
        sc = self.sidecar
        f = self.sample_rate_hz
        lines = [f"{self.path}: {RECORDING_FORMAT} ({self.kind}), sidecar {sc.path}"]
        if sc.description:
            lines.append(f"  description: {sc.description}")
        lines.append(f"  samples: {self.n_samples} at {f:g} Hz, time_s "
                     f"[{self.time_s[0]:.6g} .. {self.time_s[-1]:.6g}], duration "
                     f"{self.duration_s:.6g} s ({self.duration_s / 3600:.4g} h)")
        if self.time_origin is not None:
            lines.append(f"  time origin: {self.time_origin} (time_s counted from the table's "
                         f"timestamps; zoned ones in UTC)")
        if self.slow_rows is not None:
            lines.append(f"  temperature rate: {sc.temperature_rate_hz:g} Hz "
                         f"({self.slow_rows.size} readings)")
        n_drop = int(self.dropout.sum())
        lines.append(f"  dropouts: {n_drop} sample(s)"
                     + (f" ({n_drop / f:.6g} s)" if n_drop else ""))
        lines.append(f"  site: latitude {sc.latitude_deg:g} deg, height {sc.height_m:g} m")
        if sc.platform != "fixed":
            lines.append(f"  platform: {sc.platform} (the IMU moved; its truth: "
                         f"{sc.trajectory or 'not given'}) — the fixed-site readers refuse it")
        if self.gyro_axes:
            k = sc.gyro_sf_pulse_per_arcsec
            rates = self.gyro_rate_deg_per_h() if k is not None or all(
                self.kinds[self._column_of("gyro", a)[0]][1] != "pulses" for a in self.gyro_axes
            ) else None
            lines.append(f"  gyro axes: {', '.join(self.gyro_axes)}; nominal scale factor "
                         f"{'-' if k is None else f'{k:g}'} pulses/arcsec")
            for i, a in enumerate(self.gyro_axes):
                name = self._column_of("gyro", a)[0]
                if rates is not None:
                    r = rates[~self.dropout, i]
                    lines.append(f"    {name}: mean rate {np.mean(r):.6g} deg/h, std "
                                 f"{np.std(r):.6g} deg/h")
                else:
                    lines.append(f"    {name}")
        if self.accel_axes:
            k = sc.accel_sf_pulse_per_s_per_g
            lines.append(f"  accelerometer axes: {', '.join(self.accel_axes)}; nominal scale "
                         f"factor {'-' if k is None else f'{k:g}'} pulses/s/g")
        for name, (kind, unit, _) in self.kinds.items():
            if kind in ("probe", "chamber", "uhfo", "angle"):
                _, v = self.slow(name) if self.is_slow(name) else (None, self.columns[name])
                ok = v[np.isfinite(v)]
                u = {"c": "degC", "v": "V", "deg": "deg"}[unit]
                lines.append(f"  {name}: min {ok.min():.6g}, mean {ok.mean():.6g}, max "
                             f"{ok.max():.6g} {u}" if ok.size else f"  {name}: no value")
        if "power_on" in self.columns:
            lines.append(f"  power_on: {np.nanmean(self.columns['power_on']) * 100:.4g} % of "
                         f"readings on")
        return "\n".join(lines)

