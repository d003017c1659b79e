"""Sensor anomalies, every event labelled in the truth (issue 12; docs/sensors.md "Anomalies").

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

Random events are drawn per block ``b`` and kind from
``generator(seed, unit, "anomalies", kind, b)``: per channel a Poisson count with mean
``rate · block length``, then per event (in channel order) a uniform sample index and its size.
Nothing depends on how blocks are grouped into writes. An event that would start while its
channel is already in a stuck or dropout interval (or a glitch/spike that falls into one) is
dropped, so every recorded event is visible in the output. Stuck and dropout intervals carry
over block ends (the state holds their end and the held value).

The event record (one row per event): ``time_s`` (start: the end of the first affected sample
or thermal step, the dataset's time convention), ``end_s``, ``channel`` (gyro axis or probe
name), ``kind``, ``size`` and ``units`` — bias step [deg/h] for mode hops, pulses for spikes,
lost pulses for dropouts, the replaced-minus-true reading [°C] for glitches, the duration [s]
for stuck readings and probe dropouts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from rlgsim.ground.units import deg_per_h_to_rad_per_s
from rlgsim.sim.config import (Ctx, check_known_keys, get_bool, get_float, get_list, get_str,
                               get_table)
from rlgsim.sim.rng import generator

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


# --------------------------------------------------------------------------- the bound model


@dataclass
class AnomalyState:
    """Carried from block to block."""

    mode: np.ndarray | None                     # (G,) int: current longitudinal mode index
    imu_lost_left: int = 0                      # samples still to lose of a running dropout
    probe_until: np.ndarray | None = None       # (P,) global thermal step index where a
    probe_kind: np.ndarray | None = None        #   stuck (1) / dropout (2) interval ends
    probe_held: np.ndarray | None = None        # (P,) the held reading of a stuck probe
    probe_last: np.ndarray | None = None        # (P,) last reading written (for stuck)


class Anomalies:
    """An :class:`AnomalyModel` bound to one device: gyro axes and blocks, thermometer names,
    the thermal network's node names, the seed tree."""

    def __init__(self, model: AnomalyModel, *, node_names: Sequence[str],
                 gyro_axes: Sequence[str] = (), gyro_blocks: Sequence[str] = (),
                 probe_names: Sequence[str] = (), seed: int = 0, unit: int = 0,
                 source: str = "") -> None:
        self.model = model
        self.gyro_axes = tuple(gyro_axes)
        self.probe_names = tuple(probe_names)
        self.seed, self.unit = int(seed), int(unit)
        self.hop_nodes: list[np.ndarray] = []
        #: the mode-hop parameters of each gyro (the model's, or a drawn unit's: realise_unit)
        self.hops: list[ModeHop] = []
        if model.mode_hop is not None:
            self.hops = [model.mode_hop] * len(self.gyro_axes)
            if len(gyro_blocks) != len(self.gyro_axes):
                raise ValueError("one gyro block per gyro axis is needed for mode hops")
            names = list(node_names)
            for block in gyro_blocks:
                idx = []
                for nd in model.mode_hop.nodes:
                    full = f"{block}.{nd}" if f"{block}.{nd}" in names else nd
                    if full not in names:
                        from rlgsim.ground.errors import UserInputError
                        raise UserInputError(
                            f"{source + ': ' if source else ''}anomalies.mode_hop.nodes: "
                            f"node {nd!r} is neither a node of gyro block {block!r} nor of "
                            f"the thermal network")
                    idx.append(names.index(full))
                self.hop_nodes.append(np.array(idx, dtype=np.int64))

    def realise_unit(self, rng: np.random.Generator) -> None:
        """Draw one unit's mode-hop parameters per gyro (Monte Carlo units ≥ 1): κ and Δb
        with their relative spreads, and — with ``phase_per_unit`` — the lock point: the
        cavity length of a unit modulo one wavelength is arbitrary, so the temperatures at
        which it hops are shifted by a uniform fraction of a mode spacing. Draw order per
        gyro: N(0,1) for κ, N(0,1) for Δb, U(0,1) for the phase."""
        import dataclasses
        out = []
        for mh in self.hops:
            z1, z2, u = rng.standard_normal(), rng.standard_normal(), rng.random()
            kappa = mh.modes_per_k * math.exp(mh.modes_per_k_rel * z1)
            ref = mh.reference_c + ((u - 0.5) / kappa if mh.phase_per_unit else 0.0)
            out.append(dataclasses.replace(
                mh, modes_per_k=kappa, reference_c=ref,
                bias_step_deg_per_h=mh.bias_step_deg_per_h * (1.0 + mh.bias_step_rel * z2)))
        self.hops = out

    # ----------------------------------------------------------------- states

    def initial_state(self, start_c: np.ndarray) -> AnomalyState:
        """The state before block 0; ``start_c`` (n,) node temperatures at t = 0."""
        mode = None
        if self.hops:
            x = np.array([mh.modes_per_k * (np.mean(start_c[i]) - mh.reference_c)
                          for mh, i in zip(self.hops, self.hop_nodes)])
            mode = np.rint(x).astype(np.int64)
        P = len(self.probe_names)
        return AnomalyState(mode=mode, probe_until=np.full(P, -1, dtype=np.int64),
                            probe_kind=np.zeros(P, dtype=np.int8),
                            probe_held=np.full(P, np.nan), probe_last=np.full(P, np.nan))

    # ----------------------------------------------------------------- mode hops

    def mode_hops(self, state: AnomalyState, t_s: np.ndarray, nodes_c: np.ndarray
                  ) -> tuple[np.ndarray, Events, AnomalyState]:
        """The bias offset (m, G) [rad/s] of every gyro on the thermal steps ending at
        ``t_s`` (m,) from the node temperatures ``nodes_c`` (m, n), the hop events and the
        new state (eq. (A1)). Zeros when mode hops are off."""
        m = len(t_s)
        G = len(self.gyro_axes)
        ev = Events()
        if not self.hops or m == 0:
            return np.zeros((m, G)), ev, state
        mode = state.mode.copy()
        k_all = np.empty((m, G), dtype=np.int64)
        steps = np.array([mh.bias_step_deg_per_h for mh in self.hops])
        for gi, idx in enumerate(self.hop_nodes):
            mh = self.hops[gi]
            half = 0.5 * mh.range_modes
            step = mh.bias_step_deg_per_h
            x = mh.modes_per_k * (nodes_c[:, idx].mean(axis=1) - mh.reference_c)
            k = int(mode[gi])
            j = 0
            while j < m:
                p = x[j:] - k
                out = np.flatnonzero((p > half) | (p < -half))
                if out.size == 0:
                    k_all[j:, gi] = k
                    break
                jj = j + int(out[0])
                k_all[j:jj, gi] = k
                new = (math.ceil(x[jj] - half) if x[jj] - k > half
                       else math.floor(x[jj] + half))
                ev.add(t_s[jj], t_s[jj], self.gyro_axes[gi],
                       "mode_hop_up" if new > k else "mode_hop_down", (new - k) * step,
                       "deg/h")
                k = new
                j = jj
            mode[gi] = k
        offset = k_all.astype(float) * deg_per_h_to_rad_per_s(steps)[None, :]
        return offset, ev, AnomalyState(mode=mode, imu_lost_left=state.imu_lost_left,
                                        probe_until=state.probe_until,
                                        probe_kind=state.probe_kind,
                                        probe_held=state.probe_held,
                                        probe_last=state.probe_last)

    def mode_offset(self, state: AnomalyState) -> np.ndarray:
        """The current bias offset of every gyro [rad/s] (from the carried mode)."""
        if not self.hops:
            return np.zeros(len(self.gyro_axes))
        return state.mode.astype(float) * deg_per_h_to_rad_per_s(
            np.array([mh.bias_step_deg_per_h for mh in self.hops]))

    # ----------------------------------------------------------------- pulses

    def pulses(self, state: AnomalyState, b: int, k0_sample: int, rate_hz: float,
               pulses: np.ndarray) -> tuple[np.ndarray, np.ndarray, Events, AnomalyState]:
        """Apply read-out spikes and frame dropouts to the gyro pulses (n, G) int32 of block
        ``b`` whose first sample has the run index ``k0_sample``. Returns the logged pulses
        (a copy; lost samples hold 0), the validity flags (n,) bool, the events and the new
        state. Only the recorded samples change."""
        md = self.model
        n, G = pulses.shape
        out = np.array(pulses, dtype=np.int32, copy=True)
        valid = np.ones(n, dtype=bool)
        ev = Events()
        dt = 1.0 / float(rate_hz)
        block_h = n * dt / 3600.0
        lost_left = int(state.imu_lost_left)

        def t_end(i: int) -> float:             # time coordinate of sample i of the block
            return (k0_sample + i + 1) * dt

        # frame dropouts: a running one first, then new ones (all channels at once)
        runs: list[tuple[int, int, bool]] = []      # (start, stop, continued)
        if lost_left > 0 and n > 0:
            stop = min(n, lost_left)
            runs.append((0, stop, True))
            lost_left -= stop
        if md.imu_dropout_rate_per_h > 0 and n:
            rng = generator(self.seed, self.unit, "anomalies", "imu_dropouts", b)
            count = int(rng.poisson(md.imu_dropout_rate_per_h * block_h))
            starts = np.sort(rng.integers(0, n, size=count))
            p = 1.0 / md.imu_dropout_mean_samples
            lengths = rng.geometric(p, size=count)      # ≥ 1 sample, mean mean_samples
            busy_until = runs[0][1] if runs else 0
            for s0, ln in zip(starts.tolist(), lengths.tolist()):
                if s0 < busy_until:
                    continue
                stop = min(n, s0 + ln)
                runs.append((s0, stop, False))
                lost_left = s0 + ln - stop
                busy_until = stop
        for s0, s1, _ in runs:
            valid[s0:s1] = False
            lost = out[s0:s1].astype(np.int64).sum(axis=0)
            for gi, ax in enumerate(self.gyro_axes):
                ev.add(t_end(s0), t_end(s1 - 1), ax, "imu_dropout", float(lost[gi]), "pulses")
            out[s0:s1] = 0
        # read-out spikes
        if md.pulse_spike_rate_per_h > 0 and n:
            rng = generator(self.seed, self.unit, "anomalies", "pulse_spikes", b)
            counts = rng.poisson(md.pulse_spike_rate_per_h * block_h, size=G)
            for gi in range(G):
                c = int(counts[gi])
                where = rng.integers(0, n, size=c)
                size = rng.integers(1, md.pulse_spike_max_pulses + 1, size=c)
                sign = np.where(rng.random(c) < 0.5, -1, 1)
                for i, s in zip(where.tolist(), (size * sign).tolist()):
                    if not valid[i]:
                        continue
                    out[i, gi] += s
                    ev.add(t_end(i), t_end(i), self.gyro_axes[gi], "pulse_spike", float(s),
                           "pulses")
        new = AnomalyState(mode=state.mode, imu_lost_left=lost_left,
                           probe_until=state.probe_until, probe_kind=state.probe_kind,
                           probe_held=state.probe_held, probe_last=state.probe_last)
        return out, valid, ev, new

    def lost_frames(self, valid: np.ndarray, k0_sample: int, rate_hz: float,
                    pulses: np.ndarray, channels: Sequence[str]) -> tuple[np.ndarray, Events]:
        """The same lost frames (``valid`` from :meth:`pulses`) for another instrument's
        pulses (n, C), e.g. the accelerometers: their counts are lost too (zeroed here, one
        ``imu_dropout`` event per run and channel with the lost counts)."""
        out = np.array(pulses, dtype=np.int32, copy=True)
        ev = Events()
        if valid.all():
            return out, ev
        dt = 1.0 / float(rate_hz)
        bad = np.flatnonzero(~valid)
        breaks = np.flatnonzero(np.diff(bad) > 1)
        starts = np.concatenate(([bad[0]], bad[breaks + 1]))
        stops = np.concatenate((bad[breaks] + 1, [bad[-1] + 1]))
        for s0, s1 in zip(starts.tolist(), stops.tolist()):
            lost = out[s0:s1].astype(np.int64).sum(axis=0)
            for c, ch in enumerate(channels):
                ev.add((k0_sample + s0 + 1) * dt, (k0_sample + s1) * dt, ch, "imu_dropout",
                       float(lost[c]), "pulses")
            out[s0:s1] = 0
        return out, ev

    # ----------------------------------------------------------------- probes

    def probes(self, state: AnomalyState, b: int, k0_step: int, step_s: float,
               readings: np.ndarray) -> tuple[np.ndarray, Events, AnomalyState]:
        """Apply glitches, stuck readings and dropouts to the probe readings (m, P) of block
        ``b`` (first thermal step of the block: run index ``k0_step``). Returns the logged
        readings (a copy; dropouts are NaN), the events and the new state."""
        md = self.model
        m, P = readings.shape
        out = np.array(readings, dtype=float, copy=True)
        ev = Events()
        until = state.probe_until.copy()
        kind = state.probe_kind.copy()
        held = state.probe_held.copy()
        last = state.probe_last.copy()
        block_h = m * step_s / 3600.0

        def t_end(k: int) -> float:              # k: run index of the thermal step
            return (k + 1) * step_s

        draws: dict[str, tuple] = {}
        for name, rate in (("probe_glitches", md.probe_glitch_rate_per_h),
                           ("probe_stuck", md.probe_stuck_rate_per_h),
                           ("probe_dropouts", md.probe_dropout_rate_per_h)):
            if rate > 0 and m:
                rng = generator(self.seed, self.unit, "anomalies", name, b)
                counts = rng.poisson(rate * block_h, size=P)
                per = []
                for pi in range(P):
                    c = int(counts[pi])
                    where = rng.integers(0, m, size=c)
                    dur = (rng.exponential(1.0, size=c) if name != "probe_glitches"
                           else np.zeros(c))
                    per.append((where, dur))
                draws[name] = per
        mean_s = {"probe_stuck": md.probe_stuck_mean_s, "probe_dropouts": md.probe_dropout_mean_s}
        for pi, probe in enumerate(self.probe_names):
            # this probe's events in time order (kind order breaks ties)
            items = []
            for order, name in enumerate(("probe_dropouts", "probe_stuck", "probe_glitches")):
                if name in draws:
                    where, dur = draws[name][pi]
                    for w, d in zip(where.tolist(), dur.tolist()):
                        items.append((w, order, name, d))
            items.sort()
            j = 0                                   # next row not yet finalised
            cur_until, cur_kind = int(until[pi]), int(kind[pi])
            cur_held = float(held[pi])
            prev = float(last[pi])

            def run_interval(j0: int, j1: int) -> None:
                if cur_kind == 1:
                    out[j0:j1, pi] = cur_held
                elif cur_kind == 2:
                    out[j0:j1, pi] = np.nan

            # continue a running interval
            active_to = max(0, min(m, cur_until - k0_step))
            if cur_kind and active_to > 0:
                run_interval(0, active_to)
                j = active_to
            for w, _, name, d in items:
                kabs = k0_step + w
                if cur_kind and kabs < cur_until:
                    continue                       # the channel is already stuck / out
                if w < j:
                    continue
                if name == "probe_glitches":
                    true = out[w, pi]
                    out[w, pi] = md.probe_glitch_value_c
                    ev.add(t_end(kabs), t_end(kabs), probe, "probe_glitch",
                           md.probe_glitch_value_c - true, "degC")
                    continue
                steps = max(1, int(math.ceil(d * mean_s[name] / step_s)))
                cur_kind = 1 if name == "probe_stuck" else 2
                cur_until = kabs + steps
                if cur_kind == 1:
                    cur_held = float(out[w - 1, pi]) if w > 0 else prev
                    if not np.isfinite(cur_held):       # nothing good to repeat yet
                        cur_kind, cur_until = 0, -1
                        continue
                ev.add(t_end(kabs), t_end(cur_until - 1), probe,
                       "probe_stuck" if cur_kind == 1 else "probe_dropout",
                       steps * step_s, "s")
                stop = min(m, cur_until - k0_step)
                run_interval(w, stop)
                j = stop
            if cur_kind and cur_until <= k0_step + m:
                cur_kind, cur_until = 0, -1
            until[pi], kind[pi], held[pi] = cur_until, cur_kind, cur_held
            if m:
                last[pi] = out[-1, pi] if np.isfinite(out[-1, pi]) else last[pi]
        new = AnomalyState(mode=state.mode, imu_lost_left=state.imu_lost_left,
                           probe_until=until, probe_kind=kind, probe_held=held,
                           probe_last=last)
        return out, ev, new


# --------------------------------------------------------------------------- in a run


class AnomalyRun:
    """The anomalies of one simulated run, shared by the stages that apply them (probes, IMU)
    and :class:`rlgsim.sim.stages.anomalies.AnomalyStage`, which writes the event record. One per timeline (the simulator
    builds one timeline per run); the stages run in a fixed order within every block, so the
    shared state and the event order are deterministic. Built by :meth:`of`."""

    def __init__(self, scenario, model: AnomalyModel) -> None:
        device = scenario.device
        gyro = (getattr(device, "parts", {}) or {}).get("gyro")
        probes = device.thermal.probes
        if model.mode_hop is not None and gyro is None:
            from rlgsim.ground.errors import UserInputError
            raise UserInputError(f"{device.source}: anomalies.mode_hop: the device has no "
                                 f"[gyro] table whose mode could hop")
        self.model = model
        self.bound = Anomalies(model, node_names=device.thermal.network.node_names,
                               gyro_axes=tuple(gyro.axes) if gyro is not None else (),
                               gyro_blocks=tuple(gyro.blocks) if gyro is not None else (),
                               probe_names=tuple(probes.names) if probes is not None else (),
                               seed=scenario.seed, unit=scenario.unit, source=device.source)
        if model.mode_hop is not None and int(scenario.unit) >= 1:   # a drawn Monte Carlo unit
            self.bound.realise_unit(generator(scenario.realisation_seed, scenario.unit,
                                              "realisation", "anomalies", 0))
        self.state: AnomalyState | None = None
        self.pending = Events()

    @classmethod
    def of(cls, scenario, timeline) -> "AnomalyRun | None":
        """The run's anomalies (None when the device preset has no active ``[anomalies]``)."""
        model = (getattr(scenario.device, "parts", {}) or {}).get("anomalies")
        if model is None or not model.active:
            return None
        run = getattr(timeline, "_rlgsim_anomalies", None)
        if run is None:
            run = cls(scenario, model)
            timeline._rlgsim_anomalies = run
        return run

    def _state(self, start_c: np.ndarray) -> AnomalyState:
        if self.state is None:
            self.state = self.bound.initial_state(np.asarray(start_c, dtype=float))
        return self.state

    # ---- applied by the stages -------------------------------------------------------------
    def probe_readings(self, b: int, trace, readings: np.ndarray) -> np.ndarray:
        """The logged probe readings of block ``b`` (``trace`` the block's ThermalTrace)."""
        st = self._state(trace.start_c)
        k0 = int(round(float(trace.t_s[0]) / trace.step_s)) - 1
        out, ev, self.state = self.bound.probes(st, b, k0, trace.step_s, readings)
        self.pending.extend(ev)
        return out

    def gyro_bias_offset(self, trace) -> np.ndarray:
        """Mode-hop bias offsets (m, G) [rad/s] of the block (zeros without mode hops)."""
        st = self._state(trace.start_c)
        off, ev, self.state = self.bound.mode_hops(st, np.asarray(trace.t_s),
                                                   np.asarray(trace.nodes_c))
        self.pending.extend(ev)
        return off

    def gyro_pulses(self, b: int, k0_sample: int, rate_hz: float, pulses: np.ndarray,
                    start_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The logged gyro pulses and the frame validity flags of block ``b``."""
        st = self._state(start_c)
        out, valid, ev, self.state = self.bound.pulses(st, b, k0_sample, rate_hz, pulses)
        self.pending.extend(ev)
        return out, valid

    def other_pulses(self, valid: np.ndarray, k0_sample: int, rate_hz: float,
                     pulses: np.ndarray, channels: Sequence[str]) -> np.ndarray:
        """Another instrument's pulses with the lost frames removed (accelerometers)."""
        out, ev = self.bound.lost_frames(valid, k0_sample, rate_hz, pulses, channels)
        self.pending.extend(ev)
        return out

    def take_events(self) -> Events:
        ev, self.pending = self.pending, Events()
        return ev
