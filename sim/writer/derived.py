"""Derived datasets: a copy of a simulated dataset with its IMU pulses rewritten (paper 000's
system-level compensation, :mod:`rlgsim.lab.studies.paper000_compensation`). The writer's room,
as every HDF5 write of a dataset is: the copy keeps the format marker, every group and attribute
of the original, and the pulse datasets' chunks and compression.
"""

from __future__ import annotations

import os
import pathlib
from typing import Any, Callable

import h5py
import numpy as np

__all__ = ["rewrite_pulses"]


def rewrite_pulses(src: pathlib.Path, dst: pathlib.Path,
                   make_transform: Callable[[str], Callable[[int, np.ndarray], np.ndarray]],
                   *, title_suffix: str, attrs: dict[str, Any], chunk: int) -> pathlib.Path:
    """Write a copy of dataset ``src`` to ``dst`` (atomically) whose ``imu/<sensor>_pulses``
    (sensor "gyro", then "accel") are rewritten ``chunk`` samples at a time by
    ``make_transform(sensor)``, a function ``(first sample, pulses (samples × axes)) -> new
    pulses`` called block by block in sample order (stored as int32 with the original's chunks
    and compression); every other group and attribute is copied unchanged, the root's ``title``
    gets ``title_suffix`` and ``attrs`` are added to the root."""
    tmp = dst.with_name(f".{dst.name}.tmp{os.getpid()}")
    with h5py.File(src, "r") as fs, h5py.File(tmp, "w") as fd:
        for k, v in fs.attrs.items():
            fd.attrs[k] = v
        fd.attrs["title"] = f"{fs.attrs.get('title', '')}{title_suffix}"
        for k, v in attrs.items():
            fd.attrs[k] = v
        for name in fs:
            if name != "imu":
                fs.copy(fs[name], fd, name=name)
        gi, go = fs["imu"], fd.create_group("imu")
        for k, v in gi.attrs.items():
            go.attrs[k] = v
        for name in gi:
            if name not in ("gyro_pulses", "accel_pulses"):
                gi.copy(gi[name], go, name=name)
        n = gi["gyro_pulses"].shape[0]
        for sensor in ("gyro", "accel"):
            src_ds = gi[f"{sensor}_pulses"]
            out = go.create_dataset(f"{sensor}_pulses", shape=src_ds.shape, dtype="int32",
                                    chunks=src_ds.chunks, scaleoffset=0)
            for k, v in src_ds.attrs.items():
                if k not in ("DIMENSION_LIST", "REFERENCE_LIST"):
                    out.attrs[k] = v
            transform = make_transform(sensor)
            for k0 in range(0, n, chunk):
                k1 = min(n, k0 + chunk)
                out[k0:k1] = transform(k0, src_ds[k0:k1])
    os.replace(tmp, dst)
    return dst
