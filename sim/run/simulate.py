"""The streaming simulator: scenario → timeline → blocks of numerics → HDF5 dataset.

The run advances in blocks of fixed simulated length :data:`BLOCK_S` (600 s: a whole number of
thermal steps and of IMU samples, checked by the scenario loader). For block ``b``:

1. the *thermal* part samples the timeline (rate-limited chamber setpoint on the grid points,
   power state over each step) and propagates the thermal network exactly
   (:class:`rlgsim.sim.thermal.integrator.ThermalIntegrator`), giving a :class:`ThermalTrace`;
2. every *stage* (:data:`STAGES`: the probes now, the sensors later) turns the trace into its
   arrays: ``stage.block(state, b, trace, motion) -> (arrays, state)``.

Every carried state (thermal state, probe lags, later pulse remainders and noise-filter states)
goes from block to block, and every random draw of block ``b`` comes from
``rlgsim.sim.rng.generator(seed, unit, purpose, channel, b)``. Each block's rows go to a writer
thread (:class:`_Appender`) that appends them in block order while the next block is computed;
the user's ``chunk_s`` only bounds how many blocks may wait for it (memory stays bounded), so
the stored arrays — and the file — are the same whatever the chunk size.

Adding a stage (issue 3: the IMU) — write a class with

* ``group`` (dataset group name), ``description`` and ``needs_motion`` (True to receive the
  turntable kinematics, a :class:`rlgsim.sim.motion.kinematics.Motion` — ``motion.increments(t0_s, n, rate_hz)``
  gives the exact angle/velocity increments of ``n`` samples);
* ``declare(group_writer)`` — create coordinates/variables (see :mod:`rlgsim.sim.writer.dataset`); the growing
  dimension is usually ``time`` (``coordinate("time", growing=True, ...)``; a group may declare
  more than one growing dimension);
* ``initial_state()`` — the state before block 0 (or ``None`` and build it from the first
  block's ``trace.start_c``, as the probes do);
* ``block(state, b, trace, motion) -> (rows, state)`` — ``rows`` maps each growing dimension to
  ``{variable: array}`` holding every variable along it (the coordinate included), for this
  block only: block ``b`` covers ``[b·BLOCK_S, b·BLOCK_S + len(trace.t_s)·trace.step_s)``;
  random draws from ``generator(seed, scenario.unit, purpose, channel, b)``;

and a factory ``f(scenario, timeline) -> stage | None`` appended to :data:`STAGES`. The
shipped groups are declared in one room, :mod:`rlgsim.sim.writer.schema` (a new group goes
there, its names into :data:`rlgsim.ground.dataset_format.VARIABLES` — or
:data:`~rlgsim.ground.dataset_format.OPTIONAL_VARIABLES` for a part a scenario switches on —
and its prose into docs/dataset.md). :class:`ProbeStage` is the worked example. A stage that
writes several groups (the IMU: ``imu``, ``turntable``, ``truth``) sets
``groups = {name: description}``
instead of ``group``/``description``; its ``declare`` then receives ``{name: group_writer}`` and
its ``block`` returns ``{name: rows}``.
"""

from __future__ import annotations

import contextlib
import gc
import math
import pathlib
import threading
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np

from rlgsim.ground.dataset_format import PROBES, THERMAL
from rlgsim.sim.run._heap import keep_freed_memory
from rlgsim.sim.writer.dataset import DatasetWriter, GroupWriter, check_writable
from rlgsim.sim.writer.schema import (DESCRIPTIONS, declare_probes, declare_thermal,
                                       declare_thermal_parts, write_timeline)
from rlgsim.sim.rng import BLOCK_S, generator
from rlgsim.sim.run.schedule import Timeline, build_timeline
from rlgsim.sim.thermal.integrator import ThermalIntegrator, one_blas_thread

__all__ = ["BLOCK_S", "STAGES", "ThermalTrace", "Stage", "ThermalPart", "realised_network",
           "thermal_summary", "ProbeStage", "default_output", "simulate"]



@dataclass(frozen=True)
class ThermalTrace:
    """The thermal state over one block, on the thermal grid.

    Row ``j`` belongs to the step ``[t_s[j] - step_s, t_s[j])``: temperatures are the values at
    its end, ``power`` the state held over it.
    """

    t_s: np.ndarray          # (m,) end of each step [s]
    step_s: float
    setpoint_c: np.ndarray   # (m,) rate-limited chamber setpoint [°C]
    air_c: np.ndarray        # (m,) chamber air [°C]
    power: np.ndarray        # (m,) 0/1
    nodes_c: np.ndarray      # (m, n) true node temperatures [°C]
    start_c: np.ndarray      # (n,) node temperatures at the block start (row -1)


class Stage:
    """Interface of a simulation stage (see the module docstring)."""

    group: str
    description: str
    needs_motion: bool = False     # True: block() receives a rlgsim.sim.motion.kinematics.Motion (else None)

    def declare(self, g: GroupWriter) -> None:
        raise NotImplementedError

    def initial_state(self) -> Any:
        raise NotImplementedError

    def block(self, state: Any, b: int, trace: ThermalTrace, motion: Any
              ) -> tuple[dict[str, dict[str, np.ndarray]], Any]:
        raise NotImplementedError


# --------------------------------------------------------------------------- thermal part


class ThermalPart:
    """Samples the timeline and propagates the thermal network block by block."""

    group = THERMAL
    description = DESCRIPTIONS[THERMAL]

    def __init__(self, scenario, timeline: Timeline) -> None:
        self.timeline = timeline
        self.step = timeline.step_s
        self.nominal = scenario.device.thermal.network
        self.network = realised_network(scenario)
        self.integrator = ThermalIntegrator(self.network, self.step, scenario.chamber.air_tau_s,
                                            controller=scenario.chamber.controller)
        #: a vehicle's bay (sim/thermal/vehicle_bay.py) and its route: the airflow scales the
        #: ambient conductances with the ground speed (None: still air, as in a chamber)
        self.bay = None
        if getattr(scenario, "vehicle_bay", None) is not None:
            self.bay = (scenario.vehicle_bay,
                        scenario.trajectory.build(float(timeline.duration_s)))

    @property
    def node_names(self) -> tuple[str, ...]:
        return tuple(self.network.node_names)

    def declare(self, g: GroupWriter) -> None:
        declare_thermal(g, self.nominal, self.network)
        declare_thermal_parts(g, self.network)   # heaters, boundaries: only when it has them

    def initial_state(self) -> Any:
        ambient = float(self.timeline.setpoint(np.array([0.0]))[0])
        powered = bool(self.timeline.power(np.array([0.0]))[0])
        return self.integrator.initial_state(ambient, powered)      # keeps its modal state

    def block(self, state: Any, b: int, k0: int, m: int) -> tuple[ThermalTrace, Any]:
        k = np.arange(k0, k0 + m + 1, dtype=np.int64)
        t = k * self.step
        setpoint = np.asarray(self.timeline.setpoint(t), dtype=float)
        power = np.asarray(self.timeline.power(t[:-1]), dtype=float)
        film = None
        if self.bay is not None:             # φ − 1 at each step's start (held over the step)
            bay, route = self.bay
            film = bay.factor(np.linalg.norm(route.states(t[:-1]).v_n, axis=1)) - 1.0
        states, new_state = self.integrator.propagate(state, setpoint, power, film_factor=film)
        self._extra_rows = self.integrator.extra_rows()
        trace = ThermalTrace(t_s=t[1:], step_s=self.step, setpoint_c=setpoint[1:],
                             air_c=np.asarray(states[:, 0]), power=power,
                             nodes_c=np.asarray(states[:, 1:]), start_c=np.asarray(state[1:]))
        return trace, new_state

    def rows(self, trace: ThermalTrace) -> dict[str, dict[str, np.ndarray]]:
        return {"time": {"time": trace.t_s, "chamber_setpoint": trace.setpoint_c,
                         "chamber_air": trace.air_c, "power_on": trace.power.astype(np.int8),
                         "node_temperature": trace.nodes_c,
                         **getattr(self, "_extra_rows", {})}}


def realised_network(scenario):
    """The thermal network of the simulated unit.

    Monte Carlo units ``unit >= 1`` draw their network from the preset's tolerances with
    ``generator(realisation_seed, unit, "realisation", "thermal", 0)``
    (:meth:`rlgsim.sim.thermal.network.ThermalNetwork.realise`). Unit 0 — every plain ``rlgsim run`` and a
    study's own run — simulates the *nominal* design: the presets' bias-stability figures were
    tuned against papers 000-003 on it (tests/test_imu.py), and a drawn network breaks the
    left/right symmetry of the gyro block, which switches on the anode-arm Langmuir term (on
    paper 003's random test the raw stability of drawn units spreads from 0.009 to 0.068 °/h
    against the paper's 0.028). docs/montecarlo.md discusses the choice."""
    network = scenario.device.thermal.network
    if scenario.unit == 0:
        return network
    return network.realise(generator(scenario.realisation_seed, scenario.unit, "realisation",
                                     "thermal", 0))


def thermal_summary(network) -> dict[str, float]:
    """A few numbers that characterise a (realised) network, for Monte Carlo unit tables:
    longest time constant [s], total heat [W], total conductance to the air [W/K] and the mean
    steady-state self-heating of the nodes when powered [K]."""
    rise = network.steady_state(0.0, True) - network.steady_state(0.0, False)
    return {"thermal.tau_max_s": float(network.time_constants_s()[0]),
            "thermal.power_w": float(network.power_w.sum()),
            "thermal.ambient_conductance_w_per_k":
                float(network.ambient_conductance_w_per_k.sum()),
            "thermal.self_heating_mean_k": float(np.mean(rise))}


# --------------------------------------------------------------------------- stages


class ProbeStage(Stage):
    """Thermometer probes on the network nodes (lag, noise, resolution): what the compensators
    see. Random draws: ``generator(seed, unit, "probes", "noise", b)``."""

    group = PROBES
    description = DESCRIPTIONS[PROBES]

    def __init__(self, scenario, timeline: Timeline) -> None:
        self.probes = scenario.device.thermal.probes
        self.network = scenario.device.thermal.network
        self.seed = scenario.seed
        self.unit = scenario.unit
        self.step = timeline.step_s
        from rlgsim.sim.sensors.anomalies import AnomalyRun
        self.anomalies = AnomalyRun.of(scenario, timeline)     # None unless [anomalies]

    @classmethod
    def create(cls, scenario, timeline: Timeline) -> "ProbeStage | None":
        if not scenario.device.thermal.probes.n_probes:
            return None
        return cls(scenario, timeline)

    def declare(self, g: GroupWriter) -> None:
        declare_probes(g, self.probes, self.network)

    def initial_state(self) -> Any:
        return None          # built from the first block's start temperatures

    def block(self, state, b, trace, motion):
        if state is None:
            state = self.probes.initial_state(trace.start_c)
        rng = generator(self.seed, self.unit, "probes", "noise", b)
        readings, state = self.probes.read(state, trace.nodes_c, trace.step_s, rng)
        if self.anomalies is not None:                         # glitches, stuck, dropouts
            readings = self.anomalies.probe_readings(b, trace, readings)
        return {"time": {"time": trace.t_s, "temperature": readings}}, state


#: Stage factories run by :func:`simulate`, in order: ``f(scenario, timeline) -> Stage | None``.
def _imu_stage(scenario, timeline: Timeline) -> Stage | None:
    """The sensor stage (:class:`rlgsim.sim.sensors.imu.ImuStage`: groups imu, turntable, truth)."""
    from rlgsim.sim.sensors.imu import ImuStage
    return ImuStage.create(scenario, timeline)


def _anomaly_stage(scenario, timeline: Timeline) -> Stage | None:
    """The event record of the sensor anomalies (:class:`rlgsim.sim.sensors.anomalies.AnomalyStage`;
    None unless the device preset has an active ``[anomalies]`` table). Last: it writes the
    events the stages before it produced in the block."""
    from rlgsim.sim.sensors.anomalies import AnomalyStage
    return AnomalyStage.create(scenario, timeline)


STAGES: list[Callable[[Any, Timeline], Stage | None]] = [ProbeStage.create, _imu_stage,
                                                         _anomaly_stage]


# --------------------------------------------------------------------------- the run


class _Appender:
    """Appends each block's rows to the dataset in a writer thread, in block order.

    HDF5 releases the GIL while it filters and writes (h5py's H5D calls), so the writes of
    block ``b`` overlap the arithmetic of block ``b + 1`` on another core. The thread makes
    exactly the calls the main thread would make, in the same order — one
    :meth:`GroupWriter.append` per block, group and dimension, in the order the stages
    produced them — so the file does not depend on the thread, nor on ``chunk_s``, which only
    bounds how many blocks may wait (``max_blocks``: memory stays flat in the duration). An
    error in the thread is raised in the main thread at the next :meth:`put` or at
    :meth:`close`."""

    def __init__(self, writers: dict[str, GroupWriter], max_blocks: int) -> None:
        import queue

        self._writers = writers
        self._queue: "queue.Queue" = queue.Queue(maxsize=max(1, int(max_blocks)))
        self._error: BaseException | None = None
        self._cancelled = False
        self._thread = threading.Thread(target=self._run, name="rlgsim-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            rows = self._queue.get()
            if rows is None:
                return
            if self._error is not None or self._cancelled:
                continue                        # drain: the main thread may be waiting
            try:
                for group, grows in rows:
                    for dim, arrays in grows.items():
                        self._writers[group].append(dim, arrays)
            except BaseException as exc:        # raised again in the main thread
                self._error = exc

    def _raise(self) -> None:
        if self._error is not None:
            exc, self._error = self._error, None
            raise exc

    def put(self, rows: list[tuple[str, dict[str, dict[str, np.ndarray]]]]) -> None:
        """Queue one block's rows ``[(group, {dim: {variable: array}})]`` (waits while
        ``max_blocks`` are queued). The arrays must not change afterwards."""
        self._raise()
        self._queue.put(rows)

    def close(self) -> None:
        """Wait until everything queued is written; raise the thread's error if any."""
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        self._raise()

    def cancel(self) -> None:
        """Stop the thread, dropping what is still queued (the run failed or was stopped)."""
        if self._thread.is_alive():
            self._cancelled = True
            self._queue.put(None)
            self._thread.join()


@contextlib.contextmanager
def _no_cyclic_gc() -> Iterator[None]:
    """Python's cyclic garbage collector off for a ``with`` block run from the main thread (back
    on after, if it was); a no-op in other threads (a thread pool's worker, whose process may
    have other cyclic garbage to collect meanwhile).

    A run's blocks allocate arrays, tuples and dicts that reference counting frees; the
    collector found nothing to free in a run but scanned the young objects every ~700
    allocations — ~5 % of the run's CPU (perf, paper000 at 100 Hz)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def default_output(scenario) -> pathlib.Path:
    return pathlib.Path(f"{scenario.name}.h5")


def simulate(scenario, out_path: str | pathlib.Path | None, *, chunk_s: float | None = None,
             progress: bool = True, should_stop: Callable[[], bool] | None = None
             ) -> pathlib.Path:
    """Simulate ``scenario`` and stream it to ``out_path`` (default ``./<name>.h5``).

    ``chunk_s`` (default: the scenario's ``acquisition.chunk_s``) is how much simulated time may
    wait for the writer thread (a memory bound); it never changes the stored arrays. ``should_stop`` is asked
    before every block; when it returns true the run stops with KeyboardInterrupt and its
    temporary file is deleted (the CLI's SIGTERM handler uses it). Returns the written path.
    """
    out = check_writable(out_path if out_path is not None else default_output(scenario))
    chunk = float(chunk_s if chunk_s is not None else scenario.acquisition.chunk_s)
    if not chunk > 0:
        raise ValueError("chunk_s must be > 0")
    from rlgsim.sim.run.run_budget import check_budget, check_motions
    check_motions(scenario)                 # before the timeline holds them all
    timeline = build_timeline(scenario)
    step = timeline.step_s
    n_steps = timeline.n_steps
    per_block = int(round(BLOCK_S / step))
    n_blocks = math.ceil(n_steps / per_block)
    blocks_per_write = max(1, int(round(chunk / BLOCK_S)))

    thermal = ThermalPart(scenario, timeline)
    stages = [s for s in (f(scenario, timeline) for f in STAGES) if s is not None]
    motion = None
    if any(getattr(s, "needs_motion", False) for s in stages):
        if getattr(scenario, "trajectory", None) is not None:     # a vehicle's route
            motion = scenario.trajectory.build(float(timeline.duration_s))
        else:
            from rlgsim.sim.motion.kinematics import Motion
            motion = Motion(timeline.segments, scenario.site)  # exact turntable kinematics

    attrs = {
        "title": f"rlgsim run of scenario {scenario.name}",
        "scenario_name": scenario.name,
        "scenario_description": scenario.description,
        "scenario_source": scenario.source,
        "scenario_text": scenario.text,
        "device": scenario.device.name,
        "device_text": scenario.device.text,
        "thermal_preset_text": scenario.device.thermal.text,
        "seed": np.int64(scenario.seed),
        "unit": np.int64(scenario.unit),
        "device_seed": np.int64(scenario.realisation_seed),
        "duration_s": float(timeline.duration_s),
        "thermal_step_s": float(step),
        "sample_rate_hz": float(scenario.acquisition.sample_rate_hz),
        "block_s": BLOCK_S,
        "latitude_deg": scenario.site.latitude_deg,
        "height_m": scenario.site.height_m,
    }
    from tqdm import tqdm
    with DatasetWriter(out, attrs) as w:
        write_timeline(w, timeline)
        writers = {}
        writers[thermal.group] = w.group(thermal.group, thermal.description)
        thermal.declare(writers[thermal.group])
        for s in stages:
            if hasattr(s, "groups"):                 # a stage writing several groups
                for gname, gdesc in s.groups.items():
                    writers[gname] = w.group(gname, gdesc)
                s.declare({gname: writers[gname] for gname in s.groups})
            else:
                writers[s.group] = w.group(s.group, s.description)
                s.declare(writers[s.group])
        check_budget(w._file, scenario, out, n_steps=n_steps, steps_per_block=per_block,
                     buffered_blocks=blocks_per_write + 1, block_s=BLOCK_S,
                     progress=progress)    # refuse what cannot fit (run_budget)
        t_state = thermal.initial_state()
        s_states = [s.initial_state() for s in stages]
        bar = tqdm(total=round(n_steps * step), unit="s", unit_scale=True, disable=not progress,
                   delay=1.0, desc=f"rlgsim {scenario.name}", leave=False, dynamic_ncols=True)
        # The per-block matrices are small (tens of nodes × hundreds of steps): a threaded BLAS
        # only adds synchronisation (5× slower on a busy 2-core machine), so use one thread.
        # Each block's buffers reuse the previous block's pages (no page faults; sim/run/_heap.py).
        keep_freed_memory()
        appender = _Appender(writers, blocks_per_write)
        try:
            with one_blas_thread(), _no_cyclic_gc():
                for b in range(n_blocks):
                    if should_stop is not None and should_stop():
                        raise KeyboardInterrupt("stop requested")
                    k0 = b * per_block
                    m = min(per_block, n_steps - k0)
                    trace, t_state = thermal.block(t_state, b, k0, m)
                    rows = [(thermal.group, thermal.rows(trace))]
                    for i, s in enumerate(stages):
                        srows, s_states[i] = s.block(s_states[i], b, trace, motion)
                        if hasattr(s, "groups"):
                            rows.extend(srows.items())
                        else:
                            rows.append((s.group, srows))
                    appender.put(rows)          # written in the writer thread, in block order
                    bar.update(round(m * step))
            appender.close()
        finally:
            appender.cancel()                   # an error or a stop: discard what is queued
            bar.close()
            for s in stages:                    # stop a stage's worker threads (their queued
                if hasattr(s, "close"):         # draws are dropped)
                    s.close()
    return out
