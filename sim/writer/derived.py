"""Derived datasets: a copy of a simulated dataset with its IMU pulses rewritten (paper 000's
system-level compensation, :mod:`rlgsim.lab.studies.paper000_compensation`). The writer's room,
as every HDF5 write of a dataset is: the copy keeps the format marker, every group and attribute
of the original, and the pulse datasets' chunks and compression.

The copy is the original file's bytes (:func:`shutil.copyfile`) with the pulses then overwritten
in place: copying object by object (``h5py.Group.copy``, HDF5's ``H5Ocopy``) would carry each
variable's ``DIMENSION_LIST`` and each scale's ``REFERENCE_LIST`` over as references into the
*source* file, which dereference to garbage in the copy (xarray, ``rlgsim info`` and h5py's
``.dims`` then fail on it); a byte copy keeps every reference valid and every dimension attached.
"""

from __future__ import annotations

import pathlib
import shutil
from typing import Any, Callable

import h5py
import numpy as np

from rlgsim.ground.atomic import atomic_file

__all__ = ["rewrite_pulses"]


def rewrite_pulses(src: pathlib.Path, dst: pathlib.Path,
                   make_transform: Callable[[str], Callable[[int, np.ndarray], np.ndarray]],
                   *, title_suffix: str, attrs: dict[str, Any], chunk: int) -> pathlib.Path:
    """Write a copy of dataset ``src`` to ``dst`` (atomically) whose ``imu/<sensor>_pulses``
    (sensor "gyro", then "accel") are rewritten ``chunk`` samples at a time by
    ``make_transform(sensor)``, a function ``(first sample, pulses (samples × axes)) -> new
    pulses`` called block by block in sample order (stored in place: the original's type, chunks
    and compression); every other group and attribute is copied unchanged, the root's ``title``
    gets ``title_suffix`` and ``attrs`` are added to the root."""
    with atomic_file(dst, sep="") as tmp:
        shutil.copyfile(src, tmp)
        with h5py.File(tmp, "r+") as fd:
            fd.attrs["title"] = f"{fd.attrs.get('title', '')}{title_suffix}"
            for k, v in attrs.items():
                fd.attrs[k] = v
            imu = fd["imu"]
            n = imu["gyro_pulses"].shape[0]
            for sensor in ("gyro", "accel"):
                pulses = imu[f"{sensor}_pulses"]
                transform = make_transform(sensor)
                for k0 in range(0, n, chunk):
                    k1 = min(n, k0 + chunk)
                    pulses[k0:k1] = transform(k0, pulses[k0:k1])
    return dst
