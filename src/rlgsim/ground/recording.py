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

The format is split along its seams: :mod:`~rlgsim.ground.recording_columns` (the column
grammar and one column's checks), :mod:`~rlgsim.ground.recording_sidecar` (the sidecar),
:mod:`~rlgsim.ground.recording_table` (:class:`Recording` and its views),
:mod:`~rlgsim.ground.recording_read` (:func:`load_recording`) and
:mod:`~rlgsim.ground.recording_write` (sidecar and table writers); this module gathers them.
"""

from __future__ import annotations

from rlgsim.ground.recording_columns import COLUMN_RULES, SLOW_KINDS
from rlgsim.ground.recording_read import (DATA_SUFFIXES, is_recording, is_sidecar,
                                          load_recording)
from rlgsim.ground.recording_sidecar import (RECORDING_FORMAT, RECORDING_VERSION, Sidecar,
                                             read_sidecar, sidecar_path)
from rlgsim.ground.recording_table import Recording
from rlgsim.ground.recording_write import write_sidecar, write_table

__all__ = ["RECORDING_FORMAT", "RECORDING_VERSION", "DATA_SUFFIXES", "COLUMN_RULES",
           "SLOW_KINDS", "Recording", "Sidecar", "load_recording", "read_sidecar",
           "is_recording", "is_sidecar", "sidecar_path", "write_sidecar", "write_table"]
