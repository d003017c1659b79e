"""gnss-ins-sim's motion-definition CSV, read as it is, turned into legs.

The file (gnss-ins-sim, Aceinna, MIT licence; its ``demo_motion_def_files/``) has a header line,
one line of the initial state — latitude, longitude [°], altitude [m], velocity in its body axes
(forward, right, down) [m/s], yaw, pitch, roll [°] — a second header line, then one command per
line: type, yaw, pitch, roll [°, or °/s], vx, vy, vz [m/s, or m/s²], the command's duration [s]
and the GPS visibility (0: no fix, else visible — gnss-ins-sim never reads it itself and its
Aceinna demo passes a fix type 2, 4 … there). Its navigation frame is NED with body axes forward–right–down;
here ENU with right–forward–up, so its body velocity (x_f, y_r, z_d) is (y_r, x_f, −z_d) here and
its yaw, pitch and roll are the same physical angles as heading, pitch and roll
(:mod:`rlgsim.sim.motion.legs`).

The commands (gnss-ins-sim ``pathgen.parse_motion_def``) and how they are read here:

* type 1 — Euler-angle rates [°/s] and body-frame velocity rates [m/s²] held for the duration:
  a rate leg. (gnss-ins-sim passes the commanded rates through a first-order low-pass of
  α = 0.9 per simulation step, ~0.1 s at 100 Hz; here the rates start at once.)
* types 2–5 — a target attitude and body velocity, absolute (2), relative to the current
  values (3), absolute attitude and relative velocity (4), relative attitude and absolute
  velocity (5), reached within at most the duration: a smooth leg (quintic, rates zero at both
  ends) as short as its mobility limits allow — peak angle rate ≤ ``max_rate``, peak angular
  acceleration ≤ ``max_angular_accel``, peak acceleration ≤ ``max_accel`` per axis (gnss-ins-sim's
  ``high_mobility`` by default: 1 m/s², 0.5 rad/s², 2 rad/s) — and the next command starts when
  it is reached, as gnss-ins-sim starts the next command once its controller converged. If the
  limits need longer than the duration, the target is still reached at the duration (faster
  than the limits; gnss-ins-sim would stop short of it). gnss-ins-sim's PD controller
  (kp = 5, kd = 10) converges asymptotically, so its legs last longer than these minimum-time
  ones (docs/trajectories.md compares the two).

A command of zero duration is skipped; a negative duration, an unknown type, a non-number, an
empty cell before the row's last number, a row of the wrong length, a negative GPS
visibility, a missing header line (a first or third line of numbers: the file would be read a row
off), an initial latitude at or past ±89.9° (the ENU frame's singularity, as for the
``[trajectory]`` table), an initial altitude outside the Earth model's heights
(:data:`rlgsim.sim.motion.site.MIN_HEIGHT_M` … ``MAX_HEIGHT_M``) and more than
:data:`rlgsim.sim.motion.legs.MAX_LEGS` commands are one :class:`~rlgsim.ground.errors.UserInputError`
line naming file, line and column.
"""

from __future__ import annotations

import csv
import math
import pathlib
from dataclasses import dataclass

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import DEG
from rlgsim.sim.motion.legs import (MAX_LEGS, TOO_MANY_LEGS_ADVICE, Leg, rate_leg, smooth_leg,
                                    smooth_time)
from rlgsim.sim.motion.position_table import MAX_LATITUDE_DEG, _is_number
from rlgsim.sim.motion.site import MAX_HEIGHT_M, MIN_HEIGHT_M

#: gnss-ins-sim's built-in mobility ``high_mobility``: m/s², rad/s², rad/s
DEFAULT_MOBILITY = (1.0, 0.5, 2.0)
COMMAND_COLUMNS = ("command type", "yaw (deg)", "pitch (deg)", "roll (deg)", "vx_body (m/s)",
                   "vy_body (m/s)", "vz_body (m/s)", "command duration (s)", "GPS visibility")


@dataclass(frozen=True)
class MotionDefinition:
    """A motion definition read: the start (latitude, longitude [rad], height [m]) and its
    legs (heading, pitch, roll, body velocity right–forward–up as :mod:`rlgsim.sim.motion.legs`
    channels)."""

    lat_rad: float
    lon_rad: float
    height_m: float
    legs: tuple[Leg, ...]


def _body(frd: np.ndarray) -> np.ndarray:
    """gnss-ins-sim body velocity (forward, right, down) → (right, forward, up)."""
    return np.array([frd[1], frd[0], -frd[2]])


def _numbers(row: list[str], where: str, count: int) -> np.ndarray:
    cells = [c.strip() for c in row]
    while cells and cells[-1] == "":              # trailing separators: nothing lost
        cells.pop()
    if "" in cells:
        raise UserInputError(f"{where}, column {cells.index('') + 1}: empty cell; expected "
                             f"{count} numbers")
    if len(cells) != count:
        raise UserInputError(f"{where}: expected {count} numbers, got {len(cells)}")
    out = np.empty(count)
    for i, c in enumerate(cells):
        try:
            out[i] = float(c)
        except ValueError:
            raise UserInputError(f"{where}, column {i + 1}: {c!r} is not a number") from None
        if not math.isfinite(out[i]):
            raise UserInputError(f"{where}, column {i + 1}: {c!r} is not a finite number")
    return out


def read_motion_def(path: str | pathlib.Path, *,
                    mobility: tuple[float, float, float] = DEFAULT_MOBILITY
                    ) -> MotionDefinition:
    """Read gnss-ins-sim's motion-definition CSV at ``path`` into legs (module docstring).
    ``mobility`` = (max acceleration [m/s²], max angular acceleration [rad/s²], max angle
    rate [rad/s]) for the commands of types 2–5."""
    p = pathlib.Path(path)
    try:
        with open(p, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            rows, lines = [], []
            for r in reader:
                if any(c.strip() for c in r):
                    rows.append(r)
                    lines.append(reader.line_num)
                    if len(rows) > MAX_LEGS + 3:
                        raise UserInputError(f"{p}: more than {MAX_LEGS} commands; a route "
                                             f"takes at most {MAX_LEGS} legs: "
                                             f"{TOO_MANY_LEGS_ADVICE}")
    except OSError as e:
        raise UserInputError(f"{p}: cannot read the motion definition ({e.strerror})") from None
    except UnicodeDecodeError:
        raise UserInputError(f"{p}: not a text (UTF-8) CSV file") from None
    except csv.Error as e:
        raise UserInputError(f"{p}: not a CSV file ({e})") from None
    if len(rows) < 4:
        raise UserInputError(f"{p}: a motion definition needs a header, the initial state, a "
                             f"second header and at least one command ({len(rows)} lines)")
    for k, what in ((0, "the header of the initial state"), (2, "the header of the commands")):
        if all(_is_number(c) for c in rows[k] if c.strip()):
            raise UserInputError(f"{p}: line {lines[k]}: expected {what} (column names), got "
                                 f"numbers; gnss-ins-sim's file has a header line before the "
                                 f"initial state and another before the commands")
    init = _numbers(rows[1], f"{p}: line {lines[1]} (initial state)", 9)
    lat, lon, alt = init[0], init[1], init[2]
    if not abs(lat) < MAX_LATITUDE_DEG:
        raise UserInputError(f"{p}: line {lines[1]}, column 1: initial latitude {lat:g}° not "
                             f"allowed; |latitude| < {MAX_LATITUDE_DEG:g} (the ENU frame is "
                             f"singular at the poles)")
    if not MIN_HEIGHT_M <= alt <= MAX_HEIGHT_M:
        raise UserInputError(f"{p}: line {lines[1]}, column 3: initial altitude {alt:g} m not "
                             f"allowed; must be in [{MIN_HEIGHT_M:g}, {MAX_HEIGHT_M:g}]")
    far = np.flatnonzero(np.abs(init[6:9]) > 360.0)
    if far.size:       # far past a turn the angles lose the commands' changes to rounding
        raise UserInputError(f"{p}: line {lines[1]}, column {7 + far[0]}: initial "
                             f"{('yaw', 'pitch', 'roll')[far[0]]} {init[6 + far[0]]:g}° not "
                             f"allowed; must be in [-360, 360]")
    state = np.concatenate([init[6:9][[0, 1, 2]] * DEG, _body(init[3:6])])
    max_acc, max_dw, max_w = mobility
    rate_lim = np.array([max_w] * 3 + [np.inf] * 3)
    acc_lim = np.array([max_dw] * 3 + [max_acc] * 3)
    legs: list[Leg] = []
    for i, row in enumerate(rows[3:], start=4):
        where = f"{p}: line {lines[i - 1]}"
        c = _numbers(row, where, 9)
        kind, duration, visible = c[0], c[7], bool(c[8] != 0)
        if not c[8] >= 0:      # gnss-ins-sim's demos pass a fix type (2, 4 …): visible ≠ 0
            raise UserInputError(f"{where}, column 9: GPS visibility {c[8]:g} not allowed; "
                                 f"0 (no fix) or a positive number (visible)")
        if kind not in (1, 2, 3, 4, 5):
            raise UserInputError(f"{where}, column 1: command type {c[0]:g} not allowed; "
                                 f"one of 1, 2, 3, 4, 5")
        if duration < 0:
            raise UserInputError(f"{where}, column 8: command duration {duration:g} s is "
                                 f"negative; must be >= 0")
        if duration == 0:
            continue
        att, vel = c[1:4] * DEG, _body(c[4:7])
        label = f"command {i - 3} (type {int(kind)})"
        if kind == 1:
            leg = rate_leg(state, np.concatenate([att, vel]), duration, label=label,
                           gnss=visible)
        else:
            att_t = att if kind in (2, 4) else state[:3] + att
            vel_t = vel if kind in (2, 5) else state[3:] + vel
            target = np.concatenate([att_t, vel_t])
            need = smooth_time(target - state, rate_lim, acc_lim)
            if need == 0.0:
                continue
            leg = smooth_leg(state, target, min(need, duration), label=label, gnss=visible)
        legs.append(leg)
        state = leg.end()
    if not legs:
        raise UserInputError(f"{p}: the motion definition has no command of positive "
                             f"duration")
    return MotionDefinition(lat * DEG, lon * DEG, alt, tuple(legs))
