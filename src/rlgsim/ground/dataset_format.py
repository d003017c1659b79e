"""The rlgsim dataset format: its marker, version, names, and the one reader every module uses.

A dataset is one HDF5 file laid out the netCDF-4 way (docs/dataset.md is the schema): one
group per part of the run, a coordinate (HDF5 dimension scale) per dimension, ``units`` and
``description`` on every variable. The root carries the format marker
``rlgsim_format = "rlgsim dataset"`` and ``rlgsim_format_version``. The simulator declares the
groups in one place (:mod:`rlgsim.sim.writer.schema`) and writes them with
:mod:`rlgsim.sim.writer.dataset`; everything that *reads* a dataset — ``rlgsim info``, the calibration,
the studies, a user's notebook — goes through :func:`open_dataset` and :class:`Dataset`, so the
marker is checked once and no module spells raw HDF5 paths.

Units: what the file says (the ``units`` attribute of each variable, UDUNITS spelling): times
in s since the start of the run, absolute temperatures in °C, rates in rad/s, pulses as counts;
the reader never converts. A row on the thermal grid (dimension ``time``) describes the step
``[time − thermal_step_s, time)``; IMU sample ``k`` (dimension ``sample``, no stored coordinate)
covers ``[k/f, (k+1)/f)`` with ``f = sample_rate_hz``.

Memory: :meth:`Dataset.read` takes a row range (and columns), :meth:`Dataset.read_blocks`
walks a long variable in blocks of rows, so a reader never needs a whole 100 Hz record in
memory.

This module imports neither ``rlgsim.sim`` nor ``rlgsim.estimators`` (both sides use it), and
imports h5py only when a file is opened.
"""

from __future__ import annotations

import json
import os
import pathlib
from dataclasses import dataclass
from typing import Any, Iterator, Sequence

import numpy as np

from rlgsim.ground.errors import UserInputError

__all__ = ["FORMAT", "FORMAT_VERSION", "FORMAT_ATTR", "VERSION_ATTR", "SEGMENT_DETAILS",
           "TIMELINE", "THERMAL", "PROBES", "IMU", "TURNTABLE", "TRUTH", "ANOMALIES",
           "TRAJECTORY",
           "CALIBRATION", "TRACKS", "TIME", "SAMPLE", "VARIABLES", "OPTIONAL_VARIABLES",
           "MissingVariableError", "VariableInfo", "open_dataset", "Dataset"]

#: Root attribute :data:`FORMAT_ATTR` of every rlgsim dataset holds this marker.
FORMAT = "rlgsim dataset"
#: Layout version written today; readers refuse newer versions. Bump it when the layout
#: changes incompatibly. Version 2: the timeline's JSON segment details are the variable
#: ``details`` (version 1 called it ``attrs``, which clashes with xarray's ``.attrs``; still
#: read, :data:`SEGMENT_DETAILS_V1`).
FORMAT_VERSION = 2
#: The timeline variable holding each segment's JSON details (and its version-1 name).
SEGMENT_DETAILS = "details"
SEGMENT_DETAILS_V1 = "attrs"
FORMAT_ATTR = "rlgsim_format"
VERSION_ATTR = "rlgsim_format_version"
#: Root attribute of a dataset still being written (removed when the marker is written, last).
INCOMPLETE_ATTR = "rlgsim_incomplete"
INCOMPLETE = "rlgsim dataset being written: incomplete until its run ends"
#: Root attributes that must be finite and > 0 when present.
POSITIVE_ATTRS = ("duration_s", "thermal_step_s", "sample_rate_hz", "block_s")

# ---- group names (docs/dataset.md)
TIMELINE = "timeline"      #: labelled segments of the run and the chamber setpoint breakpoints
THERMAL = "thermal"        #: chamber and true node temperatures on the thermal grid
PROBES = "probes"          #: thermometer readings on the thermal grid (what hardware logs)
IMU = "imu"                #: pulses per sample, UHFO on the thermal grid (what hardware logs)
TURNTABLE = "turntable"    #: table angles on the thermal grid and the table of motions
TRUTH = "truth"            #: true sensor parameters, true inputs, the drawn unit
ANOMALIES = "anomalies"    #: the sensor anomalies' event record (only with ``[anomalies]``)
TRAJECTORY = "trajectory"  #: a vehicle's position, velocity, attitude (only with ``[trajectory]``)
CALIBRATION = "calibration"  #: added by ``rlgsim calibrate`` (one row per calibration window)

#: The timeline's tracks (variable ``timeline/track``), in the order the segments are stored.
TRACKS = ("chamber", "power", "turntable", "calibration", "acquisition")

# ---- dimension names shared by several groups
TIME = "time"              #: thermal grid: end of each thermal step [s]
SAMPLE = "sample"          #: IMU sample axis (no stored coordinate)

#: Every variable (coordinates included) of each group the simulator writes, in the order it
#: declares them; the device-dependent ones (accelerometers, UHFO, per-sample truth) are listed
#: too. Parts a scenario switches on (heaters, boundaries, anomalies) are in
#: :data:`OPTIONAL_VARIABLES`.
#: :mod:`rlgsim.sim.writer.schema` declares exactly these (tests/test_imu.py checks it).
VARIABLES: dict[str, tuple[str, ...]] = {
    TIMELINE: ("segment", "t0", "t1", "track", "label", "details", "breakpoint", "setpoint_time",
               "setpoint"),
    THERMAL: ("time", "chamber_setpoint", "chamber_air", "power_on", "node", "node_temperature",
              "capacitance", "capacitance_factor", "ambient_conductance",
              "ambient_conductance_factor", "power", "power_factor", "link", "link_conductance",
              "link_conductance_factor"),
    PROBES: ("time", "probe", "probe_node", "tau", "noise_sigma", "resolution", "temperature"),
    IMU: ("sample", "time", "gyro", "gyro_pulses", "accel", "accel_pulses", "uhfo"),
    TURNTABLE: ("time", "outer_angle", "inner_angle", "motion_index", "motion", "motion_t0",
                "motion_t1", "motion_label", "motion_kind", "motion_axis", "motion_rate",
                "motion_position", "motion_window"),
    TRUTH: ("time", "body", "gyro", "coefficient", "coefficient_value", "coefficient_units",
            "gyro_bias", "gyro_bias_random", "gyro_scale_factor", "gyro_installation",
            "gyro_white_sigma", "accel", "accel_bias", "accel_bias_random",
            "accel_scale_factor_pos", "accel_scale_factor_neg", "accel_installation",
            "accel_white_sigma", "uhfo_true", "uhfo_u0", "dtheta_step", "dv_step", "sample",
            "dtheta", "dv"),
}

#: Variables (coordinates included) written only when the scenario switches a part on, per
#: group, in the order they are declared — after the group's :data:`VARIABLES` names, and the
#: group :data:`ANOMALIES` after every group of :data:`VARIABLES`. A dataset holds a part's
#: names all together or none of them; a run without the part keeps exactly the layout of
#: :data:`VARIABLES` (docs/dataset.md):
#:
#: * ``thermal``: ``heater``, ``heater_power`` — the thermal preset has ``[thermal.heaters]``;
#:   ``boundary``, ``boundary_temperature`` — it has ``[thermal.boundaries]``;
#: * ``imu``: ``sample_valid`` — the device's ``[anomalies]`` table has IMU frame dropouts;
#: * ``anomalies`` (the whole group) — the device has an active ``[anomalies]`` table;
#: * ``trajectory`` (the whole group, after ``truth``) — the scenario has a
#:   ``[trajectory]`` (a vehicle instead of the turntable; docs/trajectories.md).
#:
#: :mod:`rlgsim.sim.writer.schema` declares exactly these (tests/test_dataset_optional.py).
OPTIONAL_VARIABLES: dict[str, tuple[str, ...]] = {
    THERMAL: ("heater", "heater_power", "boundary", "boundary_temperature"),
    IMU: ("sample_valid",),
    ANOMALIES: ("event", "time", "end", "channel", "kind", "size", "size_units"),
    TRAJECTORY: ("sample", "enu", "quaternion", "latitude", "longitude", "height", "velocity",
                 "attitude", "heading", "pitch", "roll", "gnss_visible", "leg", "leg_t0",
                 "leg_t1", "leg_label", "leg_kind", "leg_gnss"),
}


class MissingVariableError(UserInputError, KeyError):
    """A group or variable the caller needs is not in the dataset (one line; also a KeyError)."""


@dataclass(frozen=True)
class VariableInfo:
    """What a variable is, without reading it: ``name``, ``dims`` (dimension names, ``"?"``
    where none is attached), ``shape``, ``units`` (None when the variable has none),
    ``description``, ``dtype``, ``is_coordinate`` (a dimension scale)."""

    name: str
    dims: tuple[str, ...]
    shape: tuple[int, ...]
    units: str | None
    description: str
    dtype: np.dtype
    is_coordinate: bool


def _plain(value: Any) -> Any:
    """An attribute value as Python: bytes → str, numpy scalars → int/float/str."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return _plain(value.item())
    return value


def open_dataset(path: str | os.PathLike) -> "Dataset":
    """Open an rlgsim dataset read-only after checking its format marker and version.

    Raises :class:`~rlgsim.ground.errors.UserInputError` (one line naming the file) for a
    missing file, a directory, a file that is not HDF5, an HDF5 file without the marker
    ("not an rlgsim dataset"), or a format version this rlgsim cannot read. Use it as a
    context manager (or call :meth:`Dataset.close`).
    """
    import h5py

    import re
    import stat

    p = pathlib.Path(path)
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        raise UserInputError(f"{p}: no such file") from None
    except OSError as exc:
        raise UserInputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise UserInputError(f"{p}: is a directory, not an rlgsim dataset")
    if not stat.S_ISREG(mode):
        raise UserInputError(f"{p}: not a regular file (a FIFO, device or socket), not an "
                             f"rlgsim dataset")
    temporary = re.search(r"\.tmp-?\d+$", p.name) is not None
    incomplete = UserInputError(f"{p}: an incomplete rlgsim dataset (the temporary file of a run "
                                f"that was interrupted or is still running); run it again")
    try:
        f = h5py.File(p, "r")
    except OSError:
        if temporary:
            raise incomplete from None
        raise UserInputError(f"{p}: not an rlgsim dataset (not an HDF5 file)") from None
    try:
        try:
            attrs = {k: _plain(f.attrs[k]) for k in f.attrs.keys()}
        except (OSError, KeyError, RuntimeError, ValueError, TypeError) as exc:
            if temporary:
                raise incomplete from None
            raise UserInputError(f"{p}: damaged HDF5 file (its attributes cannot be read: "
                                 f"{' '.join(str(exc).split())[:100]})") from None
        fmt = attrs.get(FORMAT_ATTR)
        if fmt != FORMAT and (INCOMPLETE_ATTR in attrs or temporary):
            raise incomplete
        if fmt != FORMAT:
            raise UserInputError(f"{p}: not an rlgsim dataset (HDF5 file without the "
                                 f"{FORMAT_ATTR} = '{FORMAT}' marker)")
        raw = _plain(f.attrs.get(VERSION_ATTR))
        try:
            version = int(raw)
        except (TypeError, ValueError):
            version = None
        if version is None or isinstance(raw, float) and raw != version:
            raise UserInputError(f"{p}: rlgsim dataset without a valid {VERSION_ATTR} "
                                 f"({raw!r}); this rlgsim reads versions 1 to {FORMAT_VERSION}")
        if version > FORMAT_VERSION:
            raise UserInputError(f"{p}: rlgsim dataset format version {version} is newer than "
                                 f"this rlgsim reads ({FORMAT_VERSION}); upgrade rlgsim")
        if version < 1:
            raise UserInputError(f"{p}: rlgsim dataset format version {version} is not valid; "
                                 f"this rlgsim reads versions 1 to {FORMAT_VERSION}")
        for key in POSITIVE_ATTRS:
            if key in attrs:
                value = attrs[key]
                ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
                      and np.isfinite(value) and value > 0)
                if not ok:
                    raise UserInputError(f"{p}: root attribute {key} = {value!r} is not valid "
                                         f"(a finite number > 0); a damaged dataset?")
    except BaseException:
        f.close()
        raise
    return Dataset(f, p, version)


def check_finite(path: str | os.PathLike, group: str, name: str, values: np.ndarray,
                 first_row: int = 0) -> np.ndarray:
    """``values`` (rows ``first_row …`` of ``group/name``) unchanged if every value is finite,
    else a one-line :class:`UserInputError` naming the file, variable and first bad row — the
    check readers apply to what a simulated dataset never holds (NaN times, NaN readings)."""
    arr = np.asarray(values)
    if arr.dtype.kind in "fc" and arr.size and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        row = first_row + int(bad[0]) if arr.ndim else first_row
        raise UserInputError(f"{path}: {group}/{name} holds NaN or infinite values (row {row}); "
                             f"a damaged dataset? (delete a study's data/ file to simulate it "
                             f"again)")
    return values


class Dataset:
    """An open rlgsim dataset (from :func:`open_dataset`), read-only.

    ``path``; ``version`` the format version; ``attrs`` the root attributes as plain Python
    values (str, int, float; docs/dataset.md "Root attributes"). Variables are addressed by
    group and name, e.g. ``read(IMU, "gyro_pulses", rows=slice(k0, k1), columns=0)``.
    A missing group or variable raises :class:`MissingVariableError`.
    """

    def __init__(self, h5file: Any, path: pathlib.Path, version: int) -> None:
        self._f = h5file
        self.path = path
        self.version = version
        self.attrs: dict[str, Any] = {k: _plain(v) for k, v in h5file.attrs.items()}
        self._times: dict[str, np.ndarray] = {}

    # ---- life cycle ---------------------------------------------------------------------
    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> "Dataset":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<rlgsim Dataset {self.path} v{self.version}: {', '.join(self.groups())}>"

    # ---- what is there ------------------------------------------------------------------
    def groups(self) -> list[str]:
        """Group names in file order."""
        import h5py
        return [name for name, g in self._f.items() if isinstance(g, h5py.Group)]

    def has(self, group: str, name: str | None = None) -> bool:
        """Whether the group (and its variable ``name``) exists."""
        if name is None:
            return group in self._f
        return group in self._f and name in self._f[group]

    def _var(self, group: str, name: str):
        if not self.has(group, name):
            what = f"group {group!r}" if not self.has(group) else f"variable {group}/{name}"
            raise MissingVariableError(f"{self.path}: the dataset has no {what}")
        return self._f[group][name]

    def group_attrs(self, group: str) -> dict[str, Any]:
        """Attributes of a group (plain Python values), e.g. ``imu``'s ``sample_rate_hz``."""
        if not self.has(group):
            raise MissingVariableError(f"{self.path}: the dataset has no group {group!r}")
        return {k: _plain(v) for k, v in self._f[group].attrs.items()}

    def variables(self, group: str) -> list[VariableInfo]:
        """Every variable of a group, in file order, described without reading its data."""
        if not self.has(group):
            raise MissingVariableError(f"{self.path}: the dataset has no group {group!r}")
        out = []
        for name, ds in self._f[group].items():
            if ds.is_scale:
                dims = (name,) * ds.ndim
            else:
                dims = tuple((d[0].name or "?").rsplit("/", 1)[-1] if len(d) else "?"
                             for d in ds.dims)      # a deleted scale's name is None
            units = _plain(ds.attrs["units"]) if "units" in ds.attrs else None
            out.append(VariableInfo(name, dims, tuple(ds.shape), units,
                                    _plain(ds.attrs.get("description", "")), ds.dtype,
                                    bool(ds.is_scale)))
        return out

    def length(self, group: str, name: str) -> int:
        """Number of rows (first dimension) of a variable."""
        return int(self._var(group, name).shape[0])

    # ---- reading ------------------------------------------------------------------------
    def read(self, group: str, name: str, rows: slice | None = None,
             columns: int | Sequence[int] | None = None) -> np.ndarray:
        """A variable's values in its stored dtype and units; ``rows`` a slice of the first
        dimension, ``columns`` an index or increasing indices of the second. Strings come back
        as an object array of ``str``."""
        ds = self._var(group, name)
        if ds.dtype.kind == "O" or ds.dtype.kind == "S":
            import h5py
            if h5py.check_string_dtype(ds.dtype) is not None:
                ds = ds.asstr()
        if columns is not None:
            return ds[slice(None) if rows is None else rows, columns]
        return ds[...] if rows is None else ds[rows]

    def read_blocks(self, group: str, name: str, block_rows: int, *, start: int = 0,
                    stop: int | None = None, columns: int | Sequence[int] | None = None
                    ) -> Iterator[tuple[int, np.ndarray]]:
        """``(first_row, values)`` for consecutive blocks of at most ``block_rows`` rows of
        ``[start, stop)`` (default: all rows) — bounded memory over any run length."""
        if block_rows < 1:
            raise ValueError(f"block_rows must be >= 1, got {block_rows}")
        n = self.length(group, name) if stop is None else stop
        for k0 in range(start, n, block_rows):
            yield k0, self.read(group, name, slice(k0, min(n, k0 + block_rows)), columns)

    def strings(self, group: str, name: str) -> list[str]:
        """A string variable or coordinate as a list of ``str`` (e.g. ``probes/probe``)."""
        return [str(v) for v in self.read(group, name)]

    def time_rows(self, group: str, t0_s: float, t1_s: float) -> slice:
        """Rows of a group's ``time`` grid whose step ends in ``(t0_s, t1_s]`` [s]."""
        t = self._times.get(group)
        if t is None:
            t = self._times[group] = self.read(group, TIME)
        return slice(int(np.searchsorted(t, t0_s, side="right")),
                     int(np.searchsorted(t, t1_s, side="right")))

    # ---- decoded tables -----------------------------------------------------------------
    def segments(self, track: str | None = None) -> list[dict[str, Any]]:
        """The timeline's segments as dicts ``t0``, ``t1`` [s], ``track``, ``label``, ``attrs``
        (the JSON details decoded), in file order; only ``track``'s when given."""
        t0, t1 = self.read(TIMELINE, "t0"), self.read(TIMELINE, "t1")
        tracks, labels = self.read(TIMELINE, "track"), self.read(TIMELINE, "label")
        name = SEGMENT_DETAILS if self.has(TIMELINE, SEGMENT_DETAILS) else SEGMENT_DETAILS_V1
        details = self.read(TIMELINE, name)                       # version-1 files: "attrs"
        check_finite(self.path, TIMELINE, "t0", t0)
        check_finite(self.path, TIMELINE, "t1", t1)
        bad = np.flatnonzero(t1 < t0)
        if bad.size:
            raise UserInputError(f"{self.path}: {TIMELINE}/t1 is before {TIMELINE}/t0 in row "
                                 f"{int(bad[0])}; a damaged dataset?")
        if not len(t0) == len(t1) == len(tracks) == len(labels) == len(details):
            raise UserInputError(f"{self.path}: the {TIMELINE} variables have different "
                                 f"lengths; a damaged dataset?")
        out = []
        for row, (a, b, tr, lb, at) in enumerate(zip(t0, t1, tracks, labels, details)):
            if track is not None and str(tr) != track:
                continue
            try:
                decoded = json.loads(str(at))
            except ValueError as exc:
                why = getattr(exc, "msg", None) or type(exc).__name__
                raise UserInputError(f"{self.path}: {TIMELINE}/{name} row {row}: not valid JSON "
                                     f"({why}); a damaged dataset?") from None
            if not isinstance(decoded, dict):
                raise UserInputError(f"{self.path}: {TIMELINE}/{name} row {row}: JSON "
                                     f"{type(decoded).__name__}, expected an object; a damaged "
                                     f"dataset?")
            out.append(dict(t0=float(a), t1=float(b), track=str(tr), label=str(lb),
                            attrs=decoded))
        return out

    def coefficients(self) -> dict[str, float]:
        """The drawn unit's coefficient table (group ``truth``): ``<law>.<term>[<axis>]`` →
        value in the unit of ``truth/coefficient_units`` (e.g. ``gyro.k0[x]`` pulses/rad)."""
        return dict(zip(self.strings(TRUTH, "coefficient"),
                        map(float, self.read(TRUTH, "coefficient_value"))))
