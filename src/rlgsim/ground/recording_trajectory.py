"""A drive's truth as a recording table (``rlgsim export`` of a run on a vehicle,
docs/recordings.md): the dataset's group ``trajectory`` (docs/dataset.md) per IMU sample, on the
pulses' ``time_s`` — position, ENU velocity, heading/pitch/roll, GNSS visibility — written
beside the pulses in the same format; the sidecar names it (``[recording] trajectory``) and says
``platform = "vehicle"``, which the readers that take a fixed site refuse."""

from __future__ import annotations

import numpy as np

from rlgsim.ground.errors import UserInputError

__all__ = ["TRAJECTORY_COLUMNS", "check_trajectory", "trajectory_blocks"]

#: the trajectory table's columns: (column, variable of group ``trajectory``, its column)
TRAJECTORY_COLUMNS = (("latitude_deg", "latitude", None), ("longitude_deg", "longitude", None),
                      ("height_m", "height", None), ("velocity_east_m_s", "velocity", 0),
                      ("velocity_north_m_s", "velocity", 1), ("velocity_up_m_s", "velocity", 2),
                      ("heading_deg", "heading", None), ("pitch_deg", "pitch", None),
                      ("roll_deg", "roll", None), ("gnss_visible", "gnss_visible", None))


def check_trajectory(ds, n: int) -> None:
    """One line (before anything is written) when a variable of the drive's truth is missing
    or not one value (or one ENU row) per IMU sample."""
    from rlgsim.ground.dataset_format import TRAJECTORY
    for _, var, col in TRAJECTORY_COLUMNS:
        shape = ds.read(TRAJECTORY, var, slice(0, 1)).shape
        if ds.length(TRAJECTORY, var) != n or len(shape) != (1 if col is None else 2) or (
                col is not None and shape[1] != 3):
            raise UserInputError(f"{ds.path}: trajectory/{var} is not one value per IMU sample "
                                 f"({n}); a damaged dataset?")


def trajectory_blocks(ds, n: int, rate: float, block_rows: int):
    """A drive's truth per IMU sample (docs/dataset.md, group trajectory) as table blocks, on
    the pulses' ``time_s``."""
    import pandas as pd

    from rlgsim.ground.dataset_format import TRAJECTORY
    for k0 in range(0, n, block_rows):
        k1 = min(n, k0 + block_rows)
        data = {"time_s": (np.arange(k0, k1, dtype=np.float64) + 1.0) / rate}
        for name, var, col in TRAJECTORY_COLUMNS:
            v = ds.read(TRAJECTORY, var, slice(k0, k1))
            data[name] = v if col is None else v[:, col]
        yield pd.DataFrame(data)
