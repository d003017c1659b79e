"""Temperature-chamber programmes: segments → piecewise-linear setpoint → rate limit → air lag.

A programme (the ``[chamber]`` table of a scenario) starts at ``start_c`` and runs a list of
segments (docs/thermal.md, "Chamber"):

``hold``    keep the current temperature for ``duration_s|_min|_h``;
``ramp``    go linearly to ``to_c``, either at ``rate_c_per_min`` or over ``duration_*``
            (exactly one of the two);
``step``    jump to ``to_c`` at once (the rate limit turns it into a ramp at the chamber's
            maximum rate);
``repeat``  run the nested ``segments`` ``count`` times (alias ``cycle``);
``profile`` a table of ``time_s|_min|_h`` (from the segment's start) and ``temperature_c``
            joined linearly (e.g. the air of a vehicle's bay, docs/trajectories.md);
``random``  ``legs`` random ramp-and-hold legs: target uniform in ``[min_c, max_c]``, rate
            uniform in ``[min_rate_c_per_min, max_rate_c_per_min]``, hold uniform in
            ``[min_hold_*, max_hold_*]``, all drawn from the generator handed to
            :meth:`ChamberProgram.setpoint` (paper 003's random-rate test).

The chamber cannot follow a setpoint faster than ``max_rate_c_per_min``:
:meth:`ChamberProgram.rate_limited` passes the setpoint through an exact slew-rate limiter
(the programme clock is kept: a step becomes a ramp at the maximum rate, a ramp faster than
the maximum is slowed to it, and the limited setpoint catches up with the programme during the
following hold). The chamber air then follows the rate-limited setpoint as a first-order lag
with time constant ``air_tau_s``; that lag is one more state of the thermal integrator
(:mod:`rlgsim.sim.thermal.integrator`, column 0 of its state), integrated exactly.

The slew-rate limiter is written here because no library offers an exact (event-based,
closed-form) limiter of a piecewise-linear signal; sampled limiters would put the catch-up
instants off the breakpoints. docs/thermal.md §1.1 states the equations.

Why this file is over 400 lines: it is one reader and one model, the chamber programme: the
segment kinds with their checks, the expansion to the piecewise-linear set point (random
profiles included) and the rate limit, which share the segment classes; the controllers are
apart (chamber_controllers.py, chamber_controller.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Union

import numpy as np

from rlgsim.sim.config import (TIME_UNITS, Ctx, check_known_keys, get_float, get_float_list,
                               get_int, get_list, get_quantity, get_str, unit_keys, get_table)
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import MINUTE

#: Temperatures a chamber programme may ask for [°C] (a generous climatic-chamber range).
MIN_TEMPERATURE_C = -100.0
MAX_TEMPERATURE_C = 200.0
#: Default maximum rate of change of the chamber air [°C/min] (typical climatic chamber with
#: a 10 °C/min "rapid-rate" option; paper 003 runs 5 °C/min cycles).
DEFAULT_MAX_RATE_C_PER_MIN = 10.0
#: Default time constant of the chamber air behind its (rate-limited) setpoint [s].
DEFAULT_AIR_TAU_S = 60.0
#: Most breakpoints a programme may expand to (protects against runaway nested repeats).
MAX_BREAKPOINTS = 2_000_000


# --------------------------------------------------------------------------- piecewise linear


class PiecewiseLinear:
    """A piecewise-linear function of time: breakpoints ``t_s`` (non-decreasing) and ``y``.

    Linear between breakpoints; before the first breakpoint the first value and after the last
    breakpoint the last value is held. A time that appears twice marks a jump (a raw ``step``
    segment, before the rate limit); the value just after the jump is the later one. The
    rate-limited setpoint (:meth:`ChamberProgram.rate_limited`) is always continuous, with
    strictly increasing breakpoints.
    """

    def __init__(self, t_s: Any, y: Any) -> None:
        t = np.array(t_s, dtype=float).reshape(-1)
        v = np.array(y, dtype=float).reshape(-1)
        if t.shape != v.shape or t.size == 0:
            raise ValueError("t_s and y must be 1-D arrays of the same non-zero length")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ValueError("breakpoints must be finite")
        if np.any(np.diff(t) < 0):
            raise ValueError("t_s must be non-decreasing")
        t.setflags(write=False)
        v.setflags(write=False)
        self.t_s = t
        self.y = v

    def __call__(self, t: Any) -> np.ndarray:
        """Value(s) at time(s) ``t`` [s] (np.interp; at a jump the later value)."""
        t = np.asarray(t, dtype=float)
        if self.t_s.size > 1 and np.any(self.t_s[1:] == self.t_s[:-1]):
            # np.interp's choice at repeated abscissae is unspecified: pick the right side.
            i = np.clip(np.searchsorted(self.t_s, t, side="right"), 1, self.t_s.size - 1)
            t0, t1 = self.t_s[i - 1], self.t_s[i]
            y0, y1 = self.y[i - 1], self.y[i]
            with np.errstate(invalid="ignore", divide="ignore"):
                frac = np.where(t1 > t0, (t - t0) / np.where(t1 > t0, t1 - t0, 1.0), 1.0)
            out = y0 + (y1 - y0) * np.clip(frac, 0.0, 1.0)
            out = np.where(t < self.t_s[0], self.y[0], out)
            return np.where(t >= self.t_s[-1], self.y[-1], out)
        return np.interp(t, self.t_s, self.y)

    @property
    def start_s(self) -> float:
        return float(self.t_s[0])

    @property
    def end_s(self) -> float:
        """Time of the last breakpoint [s]; the value is held after it."""
        return float(self.t_s[-1])

    def max_abs_rate_c_per_min(self) -> float:
        """Largest |slope| between distinct breakpoints [°C/min] (inf if there is a jump)."""
        dt = np.diff(self.t_s)
        dy = np.diff(self.y)
        if np.any((dt == 0) & (dy != 0)):
            return float("inf")
        ok = dt > 0
        return float(np.max(np.abs(dy[ok] / dt[ok]), initial=0.0) * MINUTE)

    def __repr__(self) -> str:
        return f"PiecewiseLinear(t_s={self.t_s.tolist()}, y={self.y.tolist()})"


# --------------------------------------------------------------------------- segments


@dataclass(frozen=True)
class Hold:
    """Keep the current setpoint for ``duration_s``."""

    duration_s: float


@dataclass(frozen=True)
class Ramp:
    """Go linearly to ``to_c``: at ``rate_c_per_min`` (> 0) or over ``duration_s`` (> 0)."""

    to_c: float
    rate_c_per_min: float | None = None
    duration_s: float | None = None


@dataclass(frozen=True)
class Step:
    """Jump to ``to_c`` at once (made a ramp at the maximum rate by the rate limit)."""

    to_c: float


@dataclass(frozen=True)
class Repeat:
    """Run ``segments`` ``count`` times."""

    count: int
    segments: tuple["Segment", ...]


@dataclass(frozen=True)
class RandomProfile:
    """``legs`` random legs, each a ramp to a uniform target in ``[min_c, max_c]`` at a uniform
    rate in ``[min_rate, max_rate]`` °C/min, then a hold uniform in ``[min_hold_s, max_hold_s]``.
    A drawn target closer than ``min_change_c`` to the current temperature is redrawn from the
    part of the range at least that far away (so every leg moves)."""

    legs: int
    min_c: float
    max_c: float
    min_rate_c_per_min: float
    max_rate_c_per_min: float
    min_hold_s: float
    max_hold_s: float
    min_change_c: float = 0.0


Segment = Union[Hold, Ramp, Step, Repeat, RandomProfile]

SEGMENT_TYPES = ("hold", "ramp", "step", "repeat", "cycle", "random", "profile")
_DURATION_KEYS = tuple(unit_keys("duration", TIME_UNITS))


def _temperature(table: Mapping[str, Any], key: str, ctx: Ctx) -> float:
    return get_float(table, key, ctx, min=MIN_TEMPERATURE_C, max=MAX_TEMPERATURE_C)


def _parse_segments(items: Any, ctx: Ctx, depth: int = 0) -> tuple[Segment, ...]:
    if depth > 8:
        raise ctx.error("segments", "repeat segments nested more than 8 deep")
    out: list[Segment] = []
    for i, seg in enumerate(items):
        sctx = ctx.child("segments").item(i)
        if not isinstance(seg, Mapping):
            raise _table_error(sctx, f"expected a table, got {type(seg).__name__}")
        kind = get_str(seg, "type", sctx, choices=SEGMENT_TYPES)
        if kind == "hold":
            check_known_keys(seg, ("type", *_DURATION_KEYS), sctx)
            out.append(Hold(get_quantity(seg, "duration", sctx, TIME_UNITS, min=0.0,
                                         min_exclusive=True)))
        elif kind == "ramp":
            check_known_keys(seg, ("type", "to_c", "rate_c_per_min", *_DURATION_KEYS), sctx)
            to_c = _temperature(seg, "to_c", sctx)
            has_duration = any(k in seg for k in _DURATION_KEYS) or "duration" in seg
            if ("rate_c_per_min" in seg) == has_duration:
                raise sctx.error("rate_c_per_min", "give exactly one of rate_c_per_min or "
                                                   "duration_s/duration_min/duration_h")
            if "rate_c_per_min" in seg:
                rate = get_float(seg, "rate_c_per_min", sctx, min=0.0, min_exclusive=True)
                out.append(Ramp(to_c, rate_c_per_min=rate))
            else:
                out.append(Ramp(to_c, duration_s=get_quantity(
                    seg, "duration", sctx, TIME_UNITS, min=0.0, min_exclusive=True)))
        elif kind == "step":
            check_known_keys(seg, ("type", "to_c"), sctx)
            out.append(Step(_temperature(seg, "to_c", sctx)))
        elif kind == "profile":
            out.extend(_profile(seg, sctx))
        elif kind in ("repeat", "cycle"):
            check_known_keys(seg, ("type", "count", "segments"), sctx)
            count = get_int(seg, "count", sctx, min=1, max=100_000)
            nested = get_list(seg, "segments", sctx, min_len=1)
            out.append(Repeat(count, _parse_segments(nested, sctx, depth + 1)))
        else:  # random
            hold_keys = (*unit_keys("min_hold", TIME_UNITS), *unit_keys("max_hold", TIME_UNITS))
            check_known_keys(seg, ("type", "legs", "min_c", "max_c", "min_rate_c_per_min",
                                   "max_rate_c_per_min", "min_change_c", *hold_keys), sctx)
            legs = get_int(seg, "legs", sctx, min=1, max=100_000)
            lo = _temperature(seg, "min_c", sctx)
            hi = _temperature(seg, "max_c", sctx)
            if hi <= lo:
                raise sctx.error("max_c", f"value {hi:g} not allowed; must be > min_c ({lo:g})")
            rmin = get_float(seg, "min_rate_c_per_min", sctx, min=0.0, min_exclusive=True)
            rmax = get_float(seg, "max_rate_c_per_min", sctx, min=rmin)
            hmin = get_quantity(seg, "min_hold", sctx, TIME_UNITS, min=0.0)
            hmax = get_quantity(seg, "max_hold", sctx, TIME_UNITS, min=hmin)
            change = get_float(seg, "min_change_c", sctx, 0.0, min=0.0, max=(hi - lo) / 2)
            out.append(RandomProfile(legs, lo, hi, rmin, rmax, hmin, hmax, change))
    return tuple(out)


def _profile(seg: Mapping[str, Any], ctx: Ctx) -> list[Segment]:
    """A ``profile`` segment — a table of times from the segment's start (``time_s``,
    ``time_min`` or ``time_h``: increasing, the first 0) and ``temperature_c`` — as the steps,
    ramps and holds that join its points linearly (a vehicle bay's recorded or planned air
    temperature; the first point is jumped to, then rate-limited like any step)."""
    time_keys = unit_keys("time", TIME_UNITS)
    check_known_keys(seg, ("type", "temperature_c", *time_keys), ctx)
    present = [k for k in time_keys if k in seg]
    if len(present) != 1:
        raise ctx.error("time_s", f"give exactly one of {', '.join(time_keys)}")
    key = present[0]
    times = np.array(get_float_list(seg, key, ctx)) * TIME_UNITS[key[len("time_"):]]
    temps = get_float_list(seg, "temperature_c", ctx, length=len(times))
    if len(times) < 2 or times[0] != 0.0 or np.any(np.diff(times) <= 0):
        raise ctx.error(key, "needs at least two times, the first 0, strictly increasing")
    for v in temps:
        if not MIN_TEMPERATURE_C <= v <= MAX_TEMPERATURE_C:
            raise ctx.error("temperature_c", f"value {v:g} not allowed; must be in "
                                             f"[{MIN_TEMPERATURE_C:g}, {MAX_TEMPERATURE_C:g}]")
    out: list[Segment] = [Step(temps[0])]
    for dt, a, b in zip(np.diff(times).tolist(), temps[:-1], temps[1:]):
        out.append(Hold(dt) if a == b else Ramp(b, duration_s=dt))
    return out


def _table_error(ctx: Ctx, message: str) -> UserInputError:
    """A :class:`~rlgsim.ground.errors.UserInputError` about the table at ``ctx`` itself."""
    where = f"{ctx.source}: " if ctx.source else ""
    return UserInputError(f"{where}{ctx.path}: {message}")


# --------------------------------------------------------------------------- the programme


@dataclass
class ChamberProgram:
    """A chamber programme: start temperature, segments, rate limit, air lag.

    ``max_rate_c_per_min`` is the fastest the chamber air can be driven [°C/min];
    ``air_tau_s`` the first-order time constant of the air behind the rate-limited setpoint
    [s] (0 = the air is the rate-limited setpoint).
    """

    start_c: float
    segments: list[Segment] = field(default_factory=list)
    max_rate_c_per_min: float = DEFAULT_MAX_RATE_C_PER_MIN
    air_tau_s: float = DEFAULT_AIR_TAU_S
    #: the chamber's own air loop (``[chamber.controller]``, a controller of the ``kind`` it names:
    #: rlgsim.sim.thermal.chamber_controllers);
    #: None: the air is the rate-limited setpoint through the ``air_tau_s`` lag
    controller: Any = None

    KEYS = ("start_c", "segments", "max_rate_c_per_min", "air_tau_s", "controller")

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "ChamberProgram":
        """Build from a scenario's ``[chamber]`` table, validating every key."""
        if not isinstance(table, Mapping):
            raise _table_error(ctx, f"expected a table, got {type(table).__name__}")
        check_known_keys(table, cls.KEYS, ctx)
        start = _temperature(table, "start_c", ctx)
        segments = _parse_segments(get_list(table, "segments", ctx, []), ctx)
        max_rate = get_float(table, "max_rate_c_per_min", ctx, DEFAULT_MAX_RATE_C_PER_MIN,
                             min=0.0, min_exclusive=True)
        tau = get_float(table, "air_tau_s", ctx, DEFAULT_AIR_TAU_S, min=0.0, max=86400.0)
        controller = None
        if "controller" in table:
            if "air_tau_s" in table:
                raise ctx.error("air_tau_s", "not used with [chamber.controller] (the "
                                             "controller's air loop replaces the air lag)")
            from rlgsim.sim.thermal.chamber_controllers import controller_from_config
            controller = controller_from_config(get_table(table, "controller", ctx),
                                                ctx.child("controller"))
        program = cls(start_c=start, segments=list(segments), max_rate_c_per_min=max_rate,
                      air_tau_s=tau, controller=controller)
        n = program._count_breakpoints(program.segments)
        if n > MAX_BREAKPOINTS:
            raise ctx.error("segments", f"the programme expands to {n} breakpoints; at most "
                                        f"{MAX_BREAKPOINTS} are allowed")
        return program

    @staticmethod
    def _count_breakpoints(segments) -> int:
        n = 0
        for seg in segments:
            if isinstance(seg, Repeat):
                n += seg.count * ChamberProgram._count_breakpoints(seg.segments)
            elif isinstance(seg, RandomProfile):
                n += 2 * seg.legs
            else:
                n += 1
        return n

    # ----------------------------------------------------------------- raw setpoint

    def setpoint(self, rng: np.random.Generator | None = None) -> PiecewiseLinear:
        """The programmed setpoint (before the rate limit) as breakpoints from t = 0.

        ``rng`` draws the ``random`` segments (in programme order: per leg target, rate,
        hold); it may be ``None`` when there are none. Zero-length moves add no breakpoint;
        a ``step`` adds a repeated time (a jump).
        """
        t: list[float] = [0.0]
        y: list[float] = [float(self.start_c)]

        def add(tn: float, yn: float) -> None:
            if tn == t[-1] and yn == y[-1]:
                return
            t.append(tn)
            y.append(yn)

        def run(segments) -> None:
            for seg in segments:
                now, cur = t[-1], y[-1]
                if isinstance(seg, Hold):
                    add(now + seg.duration_s, cur)
                elif isinstance(seg, Ramp):
                    if seg.duration_s is not None:
                        add(now + seg.duration_s, seg.to_c)
                    elif seg.to_c != cur:
                        add(now + abs(seg.to_c - cur) / seg.rate_c_per_min * MINUTE, seg.to_c)
                elif isinstance(seg, Step):
                    if seg.to_c != cur:
                        # a jump: a repeated time (keep the strictly earlier one distinct)
                        t.append(now)
                        y.append(seg.to_c)
                elif isinstance(seg, Repeat):
                    for _ in range(seg.count):
                        run(seg.segments)
                elif isinstance(seg, RandomProfile):
                    if rng is None:
                        raise ValueError("a random chamber segment needs a generator")
                    for _ in range(seg.legs):
                        target = _draw_target(rng, y[-1], seg)
                        rate = rng.uniform(seg.min_rate_c_per_min, seg.max_rate_c_per_min)
                        hold = rng.uniform(seg.min_hold_s, seg.max_hold_s)
                        if target != y[-1]:
                            add(t[-1] + abs(target - y[-1]) / rate * MINUTE, target)
                        if hold > 0:
                            add(t[-1] + hold, y[-1])
                else:  # pragma: no cover - parser guarantees the types
                    raise TypeError(f"unknown segment {seg!r}")

        run(self.segments)
        return PiecewiseLinear(t, y)

    # ----------------------------------------------------------------- rate limit

    def rate_limited(self, setpoint: PiecewiseLinear) -> PiecewiseLinear:
        """The setpoint as the chamber can follow it: an exact slew-rate limiter.

        The output starts at the setpoint's first value and, whenever it differs from the
        programme, moves towards it at ``max_rate_c_per_min``; once it has caught up it tracks
        the programme as long as the programme's slope is within the limit. Every breakpoint
        (including the catch-up instants) is computed in closed form, so the result is again
        piecewise linear and continuous. The programme clock is kept: a step becomes a ramp at
        the maximum rate that eats into the following hold; a ramp faster than the maximum is
        slowed to it. If the programme ends before the output has caught up, the output
        continues to its final value (so ``end_s`` can be later than the programme's).
        """
        return rate_limit(setpoint, self.max_rate_c_per_min / MINUTE)


def _draw_target(rng: np.random.Generator, current: float, seg: RandomProfile) -> float:
    """A target uniform on ``[min_c, max_c]`` minus the band ``current ± min_change_c``."""
    lo, hi, gap = seg.min_c, seg.max_c, seg.min_change_c
    if gap <= 0:
        return float(rng.uniform(lo, hi))
    # allowed pieces [lo, current-gap] and [current+gap, hi], intersected with [lo, hi]
    a1, b1 = lo, min(hi, current - gap)
    a2, b2 = max(lo, current + gap), hi
    w1, w2 = max(0.0, b1 - a1), max(0.0, b2 - a2)
    u = float(rng.uniform(0.0, w1 + w2))
    if w1 + w2 <= 0:            # cannot happen with min_change_c <= (max_c - min_c)/2
        return float(current)
    return a1 + u if u < w1 else a2 + (u - w1)


def rate_limit(setpoint: PiecewiseLinear, max_rate_k_per_s: float) -> PiecewiseLinear:
    """Exact slew-rate limit (|dy/dt| ≤ ``max_rate_k_per_s``) of a piecewise-linear input.

    Event-based: on each input piece (linear, slope ``s``) the output either tracks the input
    (caught up and ``|s| ≤ r``) or moves at ``±r`` towards it; the time it catches up is the
    root of a linear equation. See :meth:`ChamberProgram.rate_limited`.
    """
    r = float(max_rate_k_per_s)
    if not r > 0:
        raise ValueError("max rate must be > 0")
    tin, yin = setpoint.t_s, setpoint.y
    t_out = [float(tin[0])]
    y_out = [float(yin[0])]
    # tolerance for "caught up": relative to the temperatures involved
    scale = max(1.0, float(np.max(np.abs(yin))))
    eps = 1e-12 * scale

    def push(t: float, y: float) -> None:
        if t > t_out[-1]:
            t_out.append(t)
            y_out.append(y)
        else:          # same instant: keep the latest value (can only be equal here)
            y_out[-1] = y

    t, y = float(tin[0]), float(yin[0])
    for k in range(len(tin) - 1):
        t0, t1 = float(tin[k]), float(tin[k + 1])
        x0, x1 = float(yin[k]), float(yin[k + 1])
        if t1 == t0:           # jump in the input: the output does not jump
            continue
        s = (x1 - x0) / (t1 - t0)
        caught = abs(x0 + s * (t - t0) - y) <= eps
        # advance from t (== t0) to t1 on this piece
        while t < t1:
            if caught:
                if abs(s) <= r:          # track the input to the end of the piece
                    t, y = t1, x1
                else:                    # input faster than allowed: fall behind at full rate
                    y = y + (1.0 if s > 0 else -1.0) * r * (t1 - t)
                    t = t1
                push(t, y)
                break
            d = x0 + s * (t - t0) - y
            direction = 1.0 if d > 0 else -1.0
            closing = r - direction * s            # > 0: the output closes the gap
            if closing > 0:
                tc = t + abs(d) / closing
                if tc < t1:
                    # move along the limiter's own ramp (keeps |slope| <= r to rounding; the
                    # input's value at tc would carry the input slope's rounding error)
                    y = y + direction * r * (tc - t)
                    t = tc
                    push(t, y)
                    caught = True
                    continue
            y = y + direction * r * (t1 - t)
            t = t1
            push(t, y)
    # after the last breakpoint the input is constant: finish the catch-up
    x_end = float(yin[-1])
    d = x_end - y
    if abs(d) > eps:
        push(t + abs(d) / r, x_end)
    else:
        y_out[-1] = x_end if abs(y_out[-1] - x_end) <= eps else y_out[-1]
    return PiecewiseLinear(t_out, y_out)
