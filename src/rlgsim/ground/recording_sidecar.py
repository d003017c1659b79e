"""The sidecar of a recording (docs/recordings.md): the small TOML file beside the table
(``run1.csv`` → ``run1.toml``) that says what the table cannot — the sample rate, the site, the
sensor axes and their orientation, the nominal scale factors, optionally the noise levels and
a mapping from the file's own column names to the standard ones. :func:`read_sidecar`
validates every key in one line naming the file and key.

Part of :mod:`rlgsim.ground.recording`; nothing here imports ``rlgsim.sim``.
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
from rlgsim.ground.recording_columns import ALLOWED_NAMES, column_rule

__all__ = ["RECORDING_FORMAT", "RECORDING_VERSION", "DELIMITERS", "Sidecar", "read_sidecar",
           "sidecar_path"]

#: CSV field separators a sidecar may name in ``[recording] delimiter``.
DELIMITERS = (",", ";", "\t", "|")

#: ``[recording] format`` of a sidecar (optional in a hand-written one; written by the exporter).
RECORDING_FORMAT = "rlgsim recording"
#: ``[recording] version``; readers refuse newer versions.
RECORDING_VERSION = 1

#: How far from 1 the norm of an ``[orientation]`` vector may be: direction cosines written
#: to 4 decimals ([0.7071, 0.7071, 0]: norm 0.99998) are taken and normalised; a mistyped
#: cosine is off by far more.
UNIT_TOL = 1e-3

#: ``[recording] platform``: what carried the IMU (``vehicle``: an export of a drive)
PLATFORMS = ("fixed", "vehicle")

_SIDECAR_TABLES = {
    "recording": {"format", "version", "description", "data", "sample_rate_hz",
                  "temperature_rate_hz", "hdf5_group", "ignore_columns", "source",
                  "delimiter", "decimal", "platform", "trajectory"},
    "site": {"latitude_deg", "height_m"},
    "gyro": {"axes", "scale_factor_pulses_per_arcsec"},
    "accelerometer": {"axes", "scale_factor_pulses_per_s_per_g"},
    "orientation": None,            # body axis -> [east, north, up] at table zero
    "noise": None,                  # the device presets' [noise] keys, numbers
    "columns": None,                # file's column name -> standard name
    "probes": None,                 # recorded probe name -> the thermal template's probe
    "identify": {"device_template", "thermal_template", "gyro"},   # rlgsim identify's choices
}



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
    delimiter: str | None = None          # CSV field separator; None: found from the header
    decimal: str = "."                    # CSV decimal mark
    ignore_columns: list[str] = field(default_factory=list)
    source: str = ""
    #: ``fixed`` (a site, a turntable: every reader) or ``vehicle`` (an export of a drive; the
    #: trajectory truth in the table ``trajectory`` names): see :func:`need_fixed_site`
    platform: str = "fixed"
    trajectory: str | None = None
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
    #: ``[identify]``: device_template / thermal_template (preset name or path, relative to the
    #: sidecar's folder when it names a file there) and gyro (the axis to identify)
    identify: dict[str, str] = field(default_factory=dict)


def need_fixed_site(sc: Sidecar, what: str,
                    advice: str = "give the dataset itself (its truth holds the motion)"
                    ) -> None:
    """Refuse (one line naming the key) a recording whose IMU moved with a vehicle for
    ``what``, a reader that takes the recording's site and orientation as the IMU's motion;
    ``advice`` is the caller's (what to do instead: identify and calibrate read the vehicle
    dataset itself, navigate does not)."""
    if sc.platform != "fixed":
        raise UserInputError(f"{sc.path}: recording.platform = {sc.platform!r}: {what} takes "
                             f"the IMU at a fixed site, so the drive's rotation would read as "
                             f"gyro bias — {advice}")


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
    sc.platform = rec.get("platform", "fixed")
    if sc.platform not in PLATFORMS:
        raise _fail(f"{w}.platform", f"value {sc.platform!r} not allowed; one of "
                                     f"{', '.join(map(repr, PLATFORMS))}")
    for key in ("description", "data", "hdf5_group", "source", "trajectory"):
        if key in rec:
            if not isinstance(rec[key], str):
                raise _fail(f"{w}.{key}", f"value {rec[key]!r} not allowed; must be a string")
            setattr(sc, key, rec[key])
    if "delimiter" in rec:
        if rec["delimiter"] not in DELIMITERS:
            raise _fail(f"{w}.delimiter", f"value {rec['delimiter']!r} not allowed; must be one "
                                          f"of {', '.join(map(repr, DELIMITERS))}")
        sc.delimiter = rec["delimiter"]
    if "decimal" in rec:
        if rec["decimal"] not in (".", ",") or rec["decimal"] == sc.delimiter:
            raise _fail(f"{w}.decimal", f"value {rec['decimal']!r} not allowed; must be \".\" "
                                        f"or \",\" (and not the delimiter)")
        sc.decimal = rec["decimal"]
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
    _orientation(data, p, sc)
    for key, v in data.get("noise", {}).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
            raise _fail(f"{p}: noise.{key}", f"value {v!r} not allowed; must be a number >= 0")
        sc.noise[key] = float(v)
    for src, dst in data.get("columns", {}).items():
        if not isinstance(dst, str) or column_rule(dst) is None:
            raise _fail(f"{p}: columns.{src}", f"value {dst!r} not allowed; must be a standard "
                                               f"column name ({ALLOWED_NAMES})")
        sc.columns[src] = dst
    _identify_tables(data, p, sc)
    return sc


def _orientation(data: Mapping, p: pathlib.Path, sc: Sidecar) -> None:
    """``[orientation]``: each body axis's unit vector [east, north, up], its norm 1 to
    :data:`UNIT_TOL` (then normalised), of one of the sidecar's axes or x, y, z."""
    for axis, vec in data.get("orientation", {}).items():
        a = np.asarray(vec, dtype=float) if isinstance(vec, list) and len(vec) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in vec) else None
        if a is None or not abs(np.linalg.norm(a) - 1) <= UNIT_TOL:    # NaN fails too
            raise _fail(f"{p}: orientation.{axis}", f"value {vec!r} not allowed; must be a unit "
                                                    f"vector [east, north, up] (norm 1 to "
                                                    f"{UNIT_TOL:g})")
        named = [*(sc.gyro_axes or []), *(sc.accel_axes or [])]     # axes are optional
        if named and axis not in named and axis not in ("x", "y", "z"):  # a whole mount table
            raise _fail(f"{p}: orientation.{axis}", f"unknown axis; the sidecar's axes are "
                                                    f"{', '.join(dict.fromkeys(named))} "
                                                    f"(and x, y, z are always allowed)")
        norm = np.linalg.norm(a)     # rounded cosines normalised; a unit vector kept bit for bit
        sc.orientation[axis] = a if abs(norm - 1.0) <= 1e-12 else a / norm


def _identify_tables(data: Mapping, p: pathlib.Path, sc: Sidecar) -> None:
    """``[probes]`` and ``[identify]``: what rlgsim identify reads from the sidecar."""
    for src, dst in data.get("probes", {}).items():
        if not isinstance(dst, str) or not dst:
            raise _fail(f"{p}: probes.{src}", f"value {dst!r} not allowed; must be the name of "
                                              f"a probe of the thermal template (a string)")
        sc.probes[src] = dst
    for key, v in data.get("identify", {}).items():
        if not isinstance(v, str) or not v:
            raise _fail(f"{p}: identify.{key}", f"value {v!r} not allowed; must be a non-empty "
                                                f"string (a preset name or path; for gyro, one "
                                                f"of the [gyro] axes)")
        sc.identify[key] = v
    g = sc.identify.get("gyro")
    if g is not None and sc.gyro_axes is not None and g not in sc.gyro_axes:
        raise _fail(f"{p}: identify.gyro", f"value {g!r} not allowed; must be one of the [gyro] "
                                           f"axes ({', '.join(sc.gyro_axes)})")
