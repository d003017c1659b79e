"""Two-axis turntable programmes: holds, rotations, continuous rotation, repeats, and the
19-position systematic-calibration sequence.

Gimbal convention
-----------------
Navigation frame ENU (x East, y North, z Up). The **outer axis** is horizontal and fixed to the
ground along East (ENU x). The **inner axis** is carried by the outer gimbal, perpendicular to the
outer axis, and vertical (Up) when the outer angle is zero. The IMU is mounted on the inner table
with its body (measurement) frame equal to ENU at zero angles: body x = East, y = North,
z = Up. Hence the inner axis is always body z, and the outer axis is body x when inner = 0°
(body −y at inner = 90°, −x at 180°, +y at 270°). Angles are right-handed (positive
counter-clockwise seen from the axis tip). The body-to-ENU attitude is

    C_b^n(outer, inner) = R_x(outer) · R_z(inner)

with R_x, R_z the usual active rotation matrices (Titterton & Weston 2004, §3.6). The table's
angular velocity in body axes is ω_nb^b = (cos i, −sin i, 0)·d(outer)/dt + (0, 0, 1)·d(inner)/dt;
a programme moves one axis at a time, so during every motion the body turns about an axis that
is fixed in the body at a constant rate (closed-form kinematics in :mod:`rlgsim.sim.motion.kinematics`).

Rate profile: a rotation is a constant-rate motion of duration |angle|/rate; the table's
acceleration phases (a few tenths of a second on a real table at 20 °/s) are **ignored** — the
rate steps instantly. The sensors see the same idealised motion, and the calibration filter uses
the commanded programme, so nothing is inconsistent; a real table's acceleration only adds a
small, known lag in the angle.

Programmes
----------
A :class:`TurntableProgram` is a start orientation plus a list of steps (hold, rotate,
continuous rotation, repeat, or an embedded named sequence). :meth:`TurntableProgram.motions`
expands it into :class:`TableMotion` records, each with the angles at its start and its labels:

* ``position`` — 1-based index of the static position within one repetition of the programme;
  a static dwell carries its own index, a rotation carries the index of the position it leaves.
* ``window`` — 0-based calibration-window index (one per repetition of a calibration
  programme), ``None`` for programmes that are not calibrations.
* ``kind`` — ``'static'`` or ``'rotate'``.

An optional static *lead-in* (``lead_in_s``; e.g. paper 000's 4 h soak before the ramp) holds
the start angles before the first repetition; it is labelled "lead-in", position 0, window
None, and is not part of any calibration window.

A *continuous* programme repeats back to back for the whole run (paper 000 §4.1: the IMU
"continuously carries out rotation calibration work" while the chamber ramps, 175 windows of
~40 min); :meth:`motions` then yields forever unless ``until_s`` is given.

The 19-position systematic-calibration sequence
-----------------------------------------------
Systematic (navigation-based) calibration runs the strapdown navigation on the static turntable
and lets a Kalman filter estimate the sensor errors from the velocity errors they cause during
static dwells between rotations (Cai Q. et al., "Systematic calibration for ultra-high
accuracy inertial measurement units", Sensors 16(6):940, 2016, and the work it reviews, where
the 19-position sequence of ±90° turns about the three body axes is the usual scheme for laser
SINS). The sequence here is this project's arrangement of that pattern for a two-axis table —
not a copy of a published table: 18 turns of ±90° at 20 °/s and 19 static dwells, chosen so
that the observability conditions below hold (checked numerically by the calibration tests).

* turns 1–5: outer +90° ×5 with inner = 0° → five turns about body x (x stays East, horizontal);
  body y and z each point Up and Down.
* turns 6–10: inner +90° ×5 with outer = 90° → five turns about body z while z is horizontal
  (South); body x and y each point Up and Down.
* turns 11–14: outer +90° ×4 with inner = 90° → four turns about body y (y horizontal, West).
* turns 15–18: inner −90°, outer −90°, outer −90°, outer +90° → turns in the negative sense,
  ending at the start orientation (outer 0°, inner 0°) so the repetitions join seamlessly.

Why every error is observable (zero-velocity measurement during dwells; the attitude error
feeds the velocity error through the horizontal specific force, δv̇ = f^n × φ − …): each gyro
axis is turned through ≥ 360° about a *horizontal* axis, so its scale-factor error (δK·θ) and
the misalignments of the other two gyros onto that axis (E·θ) appear as tilt errors (a turn about
a vertical axis would only give a heading error, which a zero-velocity filter sees only weakly
through Earth rate); gyro biases act in 19 different body orientations; each accelerometer
points Up and Down (+g and −g separate bias, K⁺ and K⁻) and lies horizontal while the other
axes carry g (accelerometer misalignments).

Dwell durations: 120 s per position (velocity errors from a 1 arcsec tilt grow to
g·φ·t ≈ 5.7 mm/s in 120 s, from a 0.01 °/h gyro bias to ≈ g·b·t²/2 ≈ 3.4 mm/s — far above the
velocity noise of navigation-grade accelerometers) and 159 s for the first dwell, which also
serves the static alignment: 159 + 18·120 + 18·4.5 = 2400 s = 40 min, as in paper 000
(7000 min / 40 min = 175 windows).

Why this file is over 400 lines: it is one reader, the ``[turntable]`` table and its step kinds
with their checks and durations (the calibration sequences included), whose parts share the
same small step classes; the kinematics of the result are apart (kinematics.py).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Iterator, Mapping, Sequence

from rlgsim.sim.config import Ctx, check_known_keys, get_bool, get_float, get_int, get_list, get_str
from rlgsim.ground.errors import UserInputError

AXES = ("outer", "inner")
KINDS = ("static", "rotate")
DEFAULT_RATE_DEG_S = 20.0        # paper 000 §4.1: rotation speed 20 °/s


@dataclass(frozen=True)
class TableMotion:
    """One motion of the table (constant rate about one axis, or static).

    ``duration_s`` [s]; ``kind`` 'static' | 'rotate'; ``axis`` 'outer' | 'inner' | None;
    ``rate_deg_s`` signed table rate [°/s] (0 when static); ``outer_deg``/``inner_deg`` angles at
    the start of the motion [°] (in [0, 360)); ``label`` a readable name; ``position`` 1-based
    position index within one repetition; ``window`` 0-based calibration-window index or None;
    ``continuous`` True if the programme repeats back to back.
    """

    duration_s: float
    kind: str
    axis: str | None
    rate_deg_s: float
    outer_deg: float
    inner_deg: float
    label: str
    position: int | None = None
    window: int | None = None
    continuous: bool = False

    @property
    def angle_deg(self) -> float:
        """Angle turned during the motion [°] (signed)."""
        return self.rate_deg_s * self.duration_s

    def end_angles(self) -> tuple[float, float]:
        """(outer, inner) angles at the end of the motion [°], not wrapped."""
        if self.kind == "static":
            return self.outer_deg, self.inner_deg
        if self.axis == "outer":
            return self.outer_deg + self.angle_deg, self.inner_deg
        return self.outer_deg, self.inner_deg + self.angle_deg

    def attrs(self) -> dict[str, Any]:
        """The motion's fields as a plain dict (the turntable timeline segment's ``attrs``)."""
        return asdict(self)


# --------------------------------------------------------------------------------------------
# programme steps

@dataclass(frozen=True)
class Hold:
    """Static dwell of ``duration_s`` seconds (``math.inf``: until the end of the run)."""

    duration_s: float
    label: str | None = None


@dataclass(frozen=True)
class Rotate:
    """Turn ``angle_deg`` (signed) about ``axis`` at ``rate_deg_s`` (> 0, magnitude)."""

    axis: str
    angle_deg: float
    rate_deg_s: float = DEFAULT_RATE_DEG_S
    label: str | None = None


@dataclass(frozen=True)
class Spin:
    """Continuous rotation about ``axis`` at the signed ``rate_deg_s`` for ``duration_s``."""

    axis: str
    rate_deg_s: float
    duration_s: float
    label: str | None = None


@dataclass(frozen=True)
class Repeat:
    """The ``steps`` ``count`` times in a row."""

    count: int
    steps: tuple


Step = Hold | Rotate | Spin | Repeat

#: Turns of the 19-position sequence (axis, angle [°]) from (outer, inner) = (0°, 0°); see the
#: module docstring for the arrangement and the observability argument.
CALIBRATION19_TURNS: tuple[tuple[str, float], ...] = (
    (("outer", 90.0),) * 5 + (("inner", 90.0),) * 5 + (("outer", 90.0),) * 4
    + (("inner", -90.0), ("outer", -90.0), ("outer", -90.0), ("outer", 90.0)))
CALIBRATION19_DWELL_S = 120.0
CALIBRATION19_FIRST_DWELL_S = 159.0


def calibration19_steps(rate_deg_s: float = DEFAULT_RATE_DEG_S,
                        dwell_s: float = CALIBRATION19_DWELL_S,
                        first_dwell_s: float = CALIBRATION19_FIRST_DWELL_S) -> tuple[Step, ...]:
    """The 19-position sequence as steps: dwell, (turn, dwell) ×18. Start and end at (0°, 0°)."""
    steps: list[Step] = [Hold(first_dwell_s, "P01")]
    for k, (axis, angle) in enumerate(CALIBRATION19_TURNS, start=1):
        steps.append(Rotate(axis, angle, rate_deg_s, f"R{k:02d} {axis} {angle:+g}°"))
        steps.append(Hold(dwell_s, f"P{k + 1:02d}"))
    return tuple(steps)


SEQUENCES = {"calibration19": calibration19_steps}


def _wrap(angle_deg: float) -> float:
    """Angle in [0, 360) [°]; exact for the multiples of 90° used by the sequences."""
    a = math.fmod(angle_deg, 360.0)
    if a < 0:
        a += 360.0
    return 0.0 if a == 360.0 else a


def _steps_duration(steps: Sequence[Step]) -> float:
    total = 0.0
    for s in steps:
        if isinstance(s, Repeat):
            total += s.count * _steps_duration(s.steps)
        elif isinstance(s, Rotate):
            total += abs(s.angle_deg) / s.rate_deg_s
        else:
            total += s.duration_s
    return total


class TurntableProgram:
    """A turntable programme: start angles, steps, whether it repeats and whether it calibrates.

    ``start_outer_deg``/``start_inner_deg`` [°]; ``steps`` a sequence of :class:`Hold`,
    :class:`Rotate`, :class:`Spin`, :class:`Repeat`; ``continuous`` repeat back to back for the
    whole run; ``calibration`` label each repetition as a calibration window; ``name`` for labels.
    """

    def __init__(self, steps: Sequence[Step], *, start_outer_deg: float = 0.0,
                 start_inner_deg: float = 0.0, continuous: bool = False,
                 calibration: bool = False, name: str = "custom",
                 lead_in_s: float = 0.0) -> None:
        self.steps = tuple(steps)
        self.lead_in_s = float(lead_in_s)
        if not (0.0 <= self.lead_in_s < math.inf):
            raise ValueError(f"lead_in_s must be finite and >= 0, got {lead_in_s!r}")
        if not self.steps:
            raise ValueError("a turntable programme needs at least one step")
        self.start_outer_deg = float(start_outer_deg)
        self.start_inner_deg = float(start_inner_deg)
        self.continuous = bool(continuous)
        self.calibration = bool(calibration)
        self.name = name
        self.duration_s = _steps_duration(self.steps)   # of one repetition [s], no lead-in
        if self.continuous and not (0 < self.duration_s < math.inf):
            raise ValueError("a continuous programme needs a finite, positive duration")
        if self.continuous:
            end = self._end_angles()
            if (_wrap(end[0]) != _wrap(self.start_outer_deg)
                    or _wrap(end[1]) != _wrap(self.start_inner_deg)):
                raise ValueError(
                    f"a continuous programme must end where it starts: starts at "
                    f"({self.start_outer_deg:g}°, {self.start_inner_deg:g}°), ends at "
                    f"({_wrap(end[0]):g}°, {_wrap(end[1]):g}°)")

    # ---- constructors ---------------------------------------------------------------------
    @classmethod
    def static(cls, outer_deg: float = 0.0, inner_deg: float = 0.0) -> "TurntableProgram":
        """Static mount at (outer, inner) [°] for the whole run (the simplest programme)."""
        return cls((Hold(math.inf, "static"),), start_outer_deg=outer_deg,
                   start_inner_deg=inner_deg, name="static")

    @classmethod
    def calibration19(cls, rate_deg_s: float = DEFAULT_RATE_DEG_S,
                      dwell_s: float = CALIBRATION19_DWELL_S,
                      first_dwell_s: float = CALIBRATION19_FIRST_DWELL_S,
                      continuous: bool = True, lead_in_s: float = 0.0) -> "TurntableProgram":
        """The 19-position systematic-calibration sequence (40 min with the defaults), after an
        optional static ``lead_in_s`` (e.g. a chamber soak) that belongs to no window."""
        return cls(calibration19_steps(rate_deg_s, dwell_s, first_dwell_s),
                   continuous=continuous, calibration=True, name="calibration19",
                   lead_in_s=lead_in_s)

    @classmethod
    def from_config(cls, table: Mapping | None, ctx: Ctx) -> "TurntableProgram":
        """Build from a scenario's ``[turntable]`` table.

        Keys: ``program`` = "static" (default) | "calibration19" | "custom";
        ``outer_deg``, ``inner_deg`` start/mount angles [°] (static and custom; calibration19
        always starts at 0, 0); ``continuous`` (default true for calibration19, else false);
        ``calibration`` (custom only, default false: label repetitions as calibration windows);
        ``rate_deg_s`` [°/s], ``dwell_s``, ``first_dwell_s`` [s] (calibration19);
        ``motions`` (custom): array of tables, each with ``type`` =
        "hold" (``duration_s``; omitted = to the end of the run, last motion only),
        "rotate" (``axis``, ``angle_deg``, ``rate_deg_s`` default 20),
        "continuous" (``axis``, signed ``rate_deg_s``, ``duration_s``; omitted = to the end),
        "repeat" (``count``, ``motions``), or "sequence" (``name`` = "calibration19",
        ``rate_deg_s``, ``dwell_s``, ``first_dwell_s``); every motion takes an optional ``label``.
        """
        table = {} if table is None else table
        check_known_keys(table, ("program", "outer_deg", "inner_deg", "continuous",
                                 "calibration", "rate_deg_s", "dwell_s", "first_dwell_s",
                                 "motions") + LEAD_IN_KEYS, ctx)
        program = get_str(table, "program", ctx, "static",
                          choices=("static", "calibration19", "custom"))

        def only(keys: Sequence[str]) -> None:
            for key in table:
                if key not in keys:
                    raise ctx.error(key, f"not used by program = {program!r}; allowed keys: "
                                         f"{', '.join(sorted(keys))}")

        if program == "static":
            only(("program", "outer_deg", "inner_deg"))
            return cls.static(get_float(table, "outer_deg", ctx, 0.0, min=-360.0, max=360.0),
                              get_float(table, "inner_deg", ctx, 0.0, min=-360.0, max=360.0))
        if program == "calibration19":
            only(("program", "continuous", "rate_deg_s", "dwell_s", "first_dwell_s")
                 + LEAD_IN_KEYS)
            return cls.calibration19(**_sequence_kwargs(table, ctx),
                                     continuous=get_bool(table, "continuous", ctx, True),
                                     lead_in_s=_lead_in(table, ctx))
        only(("program", "outer_deg", "inner_deg", "continuous", "calibration", "motions")
             + LEAD_IN_KEYS)
        continuous = get_bool(table, "continuous", ctx, False)
        steps = _parse_steps(get_list(table, "motions", ctx, min_len=1), ctx.child("motions"))
        _check_open_ended(steps, continuous, ctx.child("motions"))
        try:
            return cls(steps, start_outer_deg=get_float(table, "outer_deg", ctx, 0.0,
                                                        min=-360.0, max=360.0),
                       start_inner_deg=get_float(table, "inner_deg", ctx, 0.0,
                                                 min=-360.0, max=360.0),
                       continuous=continuous,
                       calibration=get_bool(table, "calibration", ctx, False),
                       lead_in_s=_lead_in(table, ctx))
        except ValueError as exc:
            raise ctx.error("motions", str(exc)) from None

    # ---- expansion ------------------------------------------------------------------------
    def _end_angles(self) -> tuple[float, float]:
        o, i = self.start_outer_deg, self.start_inner_deg
        for m in self._expand(self.steps):
            if m[0] == "rotate":
                _, axis, rate, dur, _ = m
                if axis == "outer":
                    o += rate * dur
                else:
                    i += rate * dur
        return o, i

    def _expand(self, steps: Sequence[Step]) -> Iterator[tuple]:
        """Flat (kind, axis, rate, duration, label) tuples of one repetition."""
        for s in steps:
            if isinstance(s, Repeat):
                for _ in range(s.count):
                    yield from self._expand(s.steps)
            elif isinstance(s, Hold):
                yield ("static", None, 0.0, s.duration_s, s.label)
            elif isinstance(s, Rotate):
                rate = math.copysign(s.rate_deg_s, s.angle_deg)
                yield ("rotate", s.axis, rate, abs(s.angle_deg) / s.rate_deg_s, s.label)
            else:
                yield ("rotate", s.axis, s.rate_deg_s, s.duration_s, s.label)

    def motions(self, until_s: float | None = None) -> Iterator[TableMotion]:
        """The programme as :class:`TableMotion` records, back to back from t = 0.

        A continuous programme yields forever unless ``until_s`` [s] is given; with ``until_s``
        the motion that crosses it is cut short there and nothing after it is yielded.
        Zero-length motions (e.g. a 0° turn) are skipped.
        """
        o, i = _wrap(self.start_outer_deg), _wrap(self.start_inner_deg)
        t = 0.0
        window = 0
        if self.lead_in_s > 0:
            dur = self.lead_in_s if until_s is None else min(self.lead_in_s, until_s)
            if dur <= 0:
                return
            yield TableMotion(dur, "static", None, 0.0, o, i, "lead-in", 0, None,
                              self.continuous)
            t = dur
        while True:
            position = 0
            for kind, axis, rate, dur, label in self._expand(self.steps):
                if kind == "static":
                    position += 1
                if dur <= 0:
                    continue
                if until_s is not None:
                    if t >= until_s:
                        return
                    dur = min(dur, until_s - t)
                if label is None:
                    label = (f"P{position:02d}" if kind == "static"
                             else f"{axis} {rate:+g}°/s")
                motion = TableMotion(dur, kind, axis, rate, o, i, label, max(position, 1),
                                     window if self.calibration else None, self.continuous)
                yield motion
                t += dur
                end_o, end_i = motion.end_angles()
                o, i = _wrap(end_o), _wrap(end_i)
            if not self.continuous:
                return
            window += 1

    def __repr__(self) -> str:
        return (f"TurntableProgram(name={self.name!r}, steps={len(self.steps)}, "
                f"duration_s={self.duration_s:g}, continuous={self.continuous}, "
                f"calibration={self.calibration})")


# --------------------------------------------------------------------------------------------
# config parsing

LEAD_IN_KEYS = ("lead_in_s", "lead_in_min", "lead_in_h")


def _lead_in(table: Mapping, ctx: Ctx) -> float:
    """Static lead-in before the programme [s], from exactly one of ``lead_in_s``,
    ``lead_in_min``, ``lead_in_h`` (default 0)."""
    given = [k for k in LEAD_IN_KEYS if k in table]
    if len(given) > 1:
        raise ctx.error(given[1], f"give only one of {', '.join(given)}")
    if not given:
        return 0.0
    factor = {"lead_in_s": 1.0, "lead_in_min": 60.0, "lead_in_h": 3600.0}[given[0]]
    return get_float(table, given[0], ctx, min=0.0) * factor


def _sequence_kwargs(table: Mapping, ctx: Ctx) -> dict:
    return dict(rate_deg_s=get_float(table, "rate_deg_s", ctx, DEFAULT_RATE_DEG_S,
                                     min=0.0, min_exclusive=True, max=1000.0),
                dwell_s=get_float(table, "dwell_s", ctx, CALIBRATION19_DWELL_S,
                                  min=MIN_MOTION_S),
                first_dwell_s=get_float(table, "first_dwell_s", ctx, CALIBRATION19_FIRST_DWELL_S,
                                        min=MIN_MOTION_S))


#: Shortest motion [s]: a hold, a continuous rotation or a turn (its angle over its rate) may
#: not be shorter, so that a repeated programme keeps a block's motion segments bounded (the
#: whole run is also limited to rlgsim.sim.run.run_budget.MAX_MOTIONS segments).
MIN_MOTION_S = 1e-3


def _duration(item: Mapping, ctx: Ctx) -> float:
    """``duration_s`` [s] >= :data:`MIN_MOTION_S`; omitted = to the end of the run
    (``math.inf``)."""
    value = get_float(item, "duration_s", ctx, None, min=MIN_MOTION_S)
    return math.inf if value is None else value


def _parse_steps(items: list, ctx: Ctx) -> tuple[Step, ...]:
    steps: list[Step] = []
    for n, item in enumerate(items):
        c = ctx.item(n)
        if not isinstance(item, Mapping):
            raise UserInputError(f"{c.source + ': ' if c.source else ''}{c.path}: expected a "
                                 f"table with a 'type' key, got {item!r}")
        kind = get_str(item, "type", c, choices=("hold", "rotate", "continuous", "repeat",
                                                 "sequence"))
        label = get_str(item, "label", c, None)
        if kind == "hold":
            check_known_keys(item, ("type", "duration_s", "label"), c)
            steps.append(Hold(_duration(item, c), label))
        elif kind == "rotate":
            check_known_keys(item, ("type", "axis", "angle_deg", "rate_deg_s", "label"), c)
            turn = Rotate(get_str(item, "axis", c, choices=AXES),
                          get_float(item, "angle_deg", c, min=-36000.0, max=36000.0),
                          get_float(item, "rate_deg_s", c, DEFAULT_RATE_DEG_S, min=0.0,
                                    min_exclusive=True, max=1000.0), label)
            if turn.angle_deg and abs(turn.angle_deg) / turn.rate_deg_s < MIN_MOTION_S:
                raise c.error("angle_deg", f"value {turn.angle_deg:g} not allowed at "
                                           f"rate_deg_s = {turn.rate_deg_s:g}: the turn would "
                                           f"last less than {MIN_MOTION_S:g} s")
            steps.append(turn)
        elif kind == "continuous":
            check_known_keys(item, ("type", "axis", "rate_deg_s", "duration_s", "label"), c)
            rate = get_float(item, "rate_deg_s", c, min=-1000.0, max=1000.0)
            if rate == 0:
                raise c.error("rate_deg_s", "value 0 not allowed; use a hold for a static table")
            steps.append(Spin(get_str(item, "axis", c, choices=AXES), rate, _duration(item, c),
                              label))
        elif kind == "repeat":
            check_known_keys(item, ("type", "count", "motions"), c)
            sub = _parse_steps(get_list(item, "motions", c, min_len=1), c.child("motions"))
            if not (0 < _steps_duration(sub) < math.inf):
                raise c.error("motions", "the repeated motions need a finite duration")
            steps.append(Repeat(get_int(item, "count", c, min=1, max=100000), sub))
        else:
            check_known_keys(item, ("type", "name", "rate_deg_s", "dwell_s", "first_dwell_s"), c)
            name = get_str(item, "name", c, choices=tuple(SEQUENCES))
            steps.append(Repeat(1, SEQUENCES[name](**_sequence_kwargs(item, c))))
    return tuple(steps)


def _check_open_ended(steps: Sequence[Step], continuous: bool, ctx: Ctx) -> None:
    """Only the last motion of a non-repeating programme may run to the end of the run."""
    for n, s in enumerate(steps):
        dur = getattr(s, "duration_s", 0.0)
        if math.isinf(dur) and (continuous or n != len(steps) - 1):
            raise ctx.item(n).error("duration_s", "missing: only the last motion of a programme "
                                    "that is not continuous may run to the end of the run")
