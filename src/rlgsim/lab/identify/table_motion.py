"""The turntable's true input rate on the identified gyro's axis, per gyro sample, from what a
run records of the table: for an rlgsim dataset the turntable group's motions (start, end,
axis, signed rate; start angles from the timeline), for a recording its ``outer_angle_deg`` /
``inner_angle_deg`` columns (docs/recordings.md).

Both become *knots*: times with the two table angles, unwrapped, the angles linear in between
(a dataset's motions are constant-rate by construction, :mod:`rlgsim.sim.motion.turntable`; between
two readings of a recording the table is taken to turn at a constant rate, which holds
exactly inside a constant-rate motion and needs the table to turn less than 180° between
readings so that the unwrap is unambiguous). Per sample ``[j/f, (j+1)/f)``:

- the table rate on the gyro axis ``a`` (a unit vector in body axes): ``a·(o·ΔO + e_z·ΔI)/Δt``
  with ΔO, ΔI the outer and inner angle increments over the sample and ``o`` the outer axis in
  body axes at the sample's inner angle (:func:`rlgsim.ground.frames.body_axis`);
- the Earth rate on the gyro axis through the table attitude at the sample's mid-time,
  ``(C_b^n a)·ω_ie^n`` (:func:`rlgsim.ground.frames.body_to_enu`,
  :func:`rlgsim.ground.earth.earth_rate_enu`).

Constant-rate *segments* (the rate-table scale-factor test, IEEE Std 1431-2004 §§ on scale
factor, IEEE Std 647-2006 §A) are maximal runs of knot intervals with the same pair of table
rates, the table turning; their samples are the ones lying wholly inside.

Units: rates in °/h (the gyro's), angles in °, times in s from the run's start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rlgsim.ground.dataset_format import TIMELINE, TURNTABLE
from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG, earth_rate_enu
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import body_to_enu
from rlgsim.ground.units import DEG, HOUR

__all__ = ["TableMotion", "motion_from_dataset", "motion_from_recording", "ANGLE_COLUMNS"]

#: the recording columns a turntable's motion is read from
ANGLE_COLUMNS = ("outer_angle_deg", "inner_angle_deg")

_DEG_PER_H = DEG / HOUR          # rad/s per °/h
#: a segment's table rate on the gyro axis below this [°/s] is a turn about a perpendicular
#: axis (cos 90° in floating point), not a rate segment
MIN_RATE_DEG_S = 1e-9
#: two reading intervals belong to one constant-rate run when their rates agree to this
#: relative tolerance (or RATE_ATOL_DEG_S): far above logged-angle jitter, far below a step
RATE_RTOL = 1e-3
RATE_ATOL_DEG_S = 1e-6
_CHUNK = 1 << 16


@dataclass(frozen=True)
class TableMotion:
    """The table as the gyro sees it: per sample (N,) ``input_deg_per_h`` (table + Earth rate
    on the gyro axis), ``table_deg_per_h`` (the table part), ``moving`` (the table turns during
    the sample); ``segments`` (k, 2) sample index ranges ``[i0, i1)`` at one constant table
    rate, ``segment_rate_deg_s`` (k,) that rate on the gyro axis [°/s]; ``origin`` says what
    it was read from."""

    input_deg_per_h: np.ndarray
    table_deg_per_h: np.ndarray
    moving: np.ndarray
    segments: np.ndarray
    segment_rate_deg_s: np.ndarray
    origin: str


def _unit_axis(axis: str) -> np.ndarray:
    e = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
    return np.array(e[axis])


def _from_knots(t_k: np.ndarray, outer_k: np.ndarray, inner_k: np.ndarray, n: int, f: float,
                axis_vec: np.ndarray, latitude_deg: float, origin: str) -> TableMotion:
    """Per-sample rates and constant-rate segments from knots (module docstring); angles
    before the first knot and after the last are held."""
    dt = 1.0 / f
    edges = np.arange(n + 1) * dt
    O = np.interp(edges, t_k, outer_k)
    I = np.interp(edges, t_k, inner_k)
    d_o, d_i = np.diff(O), np.diff(I)
    mid_i = 0.5 * (I[1:] + I[:-1])
    mid_o = 0.5 * (O[1:] + O[:-1])
    a = axis_vec
    # outer axis in body axes (cos i, −sin i, 0) (rlgsim.ground.frames.body_axis), vectorised
    table = (a[0] * np.cos(mid_i * DEG) - a[1] * np.sin(mid_i * DEG)) * d_o + a[2] * d_i
    table_deg_per_h = table / dt * 3600.0
    w_n = earth_rate_enu(latitude_deg) / _DEG_PER_H
    earth = np.empty(n)
    for s in range(0, n, _CHUNK):
        c = body_to_enu(mid_o[s:s + _CHUNK], mid_i[s:s + _CHUNK])      # (m, 3, 3)
        earth[s:s + _CHUNK] = (c @ a) @ w_n
    moving = (d_o != 0.0) | (d_i != 0.0)
    # constant-rate segments: runs of knot intervals with the same two rates, table turning
    dtk = np.diff(t_k)
    ok = dtk > 0
    r_o = np.where(ok, np.diff(outer_k) / np.where(ok, dtk, 1.0), 0.0)
    r_i = np.where(ok, np.diff(inner_k) / np.where(ok, dtk, 1.0), 0.0)
    # an interval continues the previous one's run when both rates agree to RATE_RTOL: logged
    # angles carry encoder resolution and time-stamp jitter (1e-4° over 1 s at 10 °/s is 1e-5
    # of the rate), while the programme's rate steps and acceleration phases change the rate
    # by far more; each run's rate is then the mean of the table's own rate over it (exact)
    turning = ok & ((r_o != 0.0) | (r_i != 0.0))
    cont = (turning[1:] & turning[:-1]
            & np.isclose(r_o[1:], r_o[:-1], rtol=RATE_RTOL, atol=RATE_ATOL_DEG_S)
            & np.isclose(r_i[1:], r_i[:-1], rtol=RATE_RTOL, atol=RATE_ATOL_DEG_S))
    first = np.flatnonzero(turning & ~np.concatenate(([False], cont)))
    last = np.flatnonzero(turning & ~np.concatenate((cont, [False])))
    segs, rates = [], []
    for k, j in zip(first, last + 1):                # one pass per run, not per reading
        ta, tb = t_k[k], t_k[j]
        i0 = int(np.ceil(ta * f - 1e-6))
        i1 = min(int(np.floor(tb * f + 1e-6)), n)
        if i1 - i0 >= 2:
            rate = float(np.mean(table_deg_per_h[i0:i1])) / 3600.0
            if abs(rate) > MIN_RATE_DEG_S:          # not a turn about an axis ⟂ the gyro
                segs.append((i0, i1))
                rates.append(rate)
    return TableMotion(input_deg_per_h=table_deg_per_h + earth, table_deg_per_h=table_deg_per_h,
                       moving=moving, segments=np.array(segs, dtype=np.int64).reshape(-1, 2),
                       segment_rate_deg_s=np.array(rates), origin=origin)


def motion_from_dataset(ds, axis: str, n: int, f: float) -> TableMotion | None:
    """The motion of an rlgsim dataset (open :class:`rlgsim.ground.dataset_format.Dataset`
    ``ds``) for the gyro on body axis ``axis``; None when the table never turns."""
    if not ds.has(TURNTABLE, "motion_t0"):
        return None
    t0 = np.asarray(ds.read(TURNTABLE, "motion_t0"), dtype=float)
    t1 = np.asarray(ds.read(TURNTABLE, "motion_t1"), dtype=float)
    rate = np.asarray(ds.read(TURNTABLE, "motion_rate"), dtype=float)
    ax = ds.strings(TURNTABLE, "motion_axis")
    if not np.any(rate != 0.0):
        return None
    o0 = i0 = 0.0
    if ds.has(TIMELINE, "track"):
        first = ds.segments("turntable")[:1]
        if first:
            d = first[0]["attrs"]
            o0, i0 = float(d.get("outer_deg", 0.0)), float(d.get("inner_deg", 0.0))
    t_k = [t0[0]]
    o_k, i_k = [o0], [i0]
    for a, r, s, e in zip(ax, rate, t0, t1):
        o, i = o_k[-1], i_k[-1]
        if a == "outer":
            o += r * (e - s)
        elif a == "inner":
            i += r * (e - s)
        t_k.append(e)
        o_k.append(o)
        i_k.append(i)
    lat = float(ds.attrs.get("latitude_deg", DEFAULT_LATITUDE_DEG))
    return _from_knots(np.array(t_k), np.array(o_k), np.array(i_k), n, f, _unit_axis(axis),
                       lat, "the dataset's turntable motions")


def motion_from_recording(rec, axis: str) -> tuple[TableMotion | None, str]:
    """The motion of a recording (:class:`rlgsim.ground.recording.Recording`) for its gyro
    ``axis``: (motion or None, why none). The gyro's input axis is the sidecar's
    ``[orientation]`` (at table zero, = body axes); the angles are unwrapped between readings
    (the table must turn less than 180° from one reading to the next)."""
    have = [c for c in ANGLE_COLUMNS if c in rec.columns]
    if not have:
        return None, ("the recording has no turntable angle columns (" + ", ".join(ANGLE_COLUMNS)
                      + "), so any turntable motion in it cannot be used; identifying the scale "
                        "factor needs those columns, read at the temperature rate or faster "
                        "with the table turning less than 180° between readings, through rate "
                        "segments on a turntable at several temperatures")
    t = None
    ang = {}
    for c in ANGLE_COLUMNS:
        if c in rec.columns:
            tc, v = rec.slow(c)
            good = np.isfinite(v)
            t = tc[good] if t is None else t
            if not good.all() or t.size != good.sum():
                raise UserInputError(f"{rec.path}: column {c!r}: the turntable angles have "
                                     f"missing readings; identification with turntable motion "
                                     f"needs every angle reading")
            ang[c] = np.unwrap(v[good], period=360.0)
        else:
            ang[c] = None
    o = ang["outer_angle_deg"] if ang["outer_angle_deg"] is not None else np.zeros(t.size)
    i = ang["inner_angle_deg"] if ang["inner_angle_deg"] is not None else np.zeros(t.size)
    if np.ptp(o) == 0.0 and np.ptp(i) == 0.0 and o[0] == 0.0 and i[0] == 0.0:
        return None, ""                       # a static table at zero: window_table's Earth
    default = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}
    a = rec.sidecar.orientation.get(axis, default.get(axis))
    if a is None:
        raise UserInputError(f"{rec.sidecar.path}: orientation.{axis} missing; give the gyro "
                             f"{axis}'s input axis as [east, north, up]")
    t_rel = t - rec.start_s
    return _from_knots(t_rel, o, i, rec.n_samples, rec.sample_rate_hz, np.asarray(a, float),
                       rec.sidecar.latitude_deg, "the recording's turntable angles"), ""
