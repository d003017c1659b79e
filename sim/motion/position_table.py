"""A route as a table of timed positions and attitudes (CSV or Parquet), interpolated smoothly.

Columns (units in the names, as in recordings): ``time_s``, ``latitude_deg``, ``longitude_deg``,
``height_m``, ``heading_deg``, ``pitch_deg``, ``roll_deg`` (heading from North clockwise, pitch
nose up, roll right wing down; docs/trajectories.md). Each of the six is interpolated by a cubic
spline in time (scipy's :class:`~scipy.interpolate.CubicSpline`, not-a-knot ends): twice
continuously differentiable, so the vehicle's acceleration and its angular rate are continuous
(the spline's second derivative of position and first of the angles). Heading is unwrapped
first (a step of more than 180° between rows is read as the shorter way round). Each row
interval becomes one leg whose last three channels are the geodetic position itself
(:class:`rlgsim.sim.motion.legs.Leg` ``frame = "geodetic"``): the velocity and its rate follow
from the spline's derivatives through the radii of curvature (sim/motion/trajectory.py).

Refused, one line naming file, row and column: a missing column, a non-number (booleans and
dates included: the columns are numbers in the units their names give), times not strictly
increasing, |latitude| ≥ 89.9°, a height outside the Earth model's
(:data:`rlgsim.sim.motion.site.MIN_HEIGHT_M` … ``MAX_HEIGHT_M``), fewer than 4 rows or more
than :data:`rlgsim.sim.motion.legs.MAX_LEGS` + 1, and a **discontinuous table** — two
rows whose straight-line distance needs a speed above ``max_speed_m_s`` (default 1000 m/s: a
judgement, faster than any aircraft an RLG INS flies in) or whose attitude turns faster than
the gyros' range.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np

from rlgsim.ground.earth import radii_of_curvature_rad
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import DEG
from rlgsim.sim.motion.legs import DEGREE, MAX_LEGS, N_CHANNELS, TOO_MANY_LEGS_ADVICE, Leg
from rlgsim.sim.motion.site import MAX_HEIGHT_M, MIN_HEIGHT_M

COLUMNS = ("time_s", "latitude_deg", "longitude_deg", "height_m", "heading_deg", "pitch_deg",
           "roll_deg")
DEFAULT_MAX_SPEED_M_S = 1000.0
MAX_LATITUDE_DEG = 89.9


def _read(path: pathlib.Path):
    import pandas as pd
    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            from rlgsim.ground.recording_columns import need_pyarrow
            need_pyarrow(path, "reading")           # an optional dependency: one line
            return pd.read_parquet(path)
        df = pd.read_csv(path, skipinitialspace=True)        # "time_s, latitude_deg, ..."
        return df.rename(columns=lambda c: c.strip() if isinstance(c, str) else c)
    except (OSError, ValueError, UnicodeDecodeError) as e:
        raise UserInputError(f"{path}: cannot read the position table "
                             f"({str(e).splitlines()[0] if str(e) else type(e).__name__})"
                             ) from None


def read_position_table(path: str | pathlib.Path, *, max_speed_m_s: float = DEFAULT_MAX_SPEED_M_S,
                        max_rate_rad_s: float = math.inf
                        ) -> tuple[tuple[float, float, float], tuple[Leg, ...], float]:
    """The table at ``path`` as (start (L, λ [rad], h [m]), legs, first time [s]); the legs
    start at the table's first time, which the run's t = 0 is."""
    p = pathlib.Path(path)
    df = _read(p)
    missing = [c for c in COLUMNS if c not in df.columns]
    if missing:
        raise UserInputError(f"{p}: missing column {missing[0]!r}; a position table has "
                             f"{', '.join(COLUMNS)}")
    if len(df) > MAX_LEGS + 1:
        raise UserInputError(f"{p}: {len(df)} rows; a position table takes at most "
                             f"{MAX_LEGS + 1}: {TOO_MANY_LEGS_ADVICE}")
    data = np.empty((len(df), len(COLUMNS)))
    for j, c in enumerate(COLUMNS):
        if df[c].dtype.kind in "bmM":               # booleans, durations, dates: not numbers
            raise UserInputError(f"{p}: column {c}: {df[c].dtype} values; expected numbers in "
                                 f"the unit the column's name gives")
        col = df[c].to_numpy()
        try:
            data[:, j] = col.astype(float)
        except (TypeError, ValueError):
            bad = next(i for i, v in enumerate(col) if not _is_number(v))
            raise UserInputError(f"{p}: row {bad + 1}, column {c}: {col[bad]!r} is not a "
                                 f"number") from None
        bad = np.flatnonzero(~np.isfinite(data[:, j]))
        if bad.size:
            value = data[bad[0], j]
            raise UserInputError(f"{p}: row {bad[0] + 1}, column {c}: "
                                 f"{'empty or NaN' if np.isnan(value) else f'{value:g}'}; "
                                 f"expected a finite number")
    if len(df) < 4:
        raise UserInputError(f"{p}: a position table needs at least 4 rows, got {len(df)}")
    low = np.flatnonzero((data[:, 3] < MIN_HEIGHT_M) | (data[:, 3] > MAX_HEIGHT_M))
    if low.size:
        raise UserInputError(f"{p}: row {low[0] + 1}, column height_m: {data[low[0], 3]:g} not "
                             f"allowed; must be in [{MIN_HEIGHT_M:g}, {MAX_HEIGHT_M:g}]")
    t = data[:, 0]
    step = np.diff(t)
    if np.any(step <= 0):
        i = int(np.argmax(step <= 0)) + 1
        raise UserInputError(f"{p}: row {i + 1}, column time_s: {t[i]:g} s is not after the "
                             f"row before ({t[i - 1]:g} s); times must increase strictly")
    lat = data[:, 1]
    far = np.flatnonzero(np.abs(lat) >= MAX_LATITUDE_DEG)
    if far.size:
        raise UserInputError(f"{p}: row {far[0] + 1}, column latitude_deg: {lat[far[0]]:g} not "
                             f"allowed; |latitude| < {MAX_LATITUDE_DEG:g} (the ENU frame is "
                             f"singular at the poles)")
    lat_r, lon_r, h = lat * DEG, np.unwrap(data[:, 2] * DEG), data[:, 3]
    rm, rn = radii_of_curvature_rad(lat_r)
    dist = np.hypot(np.diff(lat_r) * (rm[:-1] + h[:-1]),
                    np.diff(lon_r) * (rn[:-1] + h[:-1]) * np.cos(lat_r[:-1]))
    dist = np.hypot(dist, np.diff(h))
    fast = np.flatnonzero(dist / step > max_speed_m_s)
    if fast.size:
        i = int(fast[0]) + 1
        raise UserInputError(f"{p}: row {i + 1}: the position jumps {dist[i - 1]:.4g} m in "
                             f"{step[i - 1]:.4g} s after the row before ({dist[i - 1] / step[i - 1]:.4g} "
                             f"m/s, above max_speed_m_s = {max_speed_m_s:g}): a discontinuous "
                             f"table")
    angles = np.stack([np.unwrap(data[:, 4] * DEG), data[:, 5] * DEG, data[:, 6] * DEG])
    turn = np.max(np.abs(np.diff(angles, axis=1)), axis=0) / step
    fast = np.flatnonzero(turn > max_rate_rad_s)
    if fast.size:
        i = int(fast[0]) + 1
        raise UserInputError(f"{p}: row {i + 1}: the attitude turns {turn[i - 1] / DEG:.4g} °/s "
                             f"from the row before, past the gyros' range "
                             f"({max_rate_rad_s / DEG:g} °/s): a discontinuous table")
    from scipy.interpolate import CubicSpline
    channels = np.vstack([angles, lat_r, lon_r, h])                     # (6, rows)
    spline = CubicSpline(t - t[0], channels, axis=1)
    # spline.c: (4, intervals, 6), highest power first, in the interval's own time
    coef = np.zeros((len(step), N_CHANNELS, DEGREE + 1))
    for k in range(4):
        coef[:, :, k] = spline.c[3 - k]
    legs = tuple(Leg(float(step[i]), coef[i], "table", f"rows {i + 1}-{i + 2}", True, "geodetic")
                 for i in range(len(step)))
    return (float(lat_r[0]), float(lon_r[0]), float(h[0])), legs, float(t[0])


def _is_number(v) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True
