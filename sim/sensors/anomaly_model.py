"""The sensor anomalies' model: the ``[anomalies]`` table of a device preset and the rows of the
event record (issue 12; docs/sensors.md "Anomalies"); :mod:`rlgsim.sim.sensors.anomalies` applies
it to a run.

An optional ``[anomalies]`` table of a device preset switches on any of:

``mode_hop``       longitudinal mode hops of each gyro when its cavity-length (frequency)
                   control runs out of range: a bias step with thermal hysteresis;
``pulse_spikes``   isolated read-out glitches: a whole number of extra (or missing) pulses in
                   one sample of one gyro channel;
``imu_dropouts``   lost IMU frames: the pulses of those samples never reach the log (the
                   samples are flagged invalid, their counts are zero in the log and the lost
                   counts are stored in the event record);
``probe_glitches`` one thermometer reading replaced by a fixed wrong value (a digital
                   thermometer's power-on-reset value, 85 °C for the DS18B20 class);
``probe_stuck``    a thermometer repeats its last good reading for a while (a bus read
                   failure answered from the logger's cache);
``probe_dropouts`` missing thermometer readings (NaN) for a while.

Mode hops (the physics; docs/sensors.md derives the numbers). The controller keeps the optical
path an integer number ``k`` of wavelengths long by moving a mirror (piezo transducer) or, in
the total-reflection-prism gyro of paper 001 §2.1, by heating the air channel X3. The cavity
grows with temperature, so the actuator must take up ``x(T) = κ (T_c − T_ref)`` mode spacings
(free spectral ranges), ``κ = L α_eff / λ``; it sits at ``p = x − k`` and has the range
``|p| ≤ R/2`` (``R > 1`` mode spacings). When ``p`` leaves the range the controller re-locks on
the neighbouring longitudinal mode (``k → k ± 1``, ``p → p ∓ 1``)::

    hop up   k → k + 1   when κ (T_c − T_ref) > k + R/2
    hop down k → k − 1   when κ (T_c − T_ref) < k − R/2                                  (A1)

so going up the gyro hops at ``T_ref + (k + R/2)/κ`` and coming down it hops back at
``T_ref + (k + 1 − R/2)/κ``: a hysteresis loop of width ``(R − 1)/κ`` in temperature. The
bias depends on the mode (its place on the neon gain curve and the backscatter phase at the
mirrors change): ``b = b_0 + k·Δb`` (``bias_step_deg_per_h``), so the bias carries the same
hysteresis. At the start the controller locks on the mode nearest its centre,
``k_0 = round(x(T_c(0)))``. ``T_c`` is the mean of the gyro's nodes named in the table; the
hop is detected on the thermal grid (the bias steps at the end of the step in which ``x``
crossed the limit).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from rlgsim.sim.config import (Ctx, check_known_keys, get_bool, get_float, get_list, get_str,
                               get_table)

__all__ = ["KINDS", "DS18B20_RESET_C", "EVENT_FIELDS", "ModeHop", "AnomalyModel", "Events"]

KINDS = ("mode_hop", "pulse_spikes", "imu_dropouts", "probe_glitches", "probe_stuck",
         "probe_dropouts")

#: The power-on-reset value of a DS18B20-class digital thermometer's temperature register
#: [°C] (Maxim DS18B20 datasheet: "the power-on reset value of the temperature register is
#: +85 °C"): what such a probe returns when a conversion is read before it completed.
DS18B20_RESET_C = 85.0

EVENT_FIELDS = ("time_s", "end_s", "channel", "kind", "size", "units")


# --------------------------------------------------------------------------- model


@dataclass(frozen=True)
class ModeHop:
    """Cavity-length control with a finite range (eq. (A1))."""

    nodes: tuple[str, ...]            # template-local nodes of each gyro block, averaged
    modes_per_k: float                # κ [mode spacings per K]
    range_modes: float                # R [mode spacings], > 1
    reference_c: float                # T_ref [°C]: the actuator is centred here for k = 0
    bias_step_deg_per_h: float        # Δb per mode [°/h]
    # unit-to-unit spread (Monte Carlo units ≥ 1): 1σ relative spreads of κ and Δb, and a
    # uniformly drawn lock point (the cavity length modulo λ differs from unit to unit)
    modes_per_k_rel: float = 0.0
    bias_step_rel: float = 0.0
    phase_per_unit: bool = True

    @property
    def hysteresis_k(self) -> float:
        """Width of the hysteresis loop in temperature [K]: ``(R − 1)/κ``."""
        return (self.range_modes - 1.0) / self.modes_per_k


@dataclass(frozen=True)
class AnomalyModel:
    """The ``[anomalies]`` table of a device preset (every part optional; rates per channel)."""

    mode_hop: ModeHop | None = None
    pulse_spike_rate_per_h: float = 0.0
    pulse_spike_max_pulses: int = 0
    imu_dropout_rate_per_h: float = 0.0
    imu_dropout_mean_samples: float = 1.0
    probe_glitch_rate_per_h: float = 0.0
    probe_glitch_value_c: float = DS18B20_RESET_C
    probe_stuck_rate_per_h: float = 0.0
    probe_stuck_mean_s: float = 60.0
    probe_dropout_rate_per_h: float = 0.0
    probe_dropout_mean_s: float = 10.0

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "AnomalyModel":
        """Validate an ``[anomalies]`` table (UserInputError naming file and key)."""
        check_known_keys(table, KINDS + ("description", "source"), ctx)
        get_str(table, "description", ctx, "")
        get_str(table, "source", ctx, "")
        kw: dict[str, Any] = {}
        if "mode_hop" in table:
            t, c = get_table(table, "mode_hop", ctx), ctx.child("mode_hop")
            check_known_keys(t, ("nodes", "modes_per_k", "range_modes", "reference_c",
                                 "bias_step_deg_per_h", "source", "modes_per_k_rel",
                                 "bias_step_rel", "phase_per_unit"), c)
            get_str(t, "source", c, "")
            nodes = get_list(t, "nodes", c, min_len=1)
            for i, nd in enumerate(nodes):
                if not isinstance(nd, str):
                    raise c.error("nodes", f"expected node names, got {nd!r} at {i}")
            kw["mode_hop"] = ModeHop(
                nodes=tuple(nodes),
                modes_per_k=get_float(t, "modes_per_k", c, min=0.0, min_exclusive=True,
                                      max=100.0),
                range_modes=get_float(t, "range_modes", c, min=1.0, min_exclusive=True,
                                      max=1000.0),
                reference_c=get_float(t, "reference_c", c, 20.0, min=-100.0, max=200.0),
                bias_step_deg_per_h=get_float(t, "bias_step_deg_per_h", c, min=-100.0,
                                              max=100.0),
                modes_per_k_rel=get_float(t, "modes_per_k_rel", c, 0.0, min=0.0, max=1.0),
                bias_step_rel=get_float(t, "bias_step_rel", c, 0.0, min=0.0, max=10.0),
                phase_per_unit=get_bool(t, "phase_per_unit", c, True))

        def section(key: str, keys: tuple[str, ...]) -> tuple[dict, Ctx] | None:
            if key not in table:
                return None
            t, c = get_table(table, key, ctx), ctx.child(key)
            check_known_keys(t, keys + ("source",), c)
            get_str(t, "source", c, "")
            return t, c

        rate = dict(min=0.0, max=3600.0)
        if s := section("pulse_spikes", ("rate_per_h", "max_pulses")):
            t, c = s
            kw["pulse_spike_rate_per_h"] = get_float(t, "rate_per_h", c, **rate)
            kw["pulse_spike_max_pulses"] = int(get_float(t, "max_pulses", c, min=1.0,
                                                         max=1e6))
            if kw["pulse_spike_max_pulses"] != get_float(t, "max_pulses", c):
                raise c.error("max_pulses", "expected a whole number of pulses")
        if s := section("imu_dropouts", ("rate_per_h", "mean_samples")):
            t, c = s
            kw["imu_dropout_rate_per_h"] = get_float(t, "rate_per_h", c, **rate)
            kw["imu_dropout_mean_samples"] = get_float(t, "mean_samples", c, 1.0, min=1.0,
                                                       max=1e6)
        if s := section("probe_glitches", ("rate_per_h", "value_c")):
            t, c = s
            kw["probe_glitch_rate_per_h"] = get_float(t, "rate_per_h", c, **rate)
            kw["probe_glitch_value_c"] = get_float(t, "value_c", c, DS18B20_RESET_C,
                                                   min=-300.0, max=1000.0)
        if s := section("probe_stuck", ("rate_per_h", "mean_duration_s")):
            t, c = s
            kw["probe_stuck_rate_per_h"] = get_float(t, "rate_per_h", c, **rate)
            kw["probe_stuck_mean_s"] = get_float(t, "mean_duration_s", c, 60.0, min=0.0,
                                                 min_exclusive=True, max=1e6)
        if s := section("probe_dropouts", ("rate_per_h", "mean_duration_s")):
            t, c = s
            kw["probe_dropout_rate_per_h"] = get_float(t, "rate_per_h", c, **rate)
            kw["probe_dropout_mean_s"] = get_float(t, "mean_duration_s", c, 10.0, min=0.0,
                                                   min_exclusive=True, max=1e6)
        return cls(**kw)

    @property
    def active(self) -> bool:
        return (self.mode_hop is not None or self.pulse_spike_rate_per_h > 0
                or self.imu_dropout_rate_per_h > 0 or self.probe_glitch_rate_per_h > 0
                or self.probe_stuck_rate_per_h > 0 or self.probe_dropout_rate_per_h > 0)


# --------------------------------------------------------------------------- events


@dataclass
class Events:
    """Rows of the event record (see the module docstring), appended per block."""

    time_s: list[float] = field(default_factory=list)
    end_s: list[float] = field(default_factory=list)
    channel: list[str] = field(default_factory=list)
    kind: list[str] = field(default_factory=list)
    size: list[float] = field(default_factory=list)
    units: list[str] = field(default_factory=list)

    def add(self, t0: float, t1: float, channel: str, kind: str, size: float, units: str
            ) -> None:
        self.time_s.append(float(t0))
        self.end_s.append(float(t1))
        self.channel.append(str(channel))
        self.kind.append(kind)
        self.size.append(float(size))
        self.units.append(units)

    def extend(self, other: "Events") -> None:
        for f in EVENT_FIELDS:
            getattr(self, f).extend(getattr(other, f))

    def __len__(self) -> int:
        return len(self.time_s)

    def arrays(self) -> dict[str, np.ndarray]:
        """The rows as arrays sorted by (time, channel, kind) — a stable order."""
        order = sorted(range(len(self)), key=lambda i: (self.time_s[i], self.channel[i],
                                                         self.kind[i]))
        out: dict[str, np.ndarray] = {}
        for f in EVENT_FIELDS:
            vals = [getattr(self, f)[i] for i in order]
            out[f] = (np.array(vals, dtype=float) if f in ("time_s", "end_s", "size")
                      else np.array(vals, dtype=object).astype(str) if vals
                      else np.zeros(0, dtype=str))
        return out
