"""Per-unit chamber-profile variations for Monte Carlo campaigns (``rlgsim montecarlo
--chamber-offset-c S --chamber-rate-rel R``).

A real campaign never repeats the chamber profile exactly: the chamber's temperature
calibration is off by a fraction of a kelvin and its ramps run a little fast or slow. With
variations switched on, every scenario a Monte Carlo unit simulates gets

* an offset ``δ ~ N(0, S)`` [K] added to every temperature of its chamber programme (start,
  ramp and step targets, the bounds of random profiles);
* a rate factor ``f = exp(R·N(0,1))`` on every ramp rate (a ramp given by duration lasts
  ``1/f`` as long; random-profile rate bounds scale by ``f``),

drawn from ``rlgsim.sim.rng.generator(scenario.seed, unit, "chamber", "variation", 0)`` — per run
(the train and test runs of a unit, which have their own seeds, vary independently, like two
runs of a real chamber) and per unit, never per worker. The chamber's rate limit and air lag
stay as they are; a scenario with a fixed duration keeps it (a slower programme is cut, a faster
one holds its last setpoint).

The variations travel as a :class:`ChamberVariation` in a :class:`contextvars.ContextVar` that
:func:`varied` sets around a unit's run (so it works on any executor, threads included) and that
:func:`rlgsim.lab.study.scenario_for` applies through :func:`apply`. Without variations nothing
changes.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import math
from dataclasses import dataclass
from typing import Iterator

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.thermal.chamber import (MAX_TEMPERATURE_C, MIN_TEMPERATURE_C, ChamberProgram,
                                        Hold, RandomProfile, Ramp, Repeat, Step)
from rlgsim.sim.rng import generator


@dataclass(frozen=True)
class ChamberVariation:
    """1-σ spreads: ``offset_c`` [K] and ``rate_rel`` (relative, log-normal)."""

    offset_c: float = 0.0
    rate_rel: float = 0.0

    def __post_init__(self) -> None:
        for name in ("offset_c", "rate_rel"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")

    @property
    def active(self) -> bool:
        return self.offset_c > 0 or self.rate_rel > 0


_CURRENT: contextvars.ContextVar[ChamberVariation | None] = contextvars.ContextVar(
    "rlgsim_chamber_variation", default=None)


@contextlib.contextmanager
def varied(variation: ChamberVariation | None) -> Iterator[None]:
    """Apply ``variation`` to every scenario loaded for a study unit inside the block."""
    token = _CURRENT.set(variation)
    try:
        yield
    finally:
        _CURRENT.reset(token)


def draw(seed: int, unit: int, variation: ChamberVariation) -> tuple[float, float]:
    """(offset [K], rate factor) of run ``seed`` for unit ``unit``."""
    z = generator(seed, unit, "chamber", "variation", 0).standard_normal(2)
    e = float(variation.rate_rel * z[1])
    return float(variation.offset_c * z[0]), math.exp(e) if e < 709.0 else math.inf


def vary_program(program: ChamberProgram, offset_c: float, rate_factor: float
                 ) -> ChamberProgram:
    """``program`` with every temperature shifted by ``offset_c`` and every rate scaled by
    ``rate_factor``."""
    def seg(s):
        if isinstance(s, Ramp):
            return Ramp(to_c=s.to_c + offset_c,
                        rate_c_per_min=None if s.rate_c_per_min is None
                        else s.rate_c_per_min * rate_factor,
                        duration_s=None if s.duration_s is None else s.duration_s / rate_factor)
        if isinstance(s, Step):
            return Step(to_c=s.to_c + offset_c)
        if isinstance(s, Repeat):
            return Repeat(count=s.count, segments=tuple(seg(x) for x in s.segments))
        if isinstance(s, RandomProfile):
            return dataclasses.replace(s, min_c=s.min_c + offset_c, max_c=s.max_c + offset_c,
                                       min_rate_c_per_min=s.min_rate_c_per_min * rate_factor,
                                       max_rate_c_per_min=s.max_rate_c_per_min * rate_factor)
        if isinstance(s, Hold):
            return s
        raise TypeError(f"unknown chamber segment {s!r}")
    return dataclasses.replace(program, start_c=program.start_c + offset_c,
                               segments=[seg(s) for s in program.segments])


def apply(scenario):
    """``scenario`` with the current unit's chamber variation (unchanged when none is set)."""
    variation = _CURRENT.get()
    if variation is None or not variation.active:
        return scenario
    offset, factor = draw(scenario.seed, scenario.unit, variation)
    if not 0.0 < factor < math.inf:     # before the program is varied (a ramp's duration / 0)
        why = (f"a rate factor of {factor:.4g} (from --chamber-rate-rel {variation.rate_rel:g});"
               f" ramp rates are scaled by a finite factor > 0")
    else:
        program = vary_program(scenario.chamber, offset, factor)
        bad = [t for t in _temperatures(program)
               if not MIN_TEMPERATURE_C <= t <= MAX_TEMPERATURE_C]
        if not bad:
            return dataclasses.replace(scenario, chamber=program)
        why = (f"an offset of {offset:+.4g} K (from --chamber-offset-c {variation.offset_c:g}), "
               f"which takes the chamber to {bad[0]:.4g} °C; it holds {MIN_TEMPERATURE_C:g} to "
               f"{MAX_TEMPERATURE_C:g} °C")
    raise UserInputError(f"unit {scenario.unit}, scenario {scenario.name}: the drawn chamber "
                         f"variation has {why} — give smaller spreads")


def _temperatures(program: ChamberProgram) -> Iterator[float]:
    """Every temperature a chamber programme names [°C] (start, targets, random bounds)."""
    def walk(segments) -> Iterator[float]:
        for s in segments:
            if isinstance(s, (Ramp, Step)):
                yield s.to_c
            elif isinstance(s, RandomProfile):
                yield from (s.min_c, s.max_c)
            elif isinstance(s, Repeat):
                yield from walk(s.segments)
    yield program.start_c
    yield from walk(program.segments)
