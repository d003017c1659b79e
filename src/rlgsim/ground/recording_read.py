"""Reading a recording (docs/recordings.md): find the table and its sidecar, read the table
(CSV, Parquet, or the 1-D datasets of an HDF5 group written by another tool) and validate every
column — known name and unit, values in range, whole pulse counts, strictly increasing time at
the sample rate with no gap, no NaN outside rows flagged ``dropout = 1``, slow
(temperature-rate) columns on a regular grid — raising a one-line
:class:`~rlgsim.ground.errors.UserInputError` naming the file, column, row (1-based data row,
header excluded) and what is allowed.

Part of :mod:`rlgsim.ground.recording`; nothing here imports ``rlgsim.sim``.
"""

from __future__ import annotations

import os
import pathlib
import stat
import tomllib

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.paths import input_file
from rlgsim.ground.recording_columns import (check_range, column_rule, is_slow_kind,
                                             need_pyarrow, numeric_column, time_column,
                                             unknown_column)
from rlgsim.ground.recording_formats import DATA_SUFFIXES, TABLE_FORMATS
from rlgsim.ground.recording_sidecar import Sidecar, read_sidecar, sidecar_path
from rlgsim.ground.recording_table import Recording

__all__ = ["DATA_SUFFIXES", "is_recording", "is_sidecar", "load_recording"]



def is_recording(path: str | os.PathLike) -> bool:
    """True when ``path`` is a table file with a sidecar beside it, or a sidecar naming one —
    what commands check before treating an argument as a recording rather than a dataset."""
    p = pathlib.Path(path)
    if p.suffix.lower() == ".toml":
        return is_sidecar(p)
    if DATA_SUFFIXES.get(p.suffix.lower()) in ("csv", "parquet"):
        return True
    if p.suffix.lower() in TABLE_FORMATS["hdf5"].suffixes:
        # an HDF5 table of another tool, with a sidecar made for it (not the sidecar of a
        # CSV export of this dataset, which shares the stem)
        side = sidecar_path(p)
        if not is_sidecar(side):
            return False
        try:
            data = tomllib.loads(side.read_text(encoding="utf-8"))["recording"].get("data")
        except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError, AttributeError):
            return False
        return data is None or pathlib.Path(str(data)).name == p.name
    return False


def is_sidecar(path: pathlib.Path) -> bool:
    """True when ``path`` is a TOML file with a ``[recording]`` table (not, say, the scenario
    that shares a dataset's stem). Only a regular file of at most 16 MiB is read: a FIFO would
    hang, a link to ``/dev/zero`` never end."""
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > 16 << 20:
            return False
        return "recording" in tomllib.loads(pathlib.Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return False


def _resolve(path: str | os.PathLike) -> tuple[pathlib.Path, Sidecar]:
    """The table and its validated sidecar; both must be regular files (a FIFO would hang the
    reader, a link to ``/dev/zero`` never ends): :func:`rlgsim.ground.paths.input_file`."""
    p = pathlib.Path(path)
    if p.suffix.lower() == ".toml":
        sc = read_sidecar(input_file(p, "a recording sidecar (.toml)"))
        if not sc.data:
            raise UserInputError(f"{p}: recording.data missing; a sidecar given on its own must "
                                 f"name its table file (data = \"run1.csv\")")
        data = input_file(p.parent / sc.data, "a recording table",
                          missing=f"no such file (named by {p}: recording.data)")
        return data, sc
    input_file(p, "a recording (a table with a .toml sidecar)")
    if p.suffix.lower() not in DATA_SUFFIXES:
        raise UserInputError(f"{p}: not a recording; allowed table files: "
                             f"{', '.join(DATA_SUFFIXES)} with a .toml sidecar")
    side = sidecar_path(p)
    if not os.path.lexists(side):
        raise UserInputError(f"{p}: no sidecar {side.name} beside it; a recording needs one "
                             f"(at least [recording] sample_rate_hz; docs/recordings.md)")
    return p, read_sidecar(input_file(side, "a recording sidecar (.toml)"))


def _sniff_delimiter(path: pathlib.Path) -> str:
    """The CSV field separator from the header line: ``,`` unless the header has none and
    holds ``;``, a tab or ``|`` (loggers in locales with a decimal comma write ``;``)."""
    try:
        with open(path, "rb") as fh:
            head = fh.readline(1 << 16).decode("utf-8", "replace")
    except OSError:
        return ","
    if "," in head:
        return ","
    counts = {c: head.count(c) for c in (";", "\t", "|")}
    best = max(counts, key=counts.get)
    return best if counts[best] else ","


def _read_table(path: pathlib.Path, kind: str, sc: Sidecar) -> tuple[list[str], dict, int]:
    """Raw columns: names in file order, name -> (values as float64, raw text-or-None), rows.
    Non-numeric cells are reported by the caller using the raw values."""
    if kind == "csv":
        import pandas as pd
        sep = sc.delimiter or _sniff_delimiter(path)
        if sep == "," and sc.decimal == ",":
            raise UserInputError(f"{sc.path}: recording.decimal: value ',' not allowed with "
                                 f"the delimiter ','; give [recording] delimiter = \";\"")
        try:                 # numbers parsed by pandas' C reader; only empty cells are NaN
            df = pd.read_csv(path, keep_default_na=False, na_values=[""], sep=sep,
                             decimal=sc.decimal, skipinitialspace=True, low_memory=False)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
            msg = " ".join(str(exc).split())
            raise UserInputError(f"{path}: not a readable CSV table ({msg})") from None
        names = [str(c).strip() for c in df.columns]
        raw = {n: df.iloc[:, i].to_numpy() for i, n in enumerate(names)}
        return names, raw, len(df)
    if kind == "parquet":
        import pandas as pd
        need_pyarrow(path, "reading")
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
    kinds, values, where, origin = _standard_columns(data_path, kind, sc, names, raw)
    if n < 2:
        raise UserInputError(f"{data_path}: {n} row(s); a recording needs at least 2 samples")
    _check_axes(data_path, sc, kinds, where)
    dropout = np.zeros(n, dtype=bool)
    if "dropout" in values:
        d = values.pop("dropout")
        kinds.pop("dropout")
        bad = np.flatnonzero(~np.isin(d, (0.0, 1.0)))
        if bad.size:
            raise UserInputError(f"{where('dropout', int(bad[0]))}: value {float(d[bad[0]])!r} "
                                 f"not allowed; must be 0 or 1")
        dropout = d == 1.0
    t = values.pop("time_s")
    kinds.pop("time_s")
    _check_time(t, sc, where)
    slow_rows = _check_values(values, kinds, dropout, t, sc, where)
    return Recording(path=data_path, sidecar=sc, kind=kind, time_s=t, columns=values,
                     dropout=dropout, slow_rows=slow_rows, kinds=kinds, time_origin=origin)


def _standard_columns(data_path: pathlib.Path, kind: str, sc: Sidecar, names: list[str],
                      raw: dict):
    """The table's columns under their standard names: ``kinds`` (name -> rule), ``values``
    (name -> float64), ``where(std, row)`` (how a message names the file's column and row)
    and the time origin of a timestamp time axis (ISO text, or None)."""
    for src in sc.columns:
        if src not in names:
            raise UserInputError(f"{sc.path}: columns.{src}: the table has no column {src!r}")
    if len(names) == 1 and sc.delimiter is None and any(c in names[0] for c in ";\t|"):
        raise UserInputError(f"{data_path}: one column {names[0][:60]!r}: the file looks "
                             f"delimited by another character than ','; give it in the "
                             f"sidecar as [recording] delimiter = \";\" (or \"\\t\", \"|\")")
    kinds: dict[str, tuple[str, str, dict]] = {}
    values: dict[str, np.ndarray] = {}
    origin = None
    for name in names:
        if name in sc.ignore_columns:
            continue
        std = sc.columns.get(name, name)
        rule = column_rule(std)
        if rule is None:
            raise UserInputError(f"{data_path}: column {name!r}: {unknown_column(std)}")
        if std in kinds:
            raise UserInputError(f"{data_path}: column {name!r}: a second column {std!r}; each "
                                 f"standard column may appear once")
        kinds[std] = rule
        column = np.asarray(raw[name])
        if std == "time_s":
            values[std], origin = time_column(data_path, name, column, kind, sc.sample_rate_hz)
        else:
            values[std] = numeric_column(data_path, name, column, kind)
    if "time_s" not in values:
        raise UserInputError(f"{data_path}: column 'time_s' missing; every recording needs the "
                             f"time of each sample in seconds (or map the file's time column, "
                             f"seconds or ISO 8601 timestamps, in the sidecar's [columns])")
    shown = {sc.columns.get(c, c): c for c in names}        # standard -> name in the file

    def where(std: str, row: int | None = None) -> str:
        col = shown.get(std, std)
        return f"{data_path}: column {col!r}" + (f", row {row + 1}" if row is not None else "")
    return kinds, values, where, origin


def _check_axes(data_path: pathlib.Path, sc: Sidecar, kinds: dict, where) -> None:
    """The gyro and accelerometer axes of the columns against the sidecar's lists; the UHFO
    columns against the gyro axes."""
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
    if sc.gyro_axes is None and sc.accel_axes is None:   # no lists: the sidecar could not check
        axes = [g["axis"] for k, _, g in kinds.values()  # its [orientation] keys; the columns can
                if k in ("gyro", "accel") and g.get("axis") is not None]
        for key in sc.orientation:                       # (a misspelt key never passes silently)
            if key not in axes and key not in ("x", "y", "z"):
                raise UserInputError(f"{sc.path}: orientation.{key}: unknown axis; the table's "
                                     f"axes are {', '.join(dict.fromkeys(axes)) or 'none'} (and "
                                     f"x, y, z are always allowed)")
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


def _check_time(t: np.ndarray, sc: Sidecar, where) -> None:
    """Every row's time present, strictly increasing, one row every 1/f: a step that differs
    from 1/f in most rows is a wrong ``sample_rate_hz``, a longer one in a few rows a gap."""
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
                             f"{float(t[i - 1])!r} s; time must increase strictly from row to "
                             f"row")
    tol = 1e-3 * dt + 1e-9 * np.abs(t[1:])
    off = np.flatnonzero(np.abs(step - dt) > tol)
    if not off.size:
        return
    typical = float(np.median(step))
    if off.size > step.size // 2 and abs(typical - dt) > 1e-3 * dt:
        raise UserInputError(f"{where('time_s')}: the rows are {typical:.6g} s apart "
                             f"({1.0 / typical:.6g} Hz) in {off.size} of {step.size} steps, "
                             f"but the sidecar's sample_rate_hz = {sc.sample_rate_hz:g} "
                             f"needs {dt:.6g} s; set [recording] sample_rate_hz to the rate "
                             f"the file was logged at")
    i = int(off[0]) + 1
    gap = step[i - 1]
    what = (f"a gap of {gap:.6g} s ({gap / dt - 1:.4g} missing sample(s)); record a dropout "
            f"as rows with dropout = 1 (their values may be empty), not by leaving rows out"
            if gap > 1.5 * dt else
            f"a step of {gap:.6g} s; the sidecar's sample_rate_hz = {sc.sample_rate_hz:g} "
            f"needs {dt:.6g} s between rows")
    raise UserInputError(f"{where('time_s', i)}: {what}")


def _check_values(values: dict, kinds: dict, dropout: np.ndarray, t: np.ndarray, sc: Sidecar,
                  where) -> np.ndarray | None:
    """Each column's values: slow columns on their grid (the grid's rows are returned), no
    empty cell outside a dropout, the range of the column's unit."""
    n = t.size
    slow_rows = None
    slow_names = [s for s, (k, _, _) in kinds.items() if is_slow_kind(s, k)]
    if sc.temperature_rate_hz is not None and slow_names:
        slow_rows = _slow_grid(values, slow_names, dropout, t, sc, where)
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
        check_range(std, k, unit, v, check & np.isfinite(v), where, sc)
    return slow_rows


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

