"""Sensor anomalies applied to a run, every event labelled in the truth (issue 12; docs/sensors.md
"Anomalies"; the ``[anomalies]`` table and the equations: :mod:`rlgsim.sim.sensors.anomaly_model`).

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

Why this file is over 400 lines: it is one engine, the anomalies of a run drawn and applied
block by block (mode hops with their hysteresis, pulse spikes, lost frames, probe glitches,
stuck and missing readings), every kind sharing the carried state and the event record; the
table and the rows are apart (anomaly_model.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from rlgsim.ground.units import deg_per_h_to_rad_per_s
from rlgsim.sim.rng import generator
from rlgsim.sim.sensors.anomaly_model import AnomalyModel, Events, ModeHop

__all__ = ["AnomalyState", "Anomalies", "AnomalyRun"]


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
