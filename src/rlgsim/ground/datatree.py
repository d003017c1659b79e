"""Any dataset or recording as an :class:`xarray.DataTree` with a time coordinate on every group
(docs/api.md).

Datasets open lazily with xarray's h5netcdf engine (their netCDF-4 layout, docs/dataset.md), and
the view adds what the file leaves implicit:

- ``imu`` (and ``truth`` with per-sample truth): the coordinate ``sample_time`` on the
  ``sample`` dimension, ``(k+1)/f`` seconds (an :class:`xarray.indexes.RangeIndex`, so a
  100 Hz run of days costs no memory), and its timedelta twin ``sample_elapsed`` (computed
  lazily, for ``imu.resample(sample_elapsed="60s")``); every float ``time`` coordinate of the
  slow groups gets the twin ``elapsed``;
- ``timeline``: ``t0``/``t1`` become coordinates of ``segment`` and ``setpoint_time`` of
  ``breakpoint``; the JSON details of a segment are the variable ``details`` (files of format
  version 1 call it ``attrs``, which clashes with xarray's ``.attrs``; the view renames it);
- ``calibration``: ``t0``/``t1`` become coordinates of ``window``.

A recording (:mod:`rlgsim.ground.recording`) becomes a tree of the same shape: root attributes
(``rlgsim_format = "rlgsim recording"``, ``sample_rate_hz``, site, nominal scale factors),
``imu`` (``sample_time``, ``gyro_pulses``/``accel_pulses`` or ``gyro_rate`` [°/h] and
``specific_force`` [m/s²], ``dropout``, ``uhfo`` on
``time``), ``probes`` (``time``, ``probe``, ``temperature``), ``thermal`` (chamber air,
setpoint, power) and ``turntable`` (angles) — so code written for one reads the other. There
is no ``truth`` group: a recording has none.

Nothing here imports ``rlgsim.sim``.
"""

from __future__ import annotations

import os
import pathlib

import numpy as np

from rlgsim.ground.recording import Recording, is_recording, load_recording

__all__ = ["open_tree", "recording_tree", "SAMPLE_TIME", "SAMPLE_ELAPSED", "ELAPSED"]

#: Name of the per-sample time coordinate added on the ``sample`` dimension.
SAMPLE_TIME = "sample_time"


def _sample_coord(ds, rate_hz: float, n: int):
    """``ds`` with the coordinate ``sample_time`` = (k+1)/f on its ``sample`` dimension."""
    import xarray as xr
    try:
        from xarray.indexes import RangeIndex
        index = RangeIndex.linspace(1.0 / rate_hz, n / rate_hz, n, coord_name=SAMPLE_TIME,
                                    dim="sample") if n else None
    except (ImportError, AttributeError, TypeError):
        index = None
    if index is not None:
        coords = xr.Coordinates.from_xindex(index)
    else:
        coords = xr.Coordinates({SAMPLE_TIME: ("sample", (np.arange(n) + 1.0) / rate_hz)})
    out = ds.assign_coords(coords)
    out[SAMPLE_TIME].attrs.update(units="s", description="end of each sample interval, (k+1)/f")
    try:
        elapsed = _lazy_elapsed(n, rate_hz)
    except (ImportError, AttributeError, TypeError):      # an xarray without the backend API
        elapsed = xr.Variable(("sample",), _timedelta((np.arange(n) + 1.0) / rate_hz))
    return out.assign_coords({SAMPLE_ELAPSED: elapsed})


#: Name of the timedelta twin of ``sample_time`` (what ``resample`` needs).
SAMPLE_ELAPSED = "sample_elapsed"
#: Name of the timedelta twin of the slow ``time`` coordinate.
ELAPSED = "elapsed"


def _timedelta(seconds: np.ndarray) -> np.ndarray:
    """Seconds as ``timedelta64[ns]`` (rounded to the nanosecond)."""
    return np.round(np.asarray(seconds, dtype=np.float64) * 1e9).astype(np.int64).astype(
        "timedelta64[ns]")


def _lazy_elapsed(n: int, rate_hz: float):
    """The variable ``(k+1)/f`` as ``timedelta64[ns]`` on ``sample``, computed only for the
    rows read (xarray's lazily indexed backend array), so a long run costs no memory until a
    ``resample`` or selection reads it."""
    import xarray as xr
    from xarray.backends import BackendArray
    from xarray.core import indexing

    class _Elapsed(BackendArray):
        def __init__(self):
            self.shape = (n,)
            self.dtype = np.dtype("timedelta64[ns]")

        def __getitem__(self, key):
            return indexing.explicit_indexing_adapter(key, self.shape,
                                                      indexing.IndexingSupport.BASIC,
                                                      self._rows)

        def _rows(self, key):
            k = key[0] if isinstance(key, tuple) else key
            rows = (np.arange(*k.indices(n), dtype=np.float64) if isinstance(k, slice)
                    else np.asarray(k, dtype=np.float64))
            return _timedelta((rows + 1.0) / rate_hz)
    return xr.Variable(("sample",), indexing.LazilyIndexedArray(_Elapsed()),
                       {"description": "sample_time as a timedelta (for resample)"})


def _with_elapsed(ds):
    """``ds`` with ``elapsed`` (timedelta64) beside a float ``time`` coordinate in seconds."""
    if "time" in ds.coords and ELAPSED not in ds.coords and ds["time"].ndim == 1 \
            and ds["time"].dtype.kind == "f":
        ds = ds.assign_coords({ELAPSED: (ds["time"].dims, _timedelta(ds["time"].values), {
            "description": "time as a timedelta (for resample)"})})
    return ds


def open_tree(path: str | os.PathLike, *, load: bool = False):
    """Open a dataset (checked like every reader: format marker and version) or a recording as
    an :class:`xarray.DataTree`. ``load=True`` reads everything into memory and closes the file
    (a recording is always in memory)."""
    if is_recording(path):
        return recording_tree(load_recording(path))
    import xarray as xr

    from rlgsim.ground.dataset_format import open_dataset
    with open_dataset(path) as ds:                     # marker and version, one-line errors
        rate = float(ds.attrs.get("sample_rate_hz", 0.0) or 0.0)
    tree = xr.open_datatree(path, engine="h5netcdf")
    nodes = {}
    for node in tree.subtree:
        name = node.path
        d = node.to_dataset(inherit=False)
        if name == "/timeline":
            if "attrs" in d.data_vars and "details" not in d.data_vars:
                d = d.rename_vars({"attrs": "details"})
            d = d.set_coords([c for c in ("t0", "t1", "setpoint_time") if c in d])
        elif name == "/calibration":
            d = d.set_coords([c for c in ("t0", "t1") if c in d])
        if "sample" in d.dims and SAMPLE_TIME not in d.coords:
            f = float(d.attrs.get("sample_rate_hz", rate) or rate)
            d = _sample_coord(d, f, d.sizes["sample"])
        nodes[name] = _with_elapsed(d)
    out = xr.DataTree.from_dict(nodes, name=tree.name)
    out.set_close(tree.close)
    if load:
        out = out.load()
        tree.close()
    return out


def recording_tree(rec: Recording):
    """The :class:`xarray.DataTree` of a loaded recording (see the module docstring)."""
    import xarray as xr
    sc = rec.sidecar
    root = {"rlgsim_format": "rlgsim recording", "source_file": str(rec.path),
            "sidecar_file": str(sc.path), "description": sc.description,
            "sample_rate_hz": sc.sample_rate_hz, "latitude_deg": sc.latitude_deg,
            "height_m": sc.height_m}
    if sc.gyro_sf_pulse_per_arcsec is not None:
        root["gyro_sf_pulse_per_arcsec"] = sc.gyro_sf_pulse_per_arcsec
    if sc.accel_sf_pulse_per_s_per_g is not None:
        root["accel_sf_pulse_per_s_per_g"] = sc.accel_sf_pulse_per_s_per_g
    if sc.temperature_rate_hz is not None:
        root["temperature_rate_hz"] = sc.temperature_rate_hz
    t_slow, _ = rec.probes()
    imu = xr.Dataset(attrs={"description": "the recorded sensor outputs",
                            "sample_rate_hz": sc.sample_rate_hz})
    imu = imu.assign_coords({SAMPLE_TIME: ("sample", rec.time_s, {
        "units": "s", "description": "end of each sample interval (the recording's time_s)"}),
        SAMPLE_ELAPSED: ("sample", _timedelta(rec.time_s), {
            "description": "sample_time as a timedelta (for resample)"})})
    for kind, axes, what in (("gyro", rec.gyro_axes, "gyro"), ("accel", rec.accel_axes,
                                                                "accelerometer")):
        if not axes:
            continue
        units = {rec.kinds[rec._column_of(kind, a)[0]][1] for a in axes}
        imu = imu.assign_coords({kind: (kind, axes, {"description": f"{what} input axis"})})
        if units == {"pulses"}:
            data = rec.gyro_pulses() if kind == "gyro" else rec.accel_pulses()
            imu[f"{kind}_pulses"] = (("sample", kind), data, {
                "units": "1", "description": f"{what} pulses per sample (NaN in dropouts)"})
        elif kind == "gyro":
            imu["gyro_rate"] = (("sample", "gyro"), rec.gyro_rate_deg_per_h(), {
                "units": "degree h-1", "description": "mean gyro rate over the sample"})
        else:
            imu["specific_force"] = (("sample", "accel"), rec.accel_m_per_s2(), {
                "units": "m s-2", "description": "mean specific force over the sample"})
            if sc.accel_sf_pulse_per_s_per_g is not None:
                imu["accel_pulses"] = (("sample", "accel"), rec.accel_pulses(), {
                    "units": "1", "description": f"accelerometer pulses per sample at the "
                                                 f"nominal {sc.accel_sf_pulse_per_s_per_g:g} "
                                                 f"pulses/s/g (not whole numbers)"})
    imu["dropout"] = (("sample",), rec.dropout.astype(np.int8), {
        "units": "1", "description": "1: the sample's values are missing"})
    uhfo = {(g.get("axis") or (rec.gyro_axes[0] if rec.gyro_axes else "x")): name
            for name, (k, _, g) in rec.kinds.items() if k == "uhfo"}
    if uhfo:
        # one column per gyro axis; a gyro without a UHFO column is NaN (a three-gyro log may
        # carry only uhfo_z_v)
        axes = list(rec.gyro_axes) or list(uhfo)
        imu = imu.assign_coords(time=("time", t_slow, {"units": "s"}))
        if "gyro" not in imu.coords:
            imu = imu.assign_coords(gyro=("gyro", axes))
        vals = np.full((t_slow.size, len(axes)), np.nan)
        for i, a in enumerate(axes):
            if a in uhfo:
                vals[:, i] = rec.slow(uhfo[a])[1]
        imu["uhfo"] = (("time", "gyro"), vals, {
            "units": "V", "description": "logged UHFO voltage (NaN for a gyro without one)"})
    groups = {"/": xr.Dataset(attrs=root), "/imu": imu}
    names = rec.probe_names
    if names:
        _, temps = rec.probes()
        groups["/probes"] = xr.Dataset(
            {"temperature": (("time", "probe"), temps, {"units": "degC",
                                                         "description": "probe reading"})},
            coords={"time": ("time", t_slow, {"units": "s"}), "probe": names},
            attrs={"description": "thermometer readings"})
    thermal = {}
    for col, var, units in (("chamber_air_c", "chamber_air", "degC"),
                            ("chamber_setpoint_c", "chamber_setpoint", "degC"),
                            ("power_on", "power_on", "1")):
        if col in rec.columns:
            thermal[var] = (("time",), rec.slow(col)[1], {"units": units})
    if thermal:
        groups["/thermal"] = xr.Dataset(thermal, coords={"time": ("time", t_slow, {"units": "s"})},
                                        attrs={"description": "chamber"})
    table = {}
    for col, var in (("outer_angle_deg", "outer_angle"), ("inner_angle_deg", "inner_angle")):
        if col in rec.columns:
            table[var] = (("time",), rec.slow(col)[1], {"units": "degree"})
    if table:
        groups["/turntable"] = xr.Dataset(table, coords={"time": ("time", t_slow,
                                                                  {"units": "s"})},
                                          attrs={"description": "turntable angles"})
    return xr.DataTree.from_dict({k: _with_elapsed(v) for k, v in groups.items()})


def is_path(x) -> bool:
    return isinstance(x, (str, os.PathLike, pathlib.Path))
