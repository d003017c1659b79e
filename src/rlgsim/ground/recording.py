"""Recordings: data that did not come from rlgsim (docs/recordings.md is the format).

A recording is one table — CSV, Parquet, or a group of equal-length 1-D datasets in an HDF5
file written by another tool — plus a small TOML *sidecar* beside it (``run1.csv`` →
``run1.toml``) that says what the table cannot: the sample rate, the site, the sensor axes and
their orientation, the nominal scale factors, optionally the noise levels and a mapping from
the file's own column names to the standard ones.

Column names carry their unit, like the scenario keys: ``time_s``, ``gyro_x_pulses`` or
``gyro_x_rate_deg_per_h``, ``accel_x_pulses`` or ``accel_x_m_per_s2``, ``probe_<name>_c``,
``chamber_air_c``, ``chamber_setpoint_c``, ``uhfo_v`` / ``uhfo_<axis>_v``,
``outer_angle_deg``, ``inner_angle_deg``, ``power_on``, ``dropout`` (:data:`COLUMN_RULES`).

:func:`load_recording` validates every column — known name and unit, values in range, whole
pulse counts, strictly increasing time at the sample rate with no gap, no NaN outside rows
flagged ``dropout = 1``, slow (temperature-rate) columns on a regular grid — and raises a
one-line :class:`~rlgsim.ground.errors.UserInputError` naming the file, column, row (1-based
data row, header excluded) and what is allowed.

Nothing here imports ``rlgsim.sim``: the estimators read recordings too.
"""

from __future__ import annotations

import math
import os
import pathlib
import re
import tomllib
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.recording_formats import DATA_SUFFIXES, TABLE_FORMATS
from rlgsim.ground.toml_text import dumps
from rlgsim.ground.units import ARCSEC, DEG, EARTH_RATE, G0, HOUR

__all__ = ["RECORDING_FORMAT", "RECORDING_VERSION", "DATA_SUFFIXES", "COLUMN_RULES",
           "Recording", "load_recording", "is_recording", "sidecar_path", "write_sidecar",
           "write_table"]

#: ``[recording] format`` of a sidecar (optional in a hand-written one; written by the exporter).
RECORDING_FORMAT = "rlgsim recording"
#: ``[recording] version``; readers refuse newer versions.
RECORDING_VERSION = 1

#: Allowed range of each kind of value (what the messages say is allowed).
TEMPERATURE_RANGE_C = (-100.0, 200.0)
UHFO_RANGE_V = (-1000.0, 1000.0)
GYRO_RATE_LIMIT_DEG_PER_S = 2000.0
ACCEL_LIMIT_M_PER_S2 = 100.0 * G0

#: Column grammar: (regex, kind, unit, human description). ``{axis}`` is a sensor axis name.
COLUMN_RULES: list[tuple[str, str, str, str]] = [
    (r"time_s", "time", "s", "time_s (end of each sample interval, s)"),
    (r"gyro_(?P<axis>[A-Za-z0-9]+)_pulses", "gyro", "pulses",
     "gyro_<axis>_pulses (whole pulses per sample)"),
    (r"gyro_(?P<axis>[A-Za-z0-9]+)_rate_deg_per_h", "gyro", "deg_per_h",
     "gyro_<axis>_rate_deg_per_h"),
    (r"gyro_(?P<axis>[A-Za-z0-9]+)_rate_deg_per_s", "gyro", "deg_per_s",
     "gyro_<axis>_rate_deg_per_s"),
    (r"gyro_(?P<axis>[A-Za-z0-9]+)_rate_rad_per_s", "gyro", "rad_per_s",
     "gyro_<axis>_rate_rad_per_s"),
    (r"accel_(?P<axis>[A-Za-z0-9]+)_pulses", "accel", "pulses",
     "accel_<axis>_pulses (whole pulses per sample)"),
    (r"accel_(?P<axis>[A-Za-z0-9]+)_m_per_s2", "accel", "m_per_s2", "accel_<axis>_m_per_s2"),
    (r"probe_(?P<name>.+)_c", "probe", "c", "probe_<name>_c (°C)"),
    (r"chamber_air_c", "chamber", "c", "chamber_air_c (°C)"),
    (r"chamber_setpoint_c", "chamber", "c", "chamber_setpoint_c (°C)"),
    (r"uhfo_v", "uhfo", "v", "uhfo_v (V, single gyro)"),
    (r"uhfo_(?P<axis>[A-Za-z0-9]+)_v", "uhfo", "v", "uhfo_<axis>_v (V)"),
    (r"outer_angle_deg", "angle", "deg", "outer_angle_deg"),
    (r"inner_angle_deg", "angle", "deg", "inner_angle_deg"),
    (r"power_on", "flag", "1", "power_on (0/1)"),
    (r"dropout", "flag", "1", "dropout (0/1: the row's values are missing and may be empty)"),
]
_RULES = [(re.compile(rx + r"\Z"), kind, unit, desc) for rx, kind, unit, desc in COLUMN_RULES]
#: Column kinds that may be recorded at the slower temperature rate (empty cells between).
SLOW_KINDS = ("probe", "chamber", "uhfo", "angle", "flag_power")
_ALLOWED_NAMES = ", ".join(d.split(" (")[0] for _, _, _, d in COLUMN_RULES)
#: Prefixes with a unit the grammar knows; a name with a known prefix and another ending is
#: a unit mistake, reported as such.
_PREFIX_HINTS = [
    (r"time_", "time is in seconds: time_s"),
    (r"gyro_[A-Za-z0-9]+_", "gyro columns are gyro_<axis>_pulses or gyro_<axis>_rate_deg_per_h "
                            "(also _rate_deg_per_s, _rate_rad_per_s)"),
    (r"accel_[A-Za-z0-9]+_", "accelerometer columns are accel_<axis>_pulses or "
                             "accel_<axis>_m_per_s2"),
    (r"probe_", "probe temperatures are in °C: probe_<name>_c"),
    (r"chamber_", "chamber temperatures are in °C: chamber_air_c, chamber_setpoint_c"),
    (r"uhfo", "the UHFO voltage is in volts: uhfo_v or uhfo_<axis>_v"),
    (r"(outer|inner)_", "table angles are in degrees: outer_angle_deg, inner_angle_deg"),
]

_SIDECAR_TABLES = {
    "recording": {"format", "version", "description", "data", "sample_rate_hz",
                  "temperature_rate_hz", "hdf5_group", "ignore_columns", "source"},
    "site": {"latitude_deg", "height_m"},
    "gyro": {"axes", "scale_factor_pulses_per_arcsec"},
    "accelerometer": {"axes", "scale_factor_pulses_per_s_per_g"},
    "orientation": None,            # body axis -> [east, north, up] at table zero
    "noise": None,                  # the device presets' [noise] keys, numbers
    "columns": None,                # file's column name -> standard name
    "probes": None,                 # recorded probe name -> the thermal template's probe
}


# ---------------------------------------------------------------------------- the sidecar

def sidecar_path(data_path: str | os.PathLike) -> pathlib.Path:
    """The sidecar of a table file: same folder, same stem, ``.toml``."""
    p = pathlib.Path(data_path)
    return p.with_suffix(".toml")


def _fail(where: str, what: str) -> UserInputError:
    return UserInputError(f"{where}: {what}")


def _number(table: Mapping, key: str, where: str, default: Any = None, *, lo: float | None = None,
            hi: float | None = None, lo_open: bool = False, required: bool = False) -> Any:
    if key not in table:
        if required:
            raise _fail(f"{where}.{key}", "missing; give a number")
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _fail(f"{where}.{key}", f"value {v!r} not allowed; must be a finite number")
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise _fail(f"{where}.{key}", f"value {v!r} not allowed; must be {'>' if lo_open else '>='}"
                                      f" {lo:g}")
    if hi is not None and v > hi:
        raise _fail(f"{where}.{key}", f"value {v!r} not allowed; must be <= {hi:g}")
    return float(v)


def _axes(table: Mapping, where: str) -> list[str] | None:
    if "axes" not in table:
        return None
    v = table["axes"]
    if (not isinstance(v, list) or not v
            or not all(isinstance(a, str) and re.fullmatch(r"[A-Za-z0-9]+", a) for a in v)
            or len(set(v)) != len(v)):
        raise _fail(f"{where}.axes", f"value {v!r} not allowed; must be a list of distinct axis "
                                     f"names such as [\"x\", \"y\", \"z\"]")
    return list(v)


@dataclass
class Sidecar:
    """The validated sidecar (units in the field names)."""

    path: pathlib.Path
    sample_rate_hz: float
    temperature_rate_hz: float | None = None
    description: str = ""
    data: str | None = None
    hdf5_group: str = "/"
    ignore_columns: list[str] = field(default_factory=list)
    source: str = ""
    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = 0.0
    site_given: bool = False          # the sidecar has [site] latitude_deg (navigation needs it)
    gyro_axes: list[str] | None = None
    accel_axes: list[str] | None = None
    gyro_sf_pulse_per_arcsec: float | None = None
    accel_sf_pulse_per_s_per_g: float | None = None
    orientation: dict[str, np.ndarray] = field(default_factory=dict)
    noise: dict[str, float] = field(default_factory=dict)
    columns: dict[str, str] = field(default_factory=dict)
    #: recorded probe name (``probe_<name>_c``) -> probe of the thermal template (identify)
    probes: dict[str, str] = field(default_factory=dict)


def read_sidecar(path: str | os.PathLike) -> Sidecar:
    """Parse and validate a sidecar file (UserInputError naming file and key)."""
    p = pathlib.Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserInputError(f"{p}: no such sidecar file (a recording needs one beside its "
                             f"table, same name with .toml; docs/recordings.md)") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserInputError(f"{p}: not a valid TOML sidecar ({exc})") from None
    for key, value in data.items():
        if key not in _SIDECAR_TABLES:
            raise _fail(f"{p}: {key}", f"unknown table; allowed: "
                                       f"{', '.join('[' + t + ']' for t in _SIDECAR_TABLES)}")
        if not isinstance(value, dict):
            raise _fail(f"{p}: {key}", f"must be a table [{key}]")
        allowed = _SIDECAR_TABLES[key]
        if allowed is not None:
            for k in value:
                if k not in allowed:
                    raise _fail(f"{p}: {key}.{k}", f"unknown key; allowed: "
                                                   f"{', '.join(sorted(allowed))}")
    rec = data.get("recording")
    if rec is None:
        raise _fail(f"{p}", "no [recording] table; a sidecar needs at least [recording] "
                            "sample_rate_hz (docs/recordings.md)")
    w = f"{p}: recording"
    fmt = rec.get("format", RECORDING_FORMAT)
    if fmt != RECORDING_FORMAT:
        raise _fail(f"{w}.format", f"value {fmt!r} not allowed; must be {RECORDING_FORMAT!r}")
    version = rec.get("version", RECORDING_VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise _fail(f"{w}.version", f"value {version!r} not allowed; must be a whole number >= 1")
    if version > RECORDING_VERSION:
        raise _fail(f"{w}.version", f"value {version} is newer than this rlgsim reads "
                                    f"({RECORDING_VERSION}); upgrade rlgsim")
    sc = Sidecar(path=p, sample_rate_hz=_number(rec, "sample_rate_hz", w, lo=0, lo_open=True,
                                                 required=True))
    sc.temperature_rate_hz = _number(rec, "temperature_rate_hz", w, lo=0, lo_open=True,
                                     hi=sc.sample_rate_hz)
    for key in ("description", "data", "hdf5_group", "source"):
        if key in rec:
            if not isinstance(rec[key], str):
                raise _fail(f"{w}.{key}", f"value {rec[key]!r} not allowed; must be a string")
            setattr(sc, key, rec[key])
    ign = rec.get("ignore_columns", [])
    if not isinstance(ign, list) or not all(isinstance(c, str) for c in ign):
        raise _fail(f"{w}.ignore_columns", f"value {ign!r} not allowed; must be a list of "
                                           f"column names")
    sc.ignore_columns = list(ign)
    site = data.get("site", {})
    sc.latitude_deg = _number(site, "latitude_deg", f"{p}: site", DEFAULT_LATITUDE_DEG, lo=-90,
                              hi=90)
    sc.height_m = _number(site, "height_m", f"{p}: site", 0.0, lo=-1000, hi=1e5)
    sc.site_given = isinstance(site, Mapping) and "latitude_deg" in site
    gyro = data.get("gyro", {})
    sc.gyro_axes = _axes(gyro, f"{p}: gyro")
    sc.gyro_sf_pulse_per_arcsec = _number(gyro, "scale_factor_pulses_per_arcsec", f"{p}: gyro",
                                          lo=0, lo_open=True)
    acc = data.get("accelerometer", {})
    sc.accel_axes = _axes(acc, f"{p}: accelerometer")
    sc.accel_sf_pulse_per_s_per_g = _number(acc, "scale_factor_pulses_per_s_per_g",
                                            f"{p}: accelerometer", lo=0, lo_open=True)
    for axis, vec in data.get("orientation", {}).items():
        a = np.asarray(vec, dtype=float) if isinstance(vec, list) and len(vec) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in vec) else None
        if a is None or abs(np.linalg.norm(a) - 1) > 1e-6:
            raise _fail(f"{p}: orientation.{axis}", f"value {vec!r} not allowed; must be a unit "
                                                    f"vector [east, north, up]")
        sc.orientation[axis] = a
    for key, v in data.get("noise", {}).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
            raise _fail(f"{p}: noise.{key}", f"value {v!r} not allowed; must be a number >= 0")
        sc.noise[key] = float(v)
    for src, dst in data.get("columns", {}).items():
        if not isinstance(dst, str) or _rule(dst) is None:
            raise _fail(f"{p}: columns.{src}", f"value {dst!r} not allowed; must be a standard "
                                               f"column name ({_ALLOWED_NAMES})")
        sc.columns[src] = dst
    for src, dst in data.get("probes", {}).items():
        if not isinstance(dst, str) or not dst:
            raise _fail(f"{p}: probes.{src}", f"value {dst!r} not allowed; must be the name of "
                                              f"a probe of the thermal template (a string)")
        sc.probes[src] = dst
    return sc


# ---------------------------------------------------------------------------- the columns

def _rule(name: str) -> tuple[str, str, dict] | None:
    for rx, kind, unit, _ in _RULES:
        m = rx.match(name)
        if m:
            return kind, unit, m.groupdict()
    return None


def _unknown_column(name: str) -> str:
    for rx, hint in _PREFIX_HINTS:
        if re.match(rx, name):
            return f"unit or name not allowed; {hint}"
    return f"unknown column; allowed: {_ALLOWED_NAMES} (or list it in [recording] ignore_columns)"


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
                v = _rate_rad_per_s(v, unit) * k * dt
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
            rad = v / (self._need_sf("gyro") * dt) if unit == "pulses" else _rate_rad_per_s(v, unit)
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
        return self.slow_rows is not None and _is_slow_kind(name, self.kinds[name][0])

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
        if self.slow_rows is not None:
            lines.append(f"  temperature rate: {sc.temperature_rate_hz:g} Hz "
                         f"({self.slow_rows.size} readings)")
        n_drop = int(self.dropout.sum())
        lines.append(f"  dropouts: {n_drop} sample(s)"
                     + (f" ({n_drop / f:.6g} s)" if n_drop else ""))
        lines.append(f"  site: latitude {sc.latitude_deg:g} deg, height {sc.height_m:g} m")
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


def _rate_rad_per_s(v: np.ndarray, unit: str) -> np.ndarray:
    return {"deg_per_h": DEG / HOUR, "deg_per_s": DEG, "rad_per_s": 1.0}[unit] * v


def _is_slow_kind(name: str, kind: str) -> bool:
    return kind in ("probe", "chamber", "uhfo", "angle") or name == "power_on"


# ---------------------------------------------------------------------------- reading

def is_recording(path: str | os.PathLike) -> bool:
    """True when ``path`` is a table file with a sidecar beside it, or a sidecar naming one —
    what commands check before treating an argument as a recording rather than a dataset."""
    p = pathlib.Path(path)
    if p.suffix.lower() == ".toml":
        return _is_sidecar(p)
    if DATA_SUFFIXES.get(p.suffix.lower()) in ("csv", "parquet"):
        return True
    if p.suffix.lower() in TABLE_FORMATS["hdf5"].suffixes:
        # an HDF5 table of another tool, with a sidecar made for it (not the sidecar of a
        # CSV export of this dataset, which shares the stem)
        side = sidecar_path(p)
        if not _is_sidecar(side):
            return False
        try:
            data = tomllib.loads(side.read_text(encoding="utf-8"))["recording"].get("data")
        except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError, AttributeError):
            return False
        return data is None or pathlib.Path(str(data)).name == p.name
    return False


def _is_sidecar(path: pathlib.Path) -> bool:
    """True when ``path`` is a TOML file with a ``[recording]`` table (not, say, the scenario
    that shares a dataset's stem)."""
    try:
        return "recording" in tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return False


def _resolve(path: str | os.PathLike) -> tuple[pathlib.Path, Sidecar]:
    p = pathlib.Path(path)
    if p.suffix.lower() == ".toml":
        sc = read_sidecar(p)
        if not sc.data:
            raise UserInputError(f"{p}: recording.data missing; a sidecar given on its own must "
                                 f"name its table file (data = \"run1.csv\")")
        data = (p.parent / sc.data)
        if not data.is_file():
            raise UserInputError(f"{p}: recording.data: {data} no such file")
        return data, sc
    if not p.exists():
        raise UserInputError(f"{p}: no such file")
    if p.is_dir():
        raise UserInputError(f"{p}: is a directory, not a recording")
    if p.suffix.lower() not in DATA_SUFFIXES:
        raise UserInputError(f"{p}: not a recording; allowed table files: "
                             f"{', '.join(DATA_SUFFIXES)} with a .toml sidecar")
    side = sidecar_path(p)
    if not side.is_file():
        raise UserInputError(f"{p}: no sidecar {side.name} beside it; a recording needs one "
                             f"(at least [recording] sample_rate_hz; docs/recordings.md)")
    return p, read_sidecar(side)


def _read_table(path: pathlib.Path, kind: str, sc: Sidecar) -> tuple[list[str], dict, int]:
    """Raw columns: names in file order, name -> (values as float64, raw text-or-None), rows.
    Non-numeric cells are reported by the caller using the raw values."""
    if kind == "csv":
        import pandas as pd
        try:                 # numbers parsed by pandas' C reader; only empty cells are NaN
            df = pd.read_csv(path, keep_default_na=False, na_values=[""],
                             skipinitialspace=True, low_memory=False)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
            msg = " ".join(str(exc).split())
            raise UserInputError(f"{path}: not a readable CSV table ({msg})") from None
        names = [str(c).strip() for c in df.columns]
        raw = {n: df.iloc[:, i].to_numpy() for i, n in enumerate(names)}
        return names, raw, len(df)
    if kind == "parquet":
        import pandas as pd
        try:
            df = pd.read_parquet(path)
        except Exception as exc:   # noqa: BLE001 - pyarrow raises many types for a bad file
            msg = " ".join(str(exc).split())
            raise UserInputError(f"{path}: not a readable Parquet table ({msg})") from None
        names = [str(c) for c in df.columns]
        return names, {n: df.iloc[:, i].to_numpy() for i, n in enumerate(names)}, len(df)
    import h5py
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise UserInputError(f"{path}: not an HDF5 file") from None
    with f:
        g = f[sc.hdf5_group] if sc.hdf5_group in f else None
        if not isinstance(g, h5py.Group):
            raise UserInputError(f"{sc.path}: recording.hdf5_group: value {sc.hdf5_group!r} is "
                                 f"not a group of {path}")
        names = [n for n, d in g.items() if isinstance(d, h5py.Dataset) and d.ndim == 1]
        if not names:
            raise UserInputError(f"{path}: group {sc.hdf5_group} holds no 1-D datasets (one per "
                                 f"column)")
        raw = {n: g[n][()] for n in names}
    lengths = {len(v) for v in raw.values()}
    if len(lengths) != 1:
        raise UserInputError(f"{path}: the 1-D datasets of {sc.hdf5_group} differ in length "
                             f"({sorted(lengths)}); each column must have one value per row")
    return names, raw, lengths.pop()


def _numeric(path: pathlib.Path, name: str, raw: np.ndarray) -> np.ndarray:
    """float64 values; empty cells → NaN; anything else non-numeric is an error."""
    if raw.dtype.kind in "fiub":
        out = raw.astype(np.float64)
    else:
        import pandas as pd
        text = pd.Series(raw, dtype=object).map(
            lambda c: c.decode() if isinstance(c, bytes) else c).astype("string").str.strip()
        empty = text.isna() | (text == "")
        out = pd.to_numeric(text.mask(empty), errors="coerce").to_numpy(dtype=np.float64,
                                                                        na_value=np.nan)
        named_nan = text.str.lower().isin(["nan", "+nan", "-nan"]).to_numpy(dtype=bool,
                                                                           na_value=False)
        bad = np.flatnonzero(np.isnan(out) & ~empty.to_numpy(dtype=bool) & ~named_nan)
        if bad.size:
            i = int(bad[0])
            raise UserInputError(f"{path}: column {name!r}, row {i + 1}: value {str(text[i])!r} "
                                 f"not allowed; must be a number (an empty cell marks a missing "
                                 f"value)")
    inf = np.flatnonzero(np.isinf(out))
    if inf.size:
        i = int(inf[0])
        raise UserInputError(f"{path}: column {name!r}, row {i + 1}: value {float(out[i])!r} not "
                             f"allowed; must be finite")
    return out


def load_recording(path: str | os.PathLike) -> Recording:
    """Read and validate a recording: a table file (``.csv``, ``.parquet``, ``.h5``) with its
    sidecar, or a sidecar whose ``[recording] data`` names the table. Raises
    :class:`UserInputError` (one line: file, column, row, what is allowed) for anything the
    format does not allow (docs/recordings.md)."""
    data_path, sc = _resolve(path)
    kind = DATA_SUFFIXES.get(data_path.suffix.lower())
    if kind is None:
        raise UserInputError(f"{sc.path}: recording.data: {data_path.name} not allowed; table "
                             f"files are {', '.join(DATA_SUFFIXES)}")
    names, raw, n = _read_table(data_path, kind, sc)
    for src in sc.columns:
        if src not in names:
            raise UserInputError(f"{sc.path}: columns.{src}: the table has no column {src!r}")
    kinds: dict[str, tuple[str, str, dict]] = {}
    values: dict[str, np.ndarray] = {}
    for name in names:
        if name in sc.ignore_columns:
            continue
        std = sc.columns.get(name, name)
        rule = _rule(std)
        if rule is None:
            raise UserInputError(f"{data_path}: column {name!r}: {_unknown_column(std)}")
        if std in kinds:
            raise UserInputError(f"{data_path}: column {name!r}: a second column {std!r}; each "
                                 f"standard column may appear once")
        kinds[std] = rule
        values[std] = _numeric(data_path, name, np.asarray(raw[name]))
    shown = {sc.columns.get(c, c): c for c in names}        # standard -> name in the file

    def where(std: str, row: int | None = None) -> str:
        col = shown.get(std, std)
        return f"{data_path}: column {col!r}" + (f", row {row + 1}" if row is not None else "")

    if "time_s" not in values:
        raise UserInputError(f"{data_path}: column 'time_s' missing; every recording needs the "
                             f"time of each sample in seconds (or map the file's time column "
                             f"in the sidecar's [columns])")
    if n < 2:
        raise UserInputError(f"{data_path}: {n} row(s); a recording needs at least 2 samples")
    # axes declared in the sidecar must match the columns
    for kind_, declared, table in (("gyro", sc.gyro_axes, "gyro"),
                                   ("accel", sc.accel_axes, "accelerometer")):
        found = {}
        for std, (k, unit, g) in kinds.items():
            if k == kind_:
                if g["axis"] in found:
                    raise UserInputError(f"{where(std)}: axis {g['axis']} already given by "
                                         f"{found[g['axis']]!r}; one column per axis")
                found[g["axis"]] = std
                if declared is not None and g["axis"] not in declared:
                    raise UserInputError(f"{where(std)}: axis {g['axis']!r} not allowed; the "
                                         f"sidecar's [{table}] axes are {declared}")
        for a in declared or []:
            if a not in found:
                raise UserInputError(f"{data_path}: column '{kind_}_{a}_pulses' (or a rate "
                                     f"column) missing: the sidecar's [{table}] axes list {a!r}")
    gyro_axes = [g["axis"] for k, _, g in kinds.values() if k == "gyro"]
    for std, (k, _, g) in kinds.items():
        if k == "uhfo" and g.get("axis") is None and len(gyro_axes) > 1:
            raise UserInputError(f"{where(std)}: uhfo_v is for a single gyro; with gyro axes "
                                 f"{gyro_axes} name one column per axis: uhfo_<axis>_v")
        if k == "uhfo" and g.get("axis") is not None and gyro_axes \
                and g["axis"] not in gyro_axes:
            raise UserInputError(f"{where(std)}: axis {g['axis']!r} not allowed; the UHFO "
                                 f"columns belong to the gyro axes {gyro_axes}")
    if sum(1 for k, _, _ in kinds.values() if k == "uhfo") > 1 and any(
            k == "uhfo" and g.get("axis") is None for k, _, g in kinds.values()):
        raise UserInputError(f"{data_path}: uhfo_v and uhfo_<axis>_v together; give one "
                             f"column per gyro axis (uhfo_<axis>_v)")
    # dropouts
    dropout = np.zeros(n, dtype=bool)
    if "dropout" in values:
        d = values.pop("dropout")
        bad = np.flatnonzero(~np.isin(d, (0.0, 1.0)))
        if bad.size:
            raise UserInputError(f"{where('dropout', int(bad[0]))}: value {float(d[bad[0]])!r} not "
                                 f"allowed; must be 0 or 1")
        dropout = d == 1.0
        kinds.pop("dropout")
    # time
    t = values.pop("time_s")
    kinds.pop("time_s")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise UserInputError(f"{where('time_s', int(bad[0]))}: empty or NaN time not allowed; "
                             f"every row needs its time, also a dropout row")
    dt = 1.0 / sc.sample_rate_hz
    step = np.diff(t)
    back = np.flatnonzero(step <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise UserInputError(f"{where('time_s', i)}: time {float(t[i])!r} s after "
                             f"{float(t[i - 1])!r} s; time "
                             f"must increase strictly from row to row")
    off = np.flatnonzero(np.abs(step - dt) > 1e-3 * dt + 1e-9 * np.abs(t[1:]))
    if off.size:
        i = int(off[0]) + 1
        gap = step[i - 1]
        what = (f"a gap of {gap:.6g} s ({gap / dt - 1:.4g} missing sample(s)); record a dropout "
                f"as rows with dropout = 1 (their values may be empty), not by leaving rows out"
                if gap > 1.5 * dt else
                f"a step of {gap:.6g} s; the sidecar's sample_rate_hz = {sc.sample_rate_hz:g} "
                f"needs {dt:.6g} s between rows")
        raise UserInputError(f"{where('time_s', i)}: {what}")
    # slow columns
    slow_rows = None
    slow_names = [s for s, (k, _, _) in kinds.items() if _is_slow_kind(s, k)]
    if sc.temperature_rate_hz is not None and slow_names:
        slow_rows = _slow_grid(values, slow_names, dropout, t, sc, where)
    # values
    for std, (k, unit, g) in kinds.items():
        v = values[std]
        rows = slow_rows if (slow_rows is not None and std in slow_names) else None
        if rows is not None:
            outside = np.ones(n, dtype=bool)
            outside[rows] = False
            extra = np.flatnonzero(outside & np.isfinite(v))
            if extra.size:
                i = int(extra[0])
                raise UserInputError(f"{where(std, i)}: a value between the temperature-rate "
                                     f"readings (every {1 / sc.temperature_rate_hz:g} s); leave "
                                     f"those cells empty")
            check = np.zeros(n, dtype=bool)
            check[rows] = True
        else:
            check = np.ones(n, dtype=bool)
        nan = np.flatnonzero(check & ~np.isfinite(v) & ~dropout)
        if nan.size:
            i = int(nan[0])
            raise UserInputError(f"{where(std, i)}: empty or NaN value not allowed; mark a "
                                 f"missing reading with dropout = 1 in that row")
        _check_range(std, k, unit, v, check & np.isfinite(v), where, sc)
    return Recording(path=data_path, sidecar=sc, kind=kind, time_s=t, columns=values,
                     dropout=dropout, slow_rows=slow_rows, kinds=kinds)


def _slow_grid(values, slow_names, dropout, t, sc, where) -> np.ndarray:
    """Rows of the temperature-rate grid: the rows where the first slow column has a value (or
    the row is a dropout on that grid); every slow column must use the same rows, evenly spaced
    at 1/temperature_rate_hz."""
    ref = slow_names[0]
    rows = np.flatnonzero(np.isfinite(values[ref]))
    if rows.size < 1:
        raise UserInputError(f"{where(ref)}: no value at all")
    period = 1.0 / sc.temperature_rate_hz
    ratio = period * sc.sample_rate_hz
    r = int(round(ratio))
    if r < 1 or abs(ratio - r) > 1e-6:
        raise UserInputError(f"{sc.path}: recording.temperature_rate_hz: value "
                             f"{sc.temperature_rate_hz!r} not allowed; sample_rate_hz / "
                             f"temperature_rate_hz must be a whole number")
    first = int(rows[0]) % r
    grid = np.arange(first, t.size, r)
    for name in slow_names:
        v = values[name]
        missing = np.flatnonzero(~np.isfinite(v[grid]) & ~dropout[grid])
        if missing.size:
            i = int(grid[missing[0]])
            raise UserInputError(f"{where(name, i)}: empty or NaN value not allowed on the "
                                 f"temperature-rate grid (every {period:g} s from row "
                                 f"{first + 1}); mark a missing reading with dropout = 1")
    return grid


def _check_range(std, kind, unit, v, mask, where, sc) -> None:
    x = v[mask]
    if not x.size:
        return
    rows = np.flatnonzero(mask)

    def fail(bad_idx, allowed):
        i = int(rows[bad_idx])
        raise UserInputError(f"{where(std, i)}: value {float(v[i])!r} not allowed; {allowed}")
    if kind in ("probe", "chamber"):
        lo, hi = TEMPERATURE_RANGE_C
        bad = np.flatnonzero((x < lo) | (x > hi))
        if bad.size:
            fail(bad[0], f"temperatures are in °C between {lo:g} and {hi:g} (a Kelvin or °F "
                         f"column would be out of range)")
    elif kind == "uhfo":
        lo, hi = UHFO_RANGE_V
        bad = np.flatnonzero((x < lo) | (x > hi))
        if bad.size:
            fail(bad[0], f"the UHFO voltage is in V between {lo:g} and {hi:g}")
    elif kind == "angle":
        bad = np.flatnonzero((x < -360) | (x > 720))
        if bad.size:
            fail(bad[0], "table angles are in degrees between -360 and 720")
    elif kind == "flag":
        bad = np.flatnonzero(~np.isin(x, (0.0, 1.0)))
        if bad.size:
            fail(bad[0], "must be 0 or 1")
    elif kind in ("gyro", "accel") and unit == "pulses":
        bad = np.flatnonzero(x != np.round(x))
        if bad.size:
            fail(bad[0], f"pulses are whole counts per sample; a rate goes in a "
                         f"{kind}_<axis>_rate_... column" if kind == "gyro" else
                 "pulses are whole counts per sample")
        f = sc.sample_rate_hz
        if kind == "gyro" and sc.gyro_sf_pulse_per_arcsec:
            limit = GYRO_RATE_LIMIT_DEG_PER_S * 3600 * sc.gyro_sf_pulse_per_arcsec / f
            bad = np.flatnonzero(np.abs(x) > limit)
            if bad.size:
                fail(bad[0], f"more than {limit:.6g} pulses per sample is over "
                             f"{GYRO_RATE_LIMIT_DEG_PER_S:g} deg/s at the nominal scale factor")
    elif kind == "gyro":
        limit = GYRO_RATE_LIMIT_DEG_PER_S * DEG
        bad = np.flatnonzero(np.abs(_rate_rad_per_s(x, unit)) > limit)
        if bad.size:
            fail(bad[0], f"a rate above {GYRO_RATE_LIMIT_DEG_PER_S:g} deg/s; check the unit "
                         f"in the column name")
    elif kind == "accel":
        bad = np.flatnonzero(np.abs(x) > ACCEL_LIMIT_M_PER_S2)
        if bad.size:
            fail(bad[0], f"specific force is in m/s² below {ACCEL_LIMIT_M_PER_S2:g}")


# ---------------------------------------------------------------------------- writing

def write_sidecar(path: str | os.PathLike, tables: Mapping[str, Mapping[str, Any]],
                  comment: str = "") -> pathlib.Path:
    """Write a sidecar: ``tables`` maps table name to ``{key: value}`` (scalars, lists)."""
    p = pathlib.Path(path)
    text = dumps({name: dict(table) for name, table in tables.items() if table}, header=comment)
    tomllib.loads(text)                  # never write a sidecar that does not read back
    tmp = p.with_name(f".{p.name}.tmp-{os.getpid()}")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, p)
    return p


def write_table(path: str | os.PathLike, blocks, fmt: str) -> pathlib.Path:
    """Write the table from an iterable of pandas DataFrames (same columns) as CSV or Parquet,
    block by block (memory bounded by one block), to a temporary name renamed on success.
    Floats are written with full precision, so a CSV reads back to identical float64."""
    p = pathlib.Path(path)
    tmp = p.with_name(f".{p.name}.tmp-{os.getpid()}")
    writer = None
    try:
        if fmt == "csv":
            with open(tmp, "w", newline="") as fh:
                first = True
                for df in blocks:
                    df.to_csv(fh, index=False, header=first, na_rep="", float_format=None,
                              lineterminator="\n")
                    first = False
        elif fmt == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq
            for df in blocks:
                table = pa.Table.from_pandas(df, preserve_index=False)
                if writer is None:
                    writer = pq.ParquetWriter(tmp, table.schema)
                writer.write_table(table)
            if writer is not None:
                writer.close()
                writer = None
        else:
            raise ValueError(f"unknown table format {fmt!r}")
        os.replace(tmp, p)
    finally:
        if writer is not None:
            writer.close()
        if tmp.exists():
            tmp.unlink()
    return p
