"""The column grammar of a recording (docs/recordings.md): every column name carries its unit,
like the scenario keys — ``time_s``, ``gyro_<axis>_pulses`` or ``gyro_<axis>_rate_deg_per_h``,
``accel_<axis>_pulses`` or ``accel_<axis>_m_per_s2``, ``probe_<name>_c``, ``chamber_air_c``,
``chamber_setpoint_c``, ``uhfo_v`` / ``uhfo_<axis>_v``, ``outer_angle_deg``,
``inner_angle_deg``, ``power_on``, ``dropout`` (:data:`COLUMN_RULES`) — and the checks of one
column's values: numbers (empty cells are missing values), finite, in the range its unit allows.

Part of :mod:`rlgsim.ground.recording`; nothing here imports ``rlgsim.sim``.
"""

from __future__ import annotations

import pathlib
import re

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import DEG, G0, HOUR

__all__ = ["COLUMN_RULES", "SLOW_KINDS", "TEMPERATURE_RANGE_C", "UHFO_RANGE_V",
           "GYRO_RATE_LIMIT_DEG_PER_S", "ACCEL_LIMIT_M_PER_S2", "ALLOWED_NAMES", "column_rule",
           "unknown_column", "rate_rad_per_s", "is_slow_kind", "numeric_column", "time_column",
           "check_range", "need_pyarrow"]

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
ALLOWED_NAMES = ", ".join(d.split(" (")[0] for _, _, _, d in COLUMN_RULES)
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


def column_rule(name: str) -> tuple[str, str, dict] | None:
    for rx, kind, unit, _ in _RULES:
        m = rx.match(name)
        if m:
            return kind, unit, m.groupdict()
    return None


def unknown_column(name: str) -> str:
    for rx, hint in _PREFIX_HINTS:
        if re.match(rx, name):
            return f"unit or name not allowed; {hint}"
    return f"unknown column; allowed: {ALLOWED_NAMES} (or list it in [recording] ignore_columns)"


def rate_rad_per_s(v: np.ndarray, unit: str) -> np.ndarray:
    return {"deg_per_h": DEG / HOUR, "deg_per_s": DEG, "rad_per_s": 1.0}[unit] * v


def is_slow_kind(name: str, kind: str) -> bool:
    return kind in ("probe", "chamber", "uhfo", "angle") or name == "power_on"


def numeric_column(path: pathlib.Path, name: str, raw: np.ndarray,
                   table: str = "csv") -> np.ndarray:
    """float64 values; empty cells → NaN; anything else non-numeric is an error. A ``table``
    other than ``csv`` (Parquet, HDF5) carries typed columns: text there is refused whole."""
    if raw.dtype.kind in "fiub":
        out = raw.astype(np.float64)
    elif table != "csv":
        first = next((c for c in raw if c is not None and c == c), None)
        raise UserInputError(f"{path}: column {name!r}: holds text (such as {first!r}); "
                             f"{_TABLE_NAMES.get(table, table)} columns must be numbers (floats or integers, null = "
                             f"missing)")
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
            value = str(text[i])
            hint = (" (a decimal comma: give [recording] decimal = \",\" in the sidecar)"
                    if re.fullmatch(r"[-+]?\d+,\d*([eE][-+]?\d+)?", value) else "")
            raise UserInputError(f"{path}: column {name!r}, row {i + 1}: value {value!r} not "
                                 f"allowed; must be a number (an empty cell marks a missing "
                                 f"value){hint}")
    inf = np.flatnonzero(np.isinf(out))
    if inf.size:
        i = int(inf[0])
        raise UserInputError(f"{path}: column {name!r}, row {i + 1}: value {float(out[i])!r} not "
                             f"allowed; must be finite")
    return out


_TABLE_NAMES = {"parquet": "Parquet", "hdf5": "HDF5"}


def need_pyarrow(path: pathlib.Path, doing: str) -> None:
    """pyarrow is an optional dependency (only Parquet needs it, ~170 MB): its absence is one
    line saying how to install it."""
    try:
        import pyarrow  # noqa: F401 - only whether it imports
    except ImportError:
        raise UserInputError(f"{path}: {doing} Parquet needs pyarrow, which is not installed; "
                             f"pip install \"rlgsim[parquet]\" (or use CSV)") from None


def time_column(path: pathlib.Path, name: str, raw: np.ndarray, table: str,
                rate_hz: float) -> tuple[np.ndarray, str | None]:
    """The time axis ``time_s`` [s] and its origin: seconds as numbers (origin None), or
    timestamps — a Parquet/HDF5 timestamp column, or ISO 8601 text in a CSV
    (``2026-03-01T12:00:00.010``) — taken as the end of each sample interval and counted from
    one sample before the first (so ``time_s[0] = 1/f`` as in a simulated run); the origin
    (that instant, ISO 8601) is returned. Time zones are converted to UTC."""
    import datetime
    first = next((c for c in raw if c is not None and c == c), None) \
        if raw.dtype.kind == "O" and raw.size else None
    if raw.dtype.kind == "M" or isinstance(first, datetime.datetime):   # typed (zoned) stamps
        import pandas as pd
        stamps = pd.DatetimeIndex(pd.to_datetime(raw, utc=isinstance(first, datetime.datetime)))
    elif raw.dtype.kind in "fiub" or table != "csv":
        return numeric_column(path, name, raw, table), None
    else:
        import pandas as pd
        text = pd.Series(raw, dtype=object).map(
            lambda c: c.decode() if isinstance(c, bytes) else c).astype("string").str.strip()
        first = str(text.iloc[0]) if len(text) else ""
        if not re.fullmatch(r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d.*", first):
            return numeric_column(path, name, raw, table), None
        try:
            stamps = pd.DatetimeIndex(pd.to_datetime(text, format="ISO8601", utc=True))
        except (ValueError, TypeError):
            parsed = [_iso_or_none(x) for x in text]
            i = next(k for k, x in enumerate(parsed) if x is None)
            raise UserInputError(f"{path}: column {name!r}, row {i + 1}: value "
                                 f"{str(text.iloc[i])!r} not allowed; the time column holds ISO "
                                 f"8601 timestamps (2026-03-01T12:00:00.010), so every row "
                                 f"needs one") from None
    if stamps.isna().any():
        i = int(np.flatnonzero(stamps.isna())[0])
        raise UserInputError(f"{path}: column {name!r}, row {i + 1}: empty time not allowed; "
                             f"every row needs its time, also a dropout row")
    if stamps.tz is not None:
        stamps = stamps.tz_convert("UTC").tz_localize(None)
    ns = stamps.as_unit("ns").asi8.astype(np.int64)
    dt_ns = int(round(1e9 / rate_hz))
    start = ns[0] - dt_ns
    t = (ns - start).astype(np.float64) / 1e9
    origin = pd.Timestamp(start).isoformat()
    return t, origin


def _iso_or_none(text):
    import pandas as pd
    try:
        return pd.Timestamp(str(text))
    except (ValueError, TypeError):
        return None


def check_range(std, kind, unit, v, mask, where, sc) -> None:
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
        if kind == "accel" and sc.accel_sf_pulse_per_s_per_g:
            limit = ACCEL_LIMIT_M_PER_S2 / G0 * sc.accel_sf_pulse_per_s_per_g / f
            bad = np.flatnonzero(np.abs(x) > limit)
            if bad.size:
                fail(bad[0], f"more than {limit:.6g} pulses per sample is over "
                             f"{ACCEL_LIMIT_M_PER_S2 / G0:g} g at the nominal scale factor")
    elif kind == "gyro":
        limit = GYRO_RATE_LIMIT_DEG_PER_S * DEG
        bad = np.flatnonzero(np.abs(rate_rad_per_s(x, unit)) > limit)
        if bad.size:
            fail(bad[0], f"a rate above {GYRO_RATE_LIMIT_DEG_PER_S:g} deg/s; check the unit "
                         f"in the column name")
    elif kind == "accel":
        bad = np.flatnonzero(np.abs(x) > ACCEL_LIMIT_M_PER_S2)
        if bad.size:
            fail(bad[0], f"specific force is in m/s² below {ACCEL_LIMIT_M_PER_S2:g}")

