"""A scenario's ``[trajectory]`` table: a vehicle's route as segments, or a motion file.

Three forms (docs/trajectories.md lists every key):

* segments from an initial state — ``latitude_deg``, ``longitude_deg``, ``height_m``,
  ``speed_m_s`` (forward), ``heading_deg``, ``pitch_deg``, ``roll_deg`` — and
  ``[[trajectory.segment]]`` tables, each with a ``kind``, a duration (``duration_s``,
  ``duration_min`` or ``duration_h``) and ``gnss`` (the sky visible, default true):

  ========================  ==============================================================
  kind                      keys and what the vehicle does
  ========================  ==============================================================
  ``hold``                  keeps its attitude and body velocity (stands, or drives straight
                            at constant speed)
  ``accelerate``            ``accel_m_s2`` constant forward acceleration, or ``speed_m_s``
                            the forward speed reached smoothly over the segment
  ``turn``                  ``rate_deg_s`` constant heading rate, or ``by_deg`` the heading
                            change made smoothly over the segment
  ``climb``                 ``pitch_deg`` the pitch reached smoothly (then ``hold`` climbs)
  ``roll``                  ``roll_deg`` the roll reached smoothly
  ``coordinated_turn``      ``by_deg`` heading change at a constant rate r with the bank
                            φ = atan(v r / γ) of a turn without side force, rolled in and
                            out smoothly over ``roll_time_s`` (default 5 s) at either end
  ========================  ==============================================================

  ("smoothly" = the quintic of :func:`rlgsim.sim.motion.legs.smooth_leg`: rates zero at both
  ends.)
* ``file = "route.csv"``: gnss-ins-sim's motion-definition CSV (:mod:`rlgsim.sim.motion.motion_def`,
  relative to the scenario's folder), with its mobility limits ``max_accel_m_s2``,
  ``max_angular_accel_deg_s2``, ``max_rate_deg_s``;
* ``table = "route.parquet"``: a table of timed positions and attitudes (CSV or Parquet,
  :mod:`rlgsim.sim.motion.position_table`), cubic splines, with ``max_speed_m_s`` (default
  1000) above which two rows are a discontinuity.

Either form: ``gyro_range_deg_s`` (default 400 °/s) and ``accel_range_m_s2`` (default 200 m/s²),
the sensors' input ranges — a trajectory whose body rates or specific force go past them is
refused. (A navigation-grade RLG measures several hundred °/s — e.g. ±400 °/s — and its
accelerometers ±20–40 g: a judgement from typical data sheets; set your device's.)
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.paths import input_file
from rlgsim.ground.earth import WGS84_A, WGS84_E2, normal_gravity
from rlgsim.ground.units import DEG, EARTH_RATE
from rlgsim.sim.config import (TIME_UNITS, Ctx, check_known_keys, get_bool, get_float, get_list,
                               get_quantity, get_str, unit_keys)
from rlgsim.sim.motion.legs import MAX_LEGS, Leg, rate_leg, smooth_leg
from rlgsim.sim.motion.site import MAX_HEIGHT_M, MIN_HEIGHT_M
from rlgsim.sim.motion.trajectory import InitialState, Trajectory

_DURATION = unit_keys("duration", TIME_UNITS)
SEGMENT_KEYS: dict[str, tuple[str, ...]] = {
    "hold": (),
    "accelerate": ("accel_m_s2", "speed_m_s"),
    "turn": ("rate_deg_s", "by_deg"),
    "climb": ("pitch_deg",),
    "roll": ("roll_deg",),
    "coordinated_turn": ("by_deg", "roll_time_s"),
}
START_KEYS = ("latitude_deg", "longitude_deg", "height_m", "speed_m_s", "heading_deg",
              "pitch_deg", "roll_deg")
FILE_KEYS = ("file", "max_accel_m_s2", "max_angular_accel_deg_s2", "max_rate_deg_s")
RANGE_KEYS = ("gyro_range_deg_s", "accel_range_m_s2")
#: a judgement (module docstring): typical navigation-grade input ranges
DEFAULT_GYRO_RANGE_DEG_S = 400.0
DEFAULT_ACCEL_RANGE_M_S2 = 200.0


@dataclass(frozen=True)
class TrajectoryProgram:
    """A validated ``[trajectory]``: the start, the legs and the sensors' ranges."""

    initial: InitialState
    legs: tuple[Leg, ...]
    gyro_range_rad_s: float
    accel_range_m_s2: float
    source: str = ""

    @property
    def duration_s(self) -> float:
        return float(sum(leg.duration_s for leg in self.legs))

    def build(self, until_s: float) -> Trajectory:
        """The kinematics up to ``until_s`` (the run's end), checked against the sensors'
        ranges (one :class:`UserInputError` line); built once per ``until_s``."""
        cache = self.__dict__.setdefault("_built", {})
        if until_s not in cache:
            cache.clear()
            cache[until_s] = self._build(until_s)
        return cache[until_s]

    def _build(self, until_s: float) -> Trajectory:
        _check_legs(self.legs, until_s, self.gyro_range_rad_s, self.source)
        try:
            traj = Trajectory(self.legs, self.initial, until_s)
        except ValueError as e:
            raise UserInputError(f"{self.source}: trajectory: {e}") from None
        low, t_low, high, t_high = traj.height_extent()
        for h, at in ((low, t_low), (high, t_high)):
            if not MIN_HEIGHT_M <= h <= MAX_HEIGHT_M:
                raise UserInputError(
                    f"{self.source}: trajectory: the route reaches a height of {h:.6g} m at "
                    f"t = {at:.6g} s, outside the Earth model's heights [{MIN_HEIGHT_M:g}, "
                    f"{MAX_HEIGHT_M:g}] m")
        w, f, at = traj.peak_inputs(below=(self.gyro_range_rad_s, self.accel_range_m_s2))
        if w > self.gyro_range_rad_s:
            raise UserInputError(
                f"{self.source}: trajectory: body rate {w / DEG:.4g} °/s at t = {at:.6g} s is "
                f"past the gyros' range gyro_range_deg_s = {self.gyro_range_rad_s / DEG:g}")
        if f > self.accel_range_m_s2:
            raise UserInputError(
                f"{self.source}: trajectory: specific force {f:.4g} m/s² is past the "
                f"accelerometers' range accel_range_m_s2 = {self.accel_range_m_s2:g}")
        return traj

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx,
                    base_dir: pathlib.Path | None = None) -> "TrajectoryProgram":
        """Validate a scenario's ``[trajectory]`` table (module docstring)."""
        gyro_range = get_float(table, "gyro_range_deg_s", ctx, DEFAULT_GYRO_RANGE_DEG_S,
                               min=0.0, min_exclusive=True) * DEG
        accel_range = get_float(table, "accel_range_m_s2", ctx, DEFAULT_ACCEL_RANGE_M_S2,
                                min=0.0, min_exclusive=True)
        source = ctx.source or "<scenario>"
        if "table" in table:
            check_known_keys(table, ("table", "max_speed_m_s", *RANGE_KEYS), ctx)
            return cls(*_from_table(table, ctx, base_dir, gyro_range), gyro_range, accel_range,
                       source)
        if "file" in table:
            check_known_keys(table, (*FILE_KEYS, *RANGE_KEYS), ctx)
            return cls(*_from_file(table, ctx, base_dir), gyro_range, accel_range, source)
        check_known_keys(table, (*START_KEYS, "segment", *RANGE_KEYS), ctx)
        lat = get_float(table, "latitude_deg", ctx, min=-90.0, max=90.0)
        if abs(lat) >= 89.9:
            raise ctx.error("latitude_deg", f"value {lat:g} not allowed; the ENU frame is "
                                            f"singular at the poles: |latitude| < 89.9")
        lon = get_float(table, "longitude_deg", ctx, 0.0, min=-180.0, max=360.0)
        height = get_float(table, "height_m", ctx, 0.0, min=MIN_HEIGHT_M, max=MAX_HEIGHT_M)
        # a heading far past a turn loses the turns to rounding (1e20°: a 30° turn vanished)
        state = np.array([get_float(table, "heading_deg", ctx, 0.0, min=-360.0, max=360.0) * DEG,
                          get_float(table, "pitch_deg", ctx, 0.0, min=-90.0, max=90.0) * DEG,
                          get_float(table, "roll_deg", ctx, 0.0, min=-180.0, max=180.0) * DEG,
                          0.0, get_float(table, "speed_m_s", ctx, 0.0), 0.0])
        segs = get_list(table, "segment", ctx, min_len=1)
        if len(segs) > MAX_LEGS // 3:
            raise ctx.error("segment", f"{len(segs)} segments; a route takes at most "
                                       f"{MAX_LEGS // 3}")
        legs: list[Leg] = []
        gamma = normal_gravity(lat, height)
        for i, seg in enumerate(segs):
            sctx = ctx.child("segment").item(i)
            if not isinstance(seg, Mapping):
                raise sctx.error("", f"expected a table, got {seg!r:.40}")
            for leg in _segment_legs(seg, sctx, state, gamma):
                legs.append(leg)
                state = leg.end()
        if not legs:
            raise ctx.error("segment", "no segment of positive duration")
        return cls(InitialState(lat * DEG, lon * DEG, height), tuple(legs), gyro_range,
                   accel_range, source)


#: what ``[trajectory]``'s file keys name (for messages)
_INPUT_KINDS = {"file": "a motion definition (.csv)",
                "table": "a position table (.csv or .parquet)"}


def _input_path(table: Mapping[str, Any], key: str, ctx: Ctx, base_dir: pathlib.Path | None
                ) -> pathlib.Path:
    """The regular file named by ``table[key]`` (relative to ``base_dir``):
    :func:`rlgsim.ground.paths.input_file`'s refusals (missing, a folder, a FIFO or a device,
    unreadable, a name too long or with a NUL) in one line that names the key."""
    name = get_str(table, key, ctx)
    if not name:
        raise ctx.error(key, f"{name!r} not allowed; expected a file name")
    path = pathlib.Path(name)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    try:
        return input_file(path, _INPUT_KINDS[key])
    except UserInputError as e:
        raise ctx.error(key, str(e)) from None


#: fastest a vehicle may move [m/s]: the escape velocity (faster, nothing stays over the
#: ellipsoid the route is drawn on; the range check refuses far slower routes on its own)
MAX_SPEED_M_S = 11_200.0
#: where a leg is probed before the route is built, in parts of its duration: its ends, its
#: middle (a smooth leg's peak rate) and its rate of rate's peaks (Flash & Hogan's quintic)
_PROBES = np.array([0.0, 0.5 - math.sqrt(3.0) / 6.0, 0.5, 0.5 + math.sqrt(3.0) / 6.0, 1.0])


def _check_legs(legs: tuple[Leg, ...], until_s: float, gyro_range: float, source: str) -> None:
    """Refuse, before the route's position is integrated, the legs up to ``until_s`` that no
    vehicle in the sensors' range rides: rates that are not finite numbers, a speed past
    :data:`MAX_SPEED_M_S`, or a body rate past the gyros' range however the Earth and transport
    rates add to it — at each probe ω_ib^b = ω_nb^b + C_n^b (ω_ie^n + ω_en^n), so its largest
    component ≥ that of ω_nb^b − Ω − |v|/((a(1 − e²) + h_min) cos 89.9°) for a route inside the
    Earth model's heights and latitudes (one outside them is refused after the integration).
    Without this a turn of 1e300° went to DOP853 and ended in a MemoryError after a minute.
    The legs are screened :data:`_SCREEN` at a time (200 000 legs in ~1 s instead of ~20 s one
    by one); a leg the screen flags is checked alone (:func:`_check_leg`), which words the
    line. The leg the run ends in is probed up to the run's end only (its probes past it moved
    to the end), as :meth:`Trajectory.peak_inputs` checks it: a turn's peak rate after the run
    is never simulated."""
    dur = np.array([leg.duration_s for leg in legs])
    t0 = np.concatenate([[0.0], np.cumsum(dur)[:-1]])
    m = int(np.searchsorted(t0, until_s, side="right"))        # the legs up to the run's end
    upto = np.minimum(dur[:m], until_s - t0[:m])               # each one's time in the run
    for lo in range(0, m, _SCREEN):
        hi = min(m, lo + _SCREEN)
        part = legs[lo:hi]
        for k in np.flatnonzero(_screen(part, upto[lo:hi], gyro_range)):
            _check_leg(lo + int(k), part[k], float(t0[lo + k]), float(upto[lo + k]),
                       gyro_range, source)


#: legs screened at once by :func:`_check_legs` (~10 kB each)
_SCREEN = 4096


def _probe_speed_rate(x: np.ndarray, xd: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                np.ndarray]:
    """At probes of legs' channels ``x`` and rates ``xd`` (6, k): the speed [m/s], ω_nb^b
    (k, 3) [rad/s] and the lower bound of ω_ib^b's largest component (:func:`_check_legs`)."""
    from rlgsim.sim.motion.position_table import MAX_LATITUDE_DEG
    from rlgsim.sim.motion.trajectory import attitude_rates
    w_en_per_speed = 1.0 / ((WGS84_A * (1.0 - WGS84_E2) + MIN_HEIGHT_M)
                            * math.cos(math.radians(MAX_LATITUDE_DEG)))
    with np.errstate(over="ignore", invalid="ignore"):
        speed = np.hypot(np.hypot(x[3], x[4]), x[5])
        _, w_nb = attitude_rates(x, xd)
        low = np.max(np.abs(w_nb), axis=1) - EARTH_RATE - speed * w_en_per_speed
    return speed, w_nb, low


def _screen(legs: tuple[Leg, ...], upto: np.ndarray, gyro_range: float) -> np.ndarray:
    """Per leg: True where :func:`_check_leg` may refuse it (its conditions on all legs at
    once, each probed up to ``upto`` [s] from its start; the probes evaluated as power sums, so
    a leg at the bound is flagged either way)."""
    coef = np.stack([leg.coef for leg in legs])                          # (k, 6, 6)
    finite = np.isfinite(coef).all(axis=(1, 2))
    body = np.array([leg.frame == "body" for leg in legs]) & finite
    tau = np.minimum(np.array([leg.duration_s for leg in legs])[:, None] * _PROBES,
                     upto[:, None])                                       # (k, p)
    powers = tau[:, :, None] ** np.arange(coef.shape[2])                 # (k, p, n)
    dpow = powers[:, :, :-1] * np.arange(1, coef.shape[2])
    c = np.where(body[:, None, None], coef, 0.0)
    with np.errstate(over="ignore", invalid="ignore"):
        x = np.einsum("kcn,kpn->ckp", c, powers).reshape(6, -1)
        xd = np.einsum("kcn,kpn->ckp", c[:, :, 1:], dpow).reshape(6, -1)
    speed, _, low = _probe_speed_rate(x, xd)
    p = _PROBES.size
    bad = ((speed.reshape(-1, p) > 0.999 * MAX_SPEED_M_S)
           | ~np.isfinite(low.reshape(-1, p)) | (low.reshape(-1, p) > 0.999 * gyro_range))
    return ~finite | (body & bad.any(axis=1))


def _check_leg(j: int, leg: Leg, t0: float, upto: float, gyro_range: float, source: str
               ) -> None:
    """:func:`_check_legs` of leg ``j`` starting at ``t0`` [s], probed up to ``upto`` [s] from
    its start: one line if it is refused."""
    where = f"{source}: trajectory: leg {j} ({leg.label}) at t = {t0:.6g} s"
    if not np.all(np.isfinite(leg.coef)):
        raise UserInputError(f"{where}: its rates are not finite numbers (the leg lasts "
                             f"{leg.duration_s:.6g} s)")
    if leg.frame != "body":
        return
    tau = np.minimum(leg.duration_s * _PROBES, upto)
    with np.errstate(over="ignore", invalid="ignore"):
        x, xd = leg.values(tau), leg.rates(tau)
    speed, w_nb, low = _probe_speed_rate(x, xd)
    if np.max(speed) > MAX_SPEED_M_S:
        raise UserInputError(f"{where}: speed {np.max(speed):.4g} m/s is past "
                             f"{MAX_SPEED_M_S:g} m/s (the escape velocity: no vehicle of "
                             f"this model)")
    if not np.all(np.isfinite(low)):
        raise UserInputError(f"{where}: its body rates are not finite numbers")
    k = int(np.argmax(low))
    if low[k] > gyro_range:
        raise UserInputError(
            f"{source}: trajectory: body rate {np.max(np.abs(w_nb[k])) / DEG:.4g} °/s at "
            f"t = {t0 + tau[k]:.6g} s (leg {j}, {leg.label}) is past the gyros' range "
            f"gyro_range_deg_s = {gyro_range / DEG:g}")


def _from_file(table: Mapping[str, Any], ctx: Ctx, base_dir: pathlib.Path | None
               ) -> tuple[InitialState, tuple[Leg, ...]]:
    from rlgsim.sim.motion.motion_def import DEFAULT_MOBILITY, read_motion_def
    path = _input_path(table, "file", ctx, base_dir)
    mob = (get_float(table, "max_accel_m_s2", ctx, DEFAULT_MOBILITY[0], min=0.0,
                     min_exclusive=True),
           get_float(table, "max_angular_accel_deg_s2", ctx, DEFAULT_MOBILITY[1] / DEG, min=0.0,
                     min_exclusive=True) * DEG,
           get_float(table, "max_rate_deg_s", ctx, DEFAULT_MOBILITY[2] / DEG, min=0.0,
                     min_exclusive=True) * DEG)
    md = read_motion_def(path, mobility=mob)
    return InitialState(md.lat_rad, md.lon_rad, md.height_m), md.legs


def _from_table(table: Mapping[str, Any], ctx: Ctx, base_dir: pathlib.Path | None,
                gyro_range: float) -> tuple[InitialState, tuple[Leg, ...]]:
    from rlgsim.sim.motion.position_table import DEFAULT_MAX_SPEED_M_S, read_position_table
    path = _input_path(table, "table", ctx, base_dir)
    speed = get_float(table, "max_speed_m_s", ctx, DEFAULT_MAX_SPEED_M_S, min=0.0,
                      min_exclusive=True)
    (lat, lon, h), legs, _ = read_position_table(path, max_speed_m_s=speed,
                                                 max_rate_rad_s=gyro_range)
    return InitialState(lat, lon, h), legs


def _segment_legs(seg: Mapping[str, Any], ctx: Ctx, state: np.ndarray, gamma: float
                  ) -> list[Leg]:
    """The legs of one ``[[trajectory.segment]]`` from channel values ``state``."""
    kind = get_str(seg, "kind", ctx)
    if kind not in SEGMENT_KEYS:
        raise ctx.error("kind", f"{kind!r} not allowed; one of {', '.join(SEGMENT_KEYS)}")
    check_known_keys(seg, ("kind", "gnss", "label", *_DURATION, *SEGMENT_KEYS[kind]), ctx)
    duration = get_quantity(seg, "duration", ctx, TIME_UNITS)
    if duration < 0:
        key = next(k for k in _DURATION if k in seg)
        raise ctx.error(key, f"value {seg[key]!r} not allowed; a segment's duration must be "
                             f">= 0")
    gnss = get_bool(seg, "gnss", ctx, True)
    label = get_str(seg, "label", ctx, kind)
    if any(ord(c) < 32 for c in label):     # the dataset's timeline stores it as a C string
        raise ctx.error("label", f"{label[:40]!r} not allowed; a label is one line of text "
                                 f"without control characters")
    if duration == 0:
        return []
    zero = np.zeros(6)

    def one_of(*keys: str) -> str:
        present = [k for k in keys if k in seg]
        if len(present) != 1:
            raise ctx.error(keys[0], f"give exactly one of {', '.join(keys)}")
        return present[0]

    def smooth(channel: int, value: float) -> Leg:
        target = state.copy()
        target[channel] = value
        return smooth_leg(state, target, duration, label=label, gnss=gnss)

    if kind == "hold":
        return [rate_leg(state, zero, duration, label=label, gnss=gnss)]
    if kind == "accelerate":
        if one_of("accel_m_s2", "speed_m_s") == "accel_m_s2":
            rates = zero.copy()
            rates[4] = get_float(seg, "accel_m_s2", ctx)
            return [rate_leg(state, rates, duration, label=label, gnss=gnss)]
        return [smooth(4, get_float(seg, "speed_m_s", ctx))]
    if kind == "turn":
        if one_of("rate_deg_s", "by_deg") == "rate_deg_s":
            rates = zero.copy()
            rates[0] = get_float(seg, "rate_deg_s", ctx) * DEG
            return [rate_leg(state, rates, duration, label=label, gnss=gnss)]
        return [smooth(0, state[0] + get_float(seg, "by_deg", ctx) * DEG)]
    if kind == "climb":
        return [smooth(1, get_float(seg, "pitch_deg", ctx, min=-89.0, max=89.0) * DEG)]
    if kind == "roll":
        return [smooth(2, get_float(seg, "roll_deg", ctx, min=-89.0, max=89.0) * DEG)]
    # coordinated turn: roll in, turn at a constant rate, roll out
    by = get_float(seg, "by_deg", ctx) * DEG
    roll_time = get_float(seg, "roll_time_s", ctx, 5.0, min=0.0, min_exclusive=True)
    turn_time = duration - 2.0 * roll_time
    if turn_time <= 0:
        raise ctx.error("roll_time_s", f"value {roll_time:g} not allowed; rolling in and out "
                                       f"must leave time to turn (< half of {duration:g} s)")
    rate = by / turn_time
    bank = math.atan(state[4] * rate / gamma)
    roll_in = state.copy()
    roll_in[2] = state[2] + bank
    legs = [smooth_leg(state, roll_in, roll_time, label=f"{label} (roll in)", gnss=gnss)]
    rates = zero.copy()
    rates[0] = rate
    legs.append(rate_leg(legs[-1].end(), rates, turn_time, label=label, gnss=gnss))
    end = legs[-1].end()
    out = end.copy()
    out[2] = state[2]
    legs.append(smooth_leg(end, out, roll_time, label=f"{label} (roll out)", gnss=gnss))
    return legs
