"""The run's timeline, built by simpy processes (docs/design.md "data flow": schedule).

Each part of an experiment is a simpy process on one shared clock: the chamber programme, the
power switch, the turntable programme, the calibration windows and the data acquisition. Each
process walks through *its own segments* (a hold, a ramp, a rotation, a calibration window, a
600 s acquisition block) and records them as labelled :class:`TimelineSegment`s on its track.
simpy sees a handful of events per segment — never one per sample: the numerics (thermal
propagation, probes, sensors) run later, vectorised per block, in :mod:`rlgsim.sim.run.simulate`.

Events are put on the thermal grid ``k·thermal_step_s`` (rounded to the nearest step): power
switch times and the breakpoints of the rate-limited chamber setpoint. Between grid points the
setpoint is linear and the power constant, which is what the exact thermal integrator assumes
(first-order hold for the setpoint, zero-order hold for the power).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import simpy

from rlgsim.ground.dataset_format import TRACKS   # the timeline's tracks, in dataset order


@dataclass(frozen=True)
class TimelineSegment:
    """One labelled stretch ``[t0_s, t1_s)`` of one track (times in s from the run start)."""

    t0_s: float
    t1_s: float
    track: str
    label: str
    attrs: dict[str, Any] = field(default_factory=dict)


class PiecewiseConstant:
    """A step function: ``values[i]`` holds on ``[t_s[i], t_s[i+1])``; the last holds forever.

    ``t_s`` strictly increasing, starting at 0.
    """

    def __init__(self, t_s, values) -> None:
        self.t_s = np.asarray(t_s, dtype=float)
        self.values = np.asarray(values, dtype=float)
        if self.t_s.ndim != 1 or self.t_s.shape != self.values.shape or not len(self.t_s):
            raise ValueError("t_s and values must be 1-D arrays of the same non-zero length")
        if np.any(np.diff(self.t_s) <= 0):
            raise ValueError("t_s must be strictly increasing")

    def __call__(self, t) -> np.ndarray:
        idx = np.searchsorted(self.t_s, np.asarray(t, dtype=float), side="right") - 1
        return self.values[np.clip(idx, 0, len(self.values) - 1)]

    def __repr__(self) -> str:
        return f"PiecewiseConstant(t_s={self.t_s.tolist()}, values={self.values.tolist()})"


@dataclass
class Timeline:
    """What happens when: the inputs of the numerics and the labelled segments."""

    duration_s: float
    step_s: float                      # thermal grid step
    setpoint: Any                      # rate-limited chamber setpoint (PiecewiseLinear), on the grid
    power: PiecewiseConstant           # 0/1 power state, switch times on the grid
    segments: list[TimelineSegment]    # sorted by (track order, t0)
    turntable: Any = None              # the turntable programme (None: static mount)

    @property
    def n_steps(self) -> int:
        return int(round(self.duration_s / self.step_s))

    def track(self, name: str) -> list[TimelineSegment]:
        return [s for s in self.segments if s.track == name]


def _on_grid(t: float, step: float) -> float:
    return round(t / step) * step


def _setpoint_on_grid(setpoint, step: float):
    """The setpoint with its breakpoints moved to the nearest grid point (later point wins)."""
    t = np.round(np.asarray(setpoint.t_s, float) / step) * step
    y = np.asarray(setpoint.y, float)
    keep = np.r_[t[1:] != t[:-1], True]           # of equal times keep the last
    t, y = t[keep], y[keep]
    if np.array_equal(t, setpoint.t_s) and np.array_equal(y, setpoint.y):
        return setpoint
    return type(setpoint)(t, y)


def _fmt(x: float) -> str:
    return f"{x:g}"


def _chamber_process(env: simpy.Environment, setpoint, duration: float, out: list) -> Any:
    t, y = np.asarray(setpoint.t_s, float), np.asarray(setpoint.y, float)
    for i in range(len(t) - 1):
        t0, t1 = max(t[i], 0.0), min(t[i + 1], duration)
        if t1 <= t0:
            continue
        if env.now < t0:
            yield env.timeout(t0 - env.now)
        if y[i + 1] == y[i]:
            label, attrs = f"hold {_fmt(y[i])} °C", {"kind": "hold", "temperature_c": y[i]}
        else:
            rate = (y[i + 1] - y[i]) / (t[i + 1] - t[i]) * 60.0
            label = f"ramp {_fmt(y[i])} → {_fmt(y[i + 1])} °C at {rate:+.4g} °C/min"
            attrs = {"kind": "ramp", "from_c": y[i], "to_c": y[i + 1], "rate_c_per_min": rate}
        out.append(TimelineSegment(t0, t1, "chamber", label, attrs))
        yield env.timeout(t1 - t0)
    if env.now < duration:
        last = float(y[-1])
        out.append(TimelineSegment(env.now, duration, "chamber", f"hold {_fmt(last)} °C",
                                   {"kind": "hold", "temperature_c": last}))


def _power_process(env: simpy.Environment, power: PiecewiseConstant, duration: float,
                   out: list) -> Any:
    bounds = [*power.t_s.tolist(), duration]
    for i, state in enumerate(power.values):
        t0, t1 = bounds[i], min(bounds[i + 1], duration)
        if t1 <= t0:
            continue
        out.append(TimelineSegment(t0, t1, "power", "on" if state else "off",
                                   {"powered": bool(state)}))
        yield env.timeout(t1 - env.now)


def _turntable_motions(turntable, duration: float) -> list[TimelineSegment]:
    """The programme's motions (rlgsim.sim.motion.turntable.TurntableProgram.motions) laid on the time axis."""
    if turntable is None:
        return []
    out, t = [], 0.0
    names = None
    for m in turntable.motions(until_s=duration):
        if names is None:
            names = [f.name for f in dataclasses.fields(m)]
        # the fields of TableMotion (= m.attrs(), without asdict's deep copies: 10× faster)
        attrs = {name: getattr(m, name) for name in names}
        out.append(TimelineSegment(t, t + m.duration_s, "turntable", m.label, attrs))
        t += m.duration_s
    return out


def _calibration_windows(motions: list[TimelineSegment]) -> list[TimelineSegment]:
    """One segment per calibration window: the motions sharing a ``window`` index."""
    out: list[TimelineSegment] = []
    for seg in motions:
        w = seg.attrs.get("window")
        if w is None:
            continue
        if out and out[-1].attrs["window"] == w:
            last = out[-1]
            out[-1] = TimelineSegment(last.t0_s, seg.t1_s, "calibration", last.label,
                                      {**last.attrs, "motions": last.attrs["motions"] + 1})
        else:
            out.append(TimelineSegment(seg.t0_s, seg.t1_s, "calibration",
                                       f"calibration window {w}", {"window": w, "motions": 1}))
    return out


def _replay_process(env: simpy.Environment, segments: list[TimelineSegment], out: list) -> Any:
    """Walk through prepared segments on the shared clock (one event per segment)."""
    for seg in segments:
        if env.now < seg.t0_s:
            yield env.timeout(seg.t0_s - env.now)
        out.append(seg)
        yield env.timeout(max(0.0, seg.t1_s - env.now))


def _static_process(env: simpy.Environment, duration: float, out: list) -> Any:
    out.append(TimelineSegment(0.0, duration, "turntable", "static mount", {"kind": "static"}))
    yield env.timeout(duration)


def _acquisition_process(env: simpy.Environment, duration: float, rate_hz: float,
                         step_s: float, out: list) -> Any:
    out.append(TimelineSegment(0.0, duration, "acquisition", "recording",
                               {"sample_rate_hz": rate_hz, "thermal_step_s": step_s}))
    yield env.timeout(duration)


def build_timeline(scenario) -> "Timeline":
    """Run the simpy processes of ``scenario`` and return its :class:`Timeline`."""
    step = scenario.acquisition.thermal_step_s
    duration = scenario.duration_s
    chamber = scenario.chamber
    setpoint = _setpoint_on_grid(chamber.rate_limited(chamber.setpoint(scenario.chamber_rng())),
                                 step)
    on = _on_grid(scenario.power.on_at_s, step)
    off = None if scenario.power.off_at_s is None else _on_grid(scenario.power.off_at_s, step)
    times, states = [0.0], [1.0 if on <= 0 else 0.0]
    if on > 0:
        times.append(on)
        states.append(1.0)
    if off is not None and off > on:
        times.append(off)
        states.append(0.0)
    power = PiecewiseConstant(times, states)

    env = simpy.Environment()
    found: dict[str, list[TimelineSegment]] = {track: [] for track in TRACKS}
    env.process(_chamber_process(env, setpoint, duration, found["chamber"]))
    env.process(_power_process(env, power, duration, found["power"]))
    motions = _turntable_motions(scenario.turntable, duration)
    if motions:
        env.process(_replay_process(env, motions, found["turntable"]))
        env.process(_replay_process(env, _calibration_windows(motions), found["calibration"]))
    else:
        env.process(_static_process(env, duration, found["turntable"]))
    env.process(_acquisition_process(env, duration, scenario.acquisition.sample_rate_hz, step,
                                     found["acquisition"]))
    env.run(until=duration + step)
    segments = [seg for track in TRACKS for seg in sorted(found[track], key=lambda s: s.t0_s)]
    return Timeline(duration_s=duration, step_s=step, setpoint=setpoint, power=power,
                    segments=segments, turntable=scenario.turntable)
