"""Export a simulated dataset (or a recording) to the recording format (docs/recordings.md), so
the two paths meet: what a user's logger writes and what the simulator writes read the same way.

A dataset becomes one table at the IMU sample rate — ``time_s`` (end of each sample interval,
``(k+1)/f``), ``gyro_<axis>_pulses``, ``accel_<axis>_pulses`` — with the thermal-grid channels
(``probe_<name>_c``, ``chamber_air_c``, ``chamber_setpoint_c``, ``power_on``,
``uhfo_<axis>_v``, ``outer_angle_deg``, ``inner_angle_deg``) on the rows that end a thermal
step and empty in between (sidecar ``temperature_rate_hz = 1 / thermal_step_s``), plus the
sidecar (sample rate, site, axes, nominal scale factors and noise levels of the device preset)
and, when the run has calibration windows, the commanded programme ``<stem>_programme.csv``.
Every value is written exactly (pulses as integers, floats with full precision), so importing
the export gives the dataset's arrays bit for bit. The truth is not exported: a recording has
none — except a drive's (a run on a vehicle), whose trajectory goes into a table of its own
beside the pulses (:mod:`rlgsim.ground.recording_trajectory`), the sidecar marked
``platform = "vehicle"``.

Written block by block (:data:`BLOCK_ROWS` samples), so memory does not grow with the run.

Every file written is checked first (:func:`rlgsim.ground.paths.output_files`): never an input
(a recording's own sidecar is one), a link or a special file; an existing file that is not an
earlier export of the same table (its sidecar names it) is replaced only with
``overwrite=True`` (``--overwrite``). The default output is ``<stem>_recording.<ext>`` beside
the source, so the source's own sidecar ``<stem>.toml`` (a recording's, or the scenario beside a
dataset) is never the export's.
"""

from __future__ import annotations

import os
import pathlib
import tomllib
from dataclasses import dataclass

import numpy as np

from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.recording_trajectory import check_trajectory, trajectory_blocks
from rlgsim.ground.paths import input_file, output_files
from rlgsim.ground.recording_formats import EXPORT_FORMATS
from rlgsim.ground.recording import (RECORDING_FORMAT, RECORDING_VERSION, Sidecar, is_sidecar,
                                     is_recording, load_recording, sidecar_path, write_sidecar,
                                     write_table)

__all__ = ["FORMATS", "BLOCK_ROWS", "Exported", "export", "planned_outputs"]

FORMATS = EXPORT_FORMATS             # format name → the suffix written (one registry)
#: Samples per written block.
BLOCK_ROWS = 1 << 18


@dataclass(frozen=True)
class Exported:
    """What :func:`export` wrote: the table, its sidecar, the programme CSV (or None), rows."""

    table: pathlib.Path
    sidecar: pathlib.Path
    programme: pathlib.Path | None
    rows: int
    trajectory: pathlib.Path | None = None      #: a drive's truth table (a vehicle run)


def _text(v) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.generic):
        return str(v.item())
    return str(v)


def _out_path(src: pathlib.Path, fmt: str, out: str | os.PathLike | None) -> pathlib.Path:
    if fmt not in FORMATS:
        raise UserInputError(f"--format: value {fmt!r} not allowed; must be one of "
                             f"{', '.join(FORMATS)}")
    if out is not None:
        p = pathlib.Path(out).expanduser()
    else:       # <stem>_recording.<ext>; when its sidecar is another export's (the other
        p = src.with_name(f"{src.stem}_recording{FORMATS[fmt]}")     # format): _<fmt> added
        other = _sidecar_data(sidecar_path(p))
        if other is not None and other != p.name:
            p = src.with_name(f"{src.stem}_recording_{fmt}{FORMATS[fmt]}")
    if p.suffix.lower() != FORMATS[fmt]:
        raise UserInputError(f"{p}: a {fmt} table must end in {FORMATS[fmt]} (its sidecar is "
                             f"{p.with_suffix('.toml').name})")
    return p


def _sidecar_data(side: pathlib.Path) -> str | None:
    """The table an exporter's sidecar names (``[recording] data``), else None."""
    if not is_sidecar(side):
        return None
    try:
        rec = tomllib.loads(side.read_text(encoding="utf-8"))["recording"]
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError, KeyError, TypeError):
        return None
    data = rec.get("data")
    return data if rec.get("format") == RECORDING_FORMAT and isinstance(data, str) else None


def _exported_sidecar_of(table: pathlib.Path) -> bool:
    """Whether the sidecar beside ``table`` is an exporter's sidecar naming that table (so the
    table, the sidecar and the programme beside them are an earlier export's)."""
    return _sidecar_data(sidecar_path(table)) == table.name


def planned_outputs(source: str | os.PathLike, fmt: str = "csv",
                    out: str | os.PathLike | None = None, *, overwrite: bool = False
                    ) -> dict[str, pathlib.Path]:
    """The files :func:`export` would write (``table``, ``sidecar`` and, for a dataset with
    calibration windows, ``programme``), each checked (module docstring); nothing is
    written."""
    src = input_file(source, "an rlgsim dataset or a recording")
    p = _out_path(src, fmt, out)
    if fmt == "parquet":
        from rlgsim.ground.recording_columns import need_pyarrow
        need_pyarrow(p, "writing")
    outputs = {"table": p, "sidecar": sidecar_path(p)}
    inputs = [src]
    other = _sidecar_data(outputs["sidecar"])
    if other is not None and other != p.name and not overwrite:
        raise UserInputError(f"{outputs['sidecar']}: is the sidecar of the table {other}; a "
                             f"second table of the stem {p.stem!r} would take it: choose "
                             f"another -o (such as {p.stem}_{fmt}{FORMATS[fmt]}) or give "
                             f"--overwrite")
    if is_recording(src):
        inputs.append(sidecar_path(src))
    else:
        windows, drive = _dataset_extras(src)
        if windows:
            outputs["programme"] = p.with_name(f"{p.stem}_programme.csv")
        if drive:
            outputs["trajectory"] = p.with_name(f"{p.stem}_trajectory{FORMATS[fmt]}")
    return output_files(outputs, inputs=inputs, overwrite=overwrite,
                        own=lambda role, path: _exported_sidecar_of(p))


def _dataset_extras(src: pathlib.Path) -> tuple[bool, bool]:
    """Whether the dataset's timeline has calibration windows (then the programme is written
    too) and whether it has the group ``trajectory`` (a drive: its truth table too), from one
    open; a file that is no dataset: (False, False) (the export says why)."""
    from rlgsim.ground.dataset_format import TIMELINE, TRAJECTORY
    try:
        with _open(src) as ds:
            drive = ds.has(TRAJECTORY)
            try:
                windows = ds.has(TIMELINE, "t0") and any(s["track"] == "calibration"
                                                          for s in ds.segments())
            except UserInputError:          # a damaged timeline: no programme, still a drive
                windows = False
            return windows, drive
    except UserInputError:
        return False, False


def export(source: str | os.PathLike, fmt: str = "csv",
           out: str | os.PathLike | None = None, *, overwrite: bool = False) -> Exported:
    """Export a dataset or a recording at ``source`` as a ``fmt`` (``csv``/``parquet``) table
    at ``out`` (default: ``<stem>_recording.<ext>`` beside the source) with its sidecar (and
    programme); ``overwrite``: replace existing files that are not an earlier export."""
    outputs = planned_outputs(source, fmt, out, overwrite=overwrite)
    src = pathlib.Path(source)
    if is_recording(src):
        return _export_recording(src, fmt, outputs)
    return _export_dataset(src, fmt, outputs)


# ---------------------------------------------------------------------------- recordings

def _same_file(a: pathlib.Path, b: pathlib.Path) -> bool:
    """Whether ``a`` and ``b`` name one existing file."""
    try:
        return a.samefile(b)
    except (OSError, ValueError):
        return False


def _sidecar_tables(sc: Sidecar, data_name: str, rec, side: pathlib.Path) -> dict:
    """The sidecar of a recording re-exported with the sidecar ``side``: the source's, but a
    drive's ``trajectory`` key only while that table is beside the new sidecar too (it is not
    copied: re-exported to another folder the key would name a missing table; ``platform``
    stays, so the fixed-site readers still refuse it)."""
    rec_t = {"format": RECORDING_FORMAT, "version": RECORDING_VERSION}
    if sc.description:
        rec_t["description"] = sc.description
    rec_t["data"] = data_name
    rec_t["sample_rate_hz"] = sc.sample_rate_hz
    if sc.temperature_rate_hz is not None:
        rec_t["temperature_rate_hz"] = sc.temperature_rate_hz
    rec_t["source"] = sc.source or str(rec.path)
    if sc.platform != "fixed":
        rec_t["platform"] = sc.platform
    if sc.trajectory and _same_file(sc.path.parent / sc.trajectory, side.parent / sc.trajectory):
        rec_t["trajectory"] = sc.trajectory             # the drive's truth, still beside it
    tables = {"recording": rec_t,
              "site": {"latitude_deg": sc.latitude_deg, "height_m": sc.height_m}}
    g = {}
    if rec.gyro_axes:
        g["axes"] = rec.gyro_axes
    if sc.gyro_sf_pulse_per_arcsec is not None:
        g["scale_factor_pulses_per_arcsec"] = sc.gyro_sf_pulse_per_arcsec
    a = {}
    if rec.accel_axes:
        a["axes"] = rec.accel_axes
    if sc.accel_sf_pulse_per_s_per_g is not None:
        a["scale_factor_pulses_per_s_per_g"] = sc.accel_sf_pulse_per_s_per_g
    tables.update(gyro=g, accelerometer=a,
                  orientation={k: list(map(float, v)) for k, v in sc.orientation.items()},
                  noise=dict(sc.noise))
    return tables


def _export_recording(src: pathlib.Path, fmt: str, outputs: dict) -> Exported:
    p = outputs["table"]
    rec = load_recording(src)
    df = rec.to_dataframe()
    write_table(p, [df], fmt)
    side = write_sidecar(outputs["sidecar"], _sidecar_tables(rec.sidecar, p.name, rec,
                                                          outputs["sidecar"]),
                         comment=f"rlgsim recording sidecar (docs/recordings.md), exported from "
                                 f"{rec.path.name}")
    return Exported(p, side, None, len(df))


# ---------------------------------------------------------------------------- datasets

def _open(src: pathlib.Path):
    """The dataset at ``src`` (the one reader), or one line saying it is neither a dataset nor
    a recording."""
    from rlgsim.ground.dataset_format import open_dataset
    try:
        return open_dataset(src)
    except UserInputError as exc:
        if "not an HDF5 file" in str(exc):
            raise UserInputError(f"{src}: neither an rlgsim dataset nor a recording (a .csv, "
                                 f".parquet or .h5 table with a .toml sidecar)") from None
        if "without the" in str(exc):
            raise UserInputError(f"{src}: not an rlgsim dataset (HDF5 file without the "
                                 f"rlgsim_format marker) and no sidecar {sidecar_path(src).name} "
                                 f"beside it") from None
        raise


def _axes(ds, variable: str, coordinate: str) -> list[str]:
    """The axis names of ``imu/<variable>`` (its coordinate, or x, y, z by column)."""
    from rlgsim.ground.dataset_format import IMU
    if ds.has(IMU, coordinate):
        return ds.strings(IMU, coordinate)
    return list("xyz")[:ds.read(IMU, variable, slice(0, 1)).shape[1]]


def _slow_columns(ds, gyro_axes: list[str]) -> dict[str, np.ndarray]:
    """The thermal-grid channels as recording columns: column -> values on the thermal grid."""
    from rlgsim.ground.dataset_format import IMU, PROBES, THERMAL, TURNTABLE
    slow: dict[str, np.ndarray] = {}
    if ds.has(PROBES, "temperature"):
        temps = ds.read(PROBES, "temperature")
        for i, name in enumerate(ds.strings(PROBES, "probe")):
            slow[f"probe_{name}_c"] = temps[:, i].astype(np.float64)
    for var, col in (("chamber_air", "chamber_air_c"), ("chamber_setpoint", "chamber_setpoint_c"),
                     ("power_on", "power_on")):
        if ds.has(THERMAL, var):
            slow[col] = ds.read(THERMAL, var).astype(np.float64)
    if gyro_axes and ds.has(IMU, "uhfo"):
        u = ds.read(IMU, "uhfo")
        for i, ax in enumerate(gyro_axes):
            slow[f"uhfo_{ax}_v"] = u[:, i].astype(np.float64)
    for var, col in (("outer_angle", "outer_angle_deg"), ("inner_angle", "inner_angle_deg")):
        if ds.has(TURNTABLE, var):
            slow[col] = ds.read(TURNTABLE, var).astype(np.float64)
    return slow


def _dataset_sidecar(src: pathlib.Path, p: pathlib.Path, a: dict, rate: float, step: float,
                     slow: bool, has_imu: bool, gyro_axes: list[str], accel_axes: list[str]
                     ) -> dict:
    """The sidecar of the exported table: the recording, the site, the axes with the device
    preset's nominal scale factors, and its noise levels."""
    device = {}
    try:
        device = tomllib.loads(_text(a.get("device_text", ""))) if "device_text" in a else {}
    except tomllib.TOMLDecodeError:
        device = {}
    rec_t = {"format": RECORDING_FORMAT, "version": RECORDING_VERSION,
             "description": f"exported from the rlgsim dataset {src.name} (scenario "
                            f"{_text(a.get('scenario_name', '?'))}, seed "
                            f"{_text(a.get('seed', '?'))})",
             "data": p.name, "sample_rate_hz": rate}
    if slow and has_imu:
        rec_t["temperature_rate_hz"] = 1.0 / step
    rec_t["source"] = str(src)
    tables = {"recording": rec_t,
              "site": {"latitude_deg": float(a.get("latitude_deg", DEFAULT_LATITUDE_DEG)),
                       "height_m": float(a.get("height_m", 0.0))}}
    if gyro_axes:
        g = {"axes": gyro_axes}
        sf = device.get("gyro", {}).get("scale_factor_pulses_per_arcsec")
        if isinstance(sf, (int, float)):
            g["scale_factor_pulses_per_arcsec"] = float(sf)
        tables["gyro"] = g
    if accel_axes:
        acc_t = {"axes": accel_axes}
        sf = device.get("accelerometer", {}).get("scale_factor_pulses_per_s_per_g")
        if isinstance(sf, (int, float)):
            acc_t["scale_factor_pulses_per_s_per_g"] = float(sf)
        tables["accelerometer"] = acc_t
    tables["noise"] = {k: float(v) for k, v in device.get("noise", {}).items()
                       if isinstance(v, (int, float)) and not isinstance(v, bool)}
    return tables


def _exportable(src: pathlib.Path, ds) -> None:
    """Refuse (one line) pulse variables that are not integer (samples, axes) tables of one
    length."""
    from rlgsim.ground.dataset_format import IMU
    rows = None
    for name in ("gyro_pulses", "accel_pulses"):
        if ds.has(IMU, name):
            v = ds.read(IMU, name, slice(0, 1))
            n = ds.length(IMU, name) if v.ndim else 0
            if v.ndim != 2 or v.dtype.kind not in "iu" or rows not in (None, n):
                raise UserInputError(f"{src}: imu/{name} is {v.dtype} with {v.ndim} dimension(s)"
                                     f" and {n} rows; pulses are integer (samples, axes) "
                                     f"tables, gyro and accelerometer of one length (a damaged "
                                     f"dataset?)")
            rows = n


def _export_dataset(src: pathlib.Path, fmt: str, outputs: dict) -> Exported:
    import pandas as pd
    p = outputs["table"]

    from rlgsim.ground.dataset_format import IMU, TIMELINE
    with _open(src) as ds:
        _exportable(src, ds)
        a = ds.attrs
        step = float(a.get("thermal_step_s", 1.0))
        has_imu = ds.has(IMU, "gyro_pulses")
        rate = float(ds.group_attrs(IMU).get("sample_rate_hz", a.get("sample_rate_hz"))) \
            if has_imu else 1.0 / step
        ratio = step * rate
        r = int(round(ratio))
        if abs(ratio - r) > 1e-9 or r < 1:
            raise UserInputError(f"{src}: thermal step {step:g} s is not a whole number of "
                                 f"samples at {rate:g} Hz; cannot put both on one table")
        gyro_axes = _axes(ds, "gyro_pulses", "gyro") if has_imu else []
        accel_axes = (_axes(ds, "accel_pulses", "accel")
                      if has_imu and ds.has(IMU, "accel_pulses") else [])
        slow = _slow_columns(ds, gyro_axes)
        n_thermal = max((len(v) for v in slow.values()), default=0)
        n = ds.length(IMU, "gyro_pulses") if has_imu else n_thermal
        if n == 0:
            raise UserInputError(f"{src}: the dataset has no samples to export")
        # thermal row j ends at (j+1)·step: sample index (j+1)·r − 1
        slow_idx = (np.arange(n_thermal) + 1) * r - 1
        keep = slow_idx < n

        def blocks():
            for k0 in range(0, n, BLOCK_ROWS):
                k1 = min(n, k0 + BLOCK_ROWS)
                data = {"time_s": (np.arange(k0, k1, dtype=np.float64) + 1.0) / rate}
                if has_imu:
                    g = ds.read(IMU, "gyro_pulses", slice(k0, k1))
                    for i, ax in enumerate(gyro_axes):
                        data[f"gyro_{ax}_pulses"] = g[:, i].astype(np.int64)
                    if accel_axes:
                        acc = ds.read(IMU, "accel_pulses", slice(k0, k1))
                        for i, ax in enumerate(accel_axes):
                            data[f"accel_{ax}_pulses"] = acc[:, i].astype(np.int64)
                sel = keep & (slow_idx >= k0) & (slow_idx < k1)
                for col, values in slow.items():
                    v = np.full(k1 - k0, np.nan)
                    v[slow_idx[sel] - k0] = values[sel]
                    data[col] = v
                yield pd.DataFrame(data)

        if "trajectory" in outputs:
            check_trajectory(ds, n)
        write_table(p, blocks(), fmt)
        tables = _dataset_sidecar(src, p, a, rate, step, bool(slow), has_imu, gyro_axes,
                                  accel_axes)
        if "trajectory" in outputs:                     # a drive: its truth beside the pulses
            write_table(outputs["trajectory"], trajectory_blocks(ds, n, rate, BLOCK_ROWS), fmt)
            tables["recording"].update(platform="vehicle",
                                       trajectory=outputs["trajectory"].name)
        side = write_sidecar(outputs["sidecar"], tables,
                             comment="rlgsim recording sidecar (docs/recordings.md)")
        programme = None
        if "programme" in outputs and ds.has(TIMELINE, "t0"):
            from rlgsim.ground.programme import write_programme
            programme = write_programme(outputs["programme"], ds.segments())
    return Exported(p, side, programme, n, outputs.get("trajectory"))
