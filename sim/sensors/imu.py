"""The IMU stage's engine: one drawn unit (:class:`rlgsim.sim.sensors.imu_model.ImuRealisation`)
turned, block by block, into pulses, UHFO and ground truth from thermal state and motion.

:class:`ImuSimulator` runs block by block inside :func:`rlgsim.sim.run.simulate.simulate` (through
the stage :class:`rlgsim.sim.stages.imu.ImuStage`, which declares its groups):

1. UHFO on the thermal grid (:mod:`rlgsim.sim.sensors.uhfo`): the true excitation and its reading;
2. gyro and accelerometer parameters on the thermal grid (:mod:`rlgsim.sim.sensors.gyro`,
   :mod:`rlgsim.sim.sensors.accelerometer`; laws of :mod:`rlgsim.sim.sensors.temperature_laws`) plus the slow noise (flicker, random
   walk; :class:`rlgsim.sim.sensors.noise.SlowNoise`), which is part of the true bias;
3. exact angle / velocity increments of the turntable motion (:mod:`rlgsim.sim.motion.kinematics`), white noise
   (float32 standard normals × σ, as :func:`rlgsim.sim.sensors.noise.white_increments`) and the phase
   increments of eqs. 17/20;
4. pulse counting with carried remainders (:mod:`rlgsim.sim.sensors.pulses`), with the measurement
   equation in one compiled call per sensor triad (:func:`rlgsim.sim.sensors._pulse_kernel.count_block`;
   the NumPy path for short runs in a process without numba — the same pulses bit for bit).

The white-noise normals — about half the run's CPU, drawn by numpy with the GIL released —
are drawn two blocks ahead in one worker thread, from the first block on, while the
main thread computes each block's kinematics (increments, their sums per thermal step, the
table angles, the thermal steps at rest: every sample the same increment, bit for bit, whose
measurement equation :func:`rlgsim.sim.sensors.sensor_triad.count_pulses` evaluates once per step),
slow noise and UHFO drives itself (:meth:`ImuSimulator._get_inputs`). Interpreter-bound work
in a worker thread only waited for the GIL: with the kinematics and drives in a second worker
the run took ~10 % longer (paper000 at 100 Hz, bench_sim pairs). The standard normals of
the slow noise and UHFO (no state: a few generators and ~40 000 float64 normals a block at a
1 s step) are drawn by the same worker with the white noise, which cut the main thread's CPU by
~6 % (paper000 12 h: 0.278 -> 0.261 s; a 1 h static run 62 -> 59 ms). The samples at rest are
known from the motion (:attr:`rlgsim.sim.motion.kinematics.MotionBlock.constant`), so their per-step
sums are taken once per run of them.

Random streams (seed = scenario seed, unit = Monte Carlo unit, b = block index; see
docs/dataset.md "truth"): ``realisation``/``imu`` (block 0) for the unit; gyro white noise
``gyro.white``/<axis>, accelerometer ``accel.white``/<axis>; slow noise ``gyro.flicker``,
``gyro.rrw``, ``accel.flicker``, ``accel.rrw`` per axis; UHFO ``uhfo.wander``,
``uhfo.readout``. Nothing depends on how blocks are grouped into writes.

What truth is stored at the sample rate: the pulses are reproducible from the truth group's
per-step parameters, the exact increments and the documented white-noise draws. The increments
are a deterministic function of the turntable programme (stored in the ``timeline`` group) and
the site, so by default the truth group stores them summed per thermal step (float64) and
:func:`rlgsim.sim.motion.recorded.true_increments` recomputes the per-sample values bit for bit; ``truth_samples=True``
stores them per sample as well (48 bytes per epoch — at 100 Hz over paper 000's 121 h
programme that is 2 GB, several times the rest of the file, which is why it is not the
default; see benchmarks/bench_sim.py).

Why this file is over 400 lines: it is one engine, a drawn unit simulated block by block
(inputs drawn ahead in a worker thread, kinematics, slow noise, UHFO, the two counting calls),
whose parts share the carried state and the prefetch queue; the model and realisation are apart
(imu_model.py), the stage too (sim/stages/imu.py).
"""

from __future__ import annotations

import math
import sys
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from rlgsim.sim.block_steps import step_counts
from rlgsim.sim.rng import BLOCK_S, generator
from rlgsim.sim.sensors.gyro import sample_step_index
from rlgsim.sim.sensors.imu_model import ImuRealisation
from rlgsim.sim.sensors.noise import SlowNoise
from rlgsim.sim.sensors.sensor_triad import count_pulses, step_inputs

#: A run of at least this many IMU epochs counts its pulses with the compiled kernel even when
#: numba is not loaded yet: importing numba and loading the cached kernel cost ~0.4-0.7 s once
#: per process on the shared 2-core development machine, which the kernel repays at ~20-150 ns
#: of CPU per epoch (six channels: a table at rest / turning; tests/test_pulse_kernel.py's
#: block timed both ways) — from a few million epochs on (benchmarks/bench_sim.py --counters).
#: Measured with the earlier kernel of one call per channel; ``count_block`` (one call per
#: triad) is ~2.5× cheaper, so the threshold is on the safe side and was left as it was.
COMPILED_MIN_EPOCHS = 5_000_000

#: How many blocks ahead of the running one the worker thread draws the normals (paper000 at
#: 100 Hz, alternating runs at load ~1.5: two, three and four blocks ahead all 2.88-2.93 s
#: median wall; each block's normals hold 1.4 MB).
PREFETCH_BLOCKS = 2

#: How many blocks ahead a vehicle's kinematics are computed (increments, their step sums and
#: the truth rows: ~9 MB a block at 100 Hz), in their own two worker threads — a block's
#: increments in one, its truth rows in the other (the compiled kernels release the GIL) — from
#: before the file is laid out (:meth:`ImuSimulator.start`): they need nothing of the file or of
#: the thermal state. Two, not more: each block held ahead is memory (tests/test_trajectory_memory.py).
MOTION_AHEAD = 2


@dataclass
class ImuState:
    """Carried from block to block: pulse remainders (int64 fixed point, :mod:`rlgsim.sim.sensors.pulses`),
    slow-noise states and the UHFO wander."""

    gyro_remainder: np.ndarray
    accel_remainder: np.ndarray
    slow: Any
    uhfo_wander: np.ndarray


class ImuSimulator:
    """Pulses, UHFO, turntable angles and truth of one unit, block by block.

    ``realisation`` (bound or not), ``node_names`` of the thermal network, ``seed``/``unit`` of
    the seed tree, ``rate_hz`` the IMU sample rate, ``step_s`` the thermal step, ``motion`` a
    :class:`rlgsim.sim.motion.kinematics.Motion`, ``truth_samples`` store per-sample true increments too,
    ``prefetch`` draw the next blocks' white-noise normals in a worker thread, ``n_steps`` the
    run's length in thermal steps (the thread stops after the last block; :meth:`close` stops
    it earlier), ``compiled`` use the compiled kernels (None: when numba is loaded or the run
    is long; see ``self.compiled``).
    """

    def __init__(self, realisation: ImuRealisation, node_names: Sequence[str], *, seed: int,
                 unit: int, rate_hz: float, step_s: float, motion=None,
                 truth_samples: bool = False, source: str = "", prefetch: bool = True,
                 n_steps: int | None = None, compiled: bool | None = None) -> None:
        self.r = realisation
        self.node_names = tuple(node_names)
        self.r.bind(self.node_names, source)
        self.seed, self.unit = int(seed), int(unit)
        self.rate_hz = float(rate_hz)
        self.step_s = float(step_s)
        self.sample_dt = 1.0 / self.rate_hz
        self.motion = motion
        self.truth_samples = bool(truth_samples)
        #: draw the next blocks' normals in a worker thread (numpy releases the GIL while it
        #: fills an array), overlapping them with this block's arithmetic on a second core
        self.prefetch = bool(prefetch)
        self.n_steps = n_steps                  # thermal steps of the run (None: open-ended)
        #: count pulses and draw normals with the compiled kernels (rlgsim.sim.sensors._pulse_kernel,
        #: rlgsim.sim.sensors._normal_kernel; the NumPy path's numbers, bit for bit) — by default when
        #: numba is already loaded in this process or the run is long enough to repay loading
        #: it (:data:`COMPILED_MIN_EPOCHS`)
        epochs = (math.inf if n_steps is None
                  else float(n_steps) * self.step_s * self.rate_hz)
        self.compiled = (bool(compiled) if compiled is not None
                         else "numba" in sys.modules or epochs >= COMPILED_MIN_EPOCHS)
        self.anomalies = None                   # rlgsim.sim.sensors.anomalies.AnomalyRun (optional)
        #: the last block's motion (a rlgsim.sim.motion.kinematics.MotionBlock or a vehicle's)
        self.last_motion_block: Any = None
        self._pool = None
        #: queued blocks in order: ((b, k0, m, n), [futures of its gyro and accel normals])
        self._ahead: deque[tuple[tuple[int, int, int, int], list[Any]]] = deque()
        #: a vehicle's kinematics of the queued blocks, by (first step, steps, samples): the
        #: futures of :meth:`_kinematics_now` and :meth:`_truth_rows` (None: made with the
        #: kinematics), computed in their own two worker threads (the trajectory's compiled
        #: kernels release the GIL), :data:`MOTION_AHEAD` blocks ahead
        self._motion_ahead: dict[tuple[int, int, int], Any] = {}
        self._motion_pool = None
        self._motion_next = 0                   # first step of the next block to queue
        #: ``rows(t_s, states)`` of a vehicle's truth group, made with its kinematics (the
        #: stage's; ``states`` None: it computes them too; the attribute None: the states are
        #: kept for the caller instead)
        self.motion_rows: Any = None
        g, a, lv = self.r.gyros, self.r.accels, self.r.levels
        # one flicker bank for gyros and accelerometers (same τ grid): one lfilter per process
        acc_axes = a.axes if a is not None else ()
        self.n_gyro = g.n
        self.slow = SlowNoise(np.concatenate([lv["gyro_bi"], lv["accel_bi"]]),
                              np.concatenate([lv["gyro_rrw"], lv["accel_rrw"]]), self.step_s,
                              self.r.noise, g.axes + acc_axes, self.seed, self.unit,
                              ("gyro",) * g.n + ("accel",) * len(acc_axes))
        #: white-noise standard deviation per sample: gyro [rad], accel [m/s]
        self.gyro_white_sigma = lv["gyro_arw"] * math.sqrt(self.sample_dt)
        self.accel_white_sigma = (lv["accel_vrw"] * math.sqrt(self.sample_dt)
                                  if a is not None else np.zeros(0))

    # ---- state ----------------------------------------------------------------------------
    def initial_state(self) -> ImuState:
        g, a = self.r.gyros, self.r.accels
        return ImuState(
            gyro_remainder=np.zeros(g.n, dtype=np.int64),
            accel_remainder=np.zeros(a.n if a else 0, dtype=np.int64),
            slow=self.slow.initial_state(),
            uhfo_wander=(self.r.uhfo.initial_state(self.seed, self.unit)
                         if self.r.uhfo is not None else np.zeros(0)))

    # ---- white noise ----------------------------------------------------------------------
    def white(self, purpose: str, axes: Sequence[str], sigma: np.ndarray, b: int, n: int
              ) -> np.ndarray | None:
        """Standard normals (C, n) float32 of ``generator(seed, unit, purpose, axis, b)
        .standard_normal(n, dtype=float32)`` per axis (None when every σ is 0); the white
        increment of a sample is σ·z in float64. Drawn by the compiled kernel
        (:mod:`rlgsim.sim.sensors._normal_kernel`: the same numbers) on the compiled paths."""
        if not np.any(sigma > 0):
            return None
        z = np.empty((len(axes), n), dtype=np.float32)
        generators = [generator(self.seed, self.unit, purpose, ax, b) for ax in axes]
        fill = _compiled("fill") if self.compiled else None
        if fill is not None:                    # the same draws, compiled (_normal_kernel)
            fill(generators, z, advance=False)
        else:
            for g, row in zip(generators, z):
                g.standard_normal(n, dtype=np.float32, out=row)
        return z

    # ---- one block ------------------------------------------------------------------------
    def start(self, motion: Any) -> None:
        """Adopt the run's ``motion``; a vehicle's kinematics (:meth:`_kinematics_now`) of the
        first :data:`MOTION_AHEAD` blocks then start in two worker threads at once — while the
        caller lays out the file — and stay that many blocks ahead of :meth:`block` (the same
        numbers whichever thread computes them; :meth:`close` stops them); so do the first
        blocks' normals (:meth:`_queue_first`)."""
        self.motion = motion
        if self.prefetch and self.n_steps is not None and self._is_vehicle():
            self._queue_motion(0)
        if self.prefetch and self.n_steps and not self._ahead:
            self._queue_first()

    def _queue_first(self) -> None:
        """Queue the normals of the first :data:`PREFETCH_BLOCKS` blocks (the block layout of
        :func:`rlgsim.sim.run.simulate.simulate`), so the worker draws block 0's while the
        caller lays out the file (the compiled draw and numpy's release the GIL) — otherwise
        block 0 drew its own in this thread: ~2 ms of a 1 h run at 100 Hz. A block of
        another layout is drawn when asked for (:meth:`_take_normals`)."""
        per_block = int(round(BLOCK_S / self.step_s))
        self._queue_after(-1, -per_block, per_block)        # from block 0, step 0

    def _is_vehicle(self) -> bool:
        return getattr(self.motion, "kind", "") == "trajectory"

    def _queue_motion(self, k_taken: int) -> None:
        """Queue a vehicle's kinematics of the blocks after thermal step ``k_taken`` (the
        block layout of :func:`rlgsim.sim.run.simulate.simulate`: :data:`BLOCK_S` each, the
        last one shorter) until :data:`MOTION_AHEAD` are queued or the run ends."""
        per_block = int(round(BLOCK_S / self.step_s))
        if self._motion_pool is None:
            self._motion_pool = ThreadPoolExecutor(max_workers=2,
                                                   thread_name_prefix="rlgsim-motion")
        self._motion_next = max(self._motion_next, k_taken)
        while len(self._motion_ahead) < MOTION_AHEAD and self._motion_next < self.n_steps:
            k0 = self._motion_next
            m = min(per_block, self.n_steps - k0)
            n = self._block_size(m)
            apart = self.motion_rows is not None         # the truth rows in the other thread
            self._motion_ahead[(k0, m, n)] = (
                self._motion_pool.submit(self._kinematics_now, k0, m, n, not apart),
                self._motion_pool.submit(self._truth_rows, k0, n) if apart else None)
            self._motion_next = k0 + m

    def _kinematics(self, b: int, k0: int, m: int, n: int) -> dict[str, Any]:
        """:meth:`_kinematics_now` of the block — a vehicle's from the worker thread when it
        queued the block (then the next block is queued)."""
        ahead = self._motion_ahead.pop((k0, m, n), None)
        if ahead is None:
            return self._kinematics_now(k0, m, n)
        out = ahead[0].result()
        if ahead[1] is not None:
            out["motion"].rows = ahead[1].result()
        self._queue_motion(k0 + m)
        return out

    def _truth_rows(self, k0: int, n: int) -> Any:
        """A vehicle's truth rows (:attr:`motion_rows`) of the ``n`` samples from thermal step
        ``k0``, at the sample end times :meth:`_vehicle_block`'s block has."""
        from rlgsim.sim.motion.kinematics import _edges
        t_s = _edges(round(k0 * self.step_s * self.rate_hz), np.arange(n) + 1, self.rate_hz)
        return self.motion_rows(t_s, None)          # made with the states in one pass

    def _kinematics_now(self, k0: int, m: int, n: int, truth: bool = True) -> dict[str, Any]:
        """The motion's exact increments (``dth_t``, ``dv_t`` (3, n) rows of the body axes),
        the steps at rest of each, their sums per thermal step and the table at each step's
        end; a vehicle's truth rows too (:attr:`motion_rows`) unless ``truth`` is False (then
        :meth:`_truth_rows` makes them)."""
        idx = sample_step_index(n, m, self.rate_hz, self.step_s)
        # a turntable's runs of whole steps at rest are read through their first step only
        # (steps_held, _step_sums): the rest of them is not written (Motion.increments)
        sparse = (isinstance(idx, int) and n == m * idx and not self.truth_samples
                  and not self._is_vehicle())
        mb = self._vehicle_block(k0, n, truth, held_steps=idx if sparse else 0)
        dth_t, dv_t = mb.dtheta_rad.T, mb.dv_m_per_s.T          # (3, n) C-contiguous
        held = _held_steps(mb.constant, m, idx)
        out: dict[str, Any] = {"motion": mb, "dth_t": dth_t, "dv_t": dv_t}
        if sparse:      # a turntable's Δθ and Δv rows are one array (Motion.increments): one call
            uniform, first = steps_held(mb.both, m, idx, held)
            sums = _step_sums(mb.both, idx, m, held)
            out.update(steps_g=(uniform, first[:3]),
                       steps_a=(uniform, first[3:]) if self.r.accels is not None else None,
                       dtheta_step=np.ascontiguousarray(sums[:, :3]),
                       dv_step=np.ascontiguousarray(sums[:, 3:]))
        else:
            # steps at rest (one increment for all their samples): evaluated once per step
            out.update(steps_g=step_inputs(dth_t, m, idx),
                       steps_a=step_inputs(dv_t, m, idx) if self.r.accels is not None else None,
                       dtheta_step=_step_sums(dth_t, idx, m, held),
                       dv_step=_step_sums(dv_t, idx, m, held))
        if n:                               # the table at the ends of each step's last sample
            outer, inner, segment = self.motion.angles(
                mb.end_times(_last_sample_of_step(idx, m, n)))
            out["table"] = (outer, inner, np.asarray(segment).astype(np.int32))
        return out

    def _vehicle_block(self, k0: int, n: int, truth: bool = True, held_steps: int = 0
                       ) -> Any:
        """The motion's block of ``n`` samples from thermal step ``k0``; a vehicle's with its
        truth states (``states``) too (``truth``); a turntable's with the runs of whole steps
        of ``held_steps`` samples at rest written only in their first step (> 0;
        :meth:`rlgsim.sim.motion.kinematics.Motion.increments`)."""
        more = {"held_steps": held_steps} if held_steps else {}
        mb = self.motion.increments(k0 * self.step_s, n, self.rate_hz, angles=False, **more)
        if self._is_vehicle() and truth:
            mb.states = self.motion.truth(mb.t_s)
            if self.motion_rows is not None:    # the truth group's rows, made here once
                mb.rows, mb.states = self.motion_rows(mb.t_s, mb.states), None
        return mb

    def _drives(self, b: int, m: int, slow_state: Any, draws: dict[str, Any] | None = None
                ) -> dict[str, Any]:
        """The block's slow noise ``slow_block`` = (slow noise (m, C), state after) from the
        carried ``slow_state`` and the block's own draws, and the UHFO drives (each channel has
        its own generator); ``draws`` :meth:`_drive_draws` of the block (drawn now when None)."""
        draws = draws if draws is not None else self._drive_draws(b, m)
        out: dict[str, Any] = {"slow_block": self.slow.block(slow_state, b, m,
                                                              draws["slow_draws"])}
        if self.r.uhfo is not None:
            out["uhfo"] = draws["uhfo_draws"]
        return out

    def _drive_draws(self, b: int, m: int) -> dict[str, Any]:
        """The standard normals of block ``b``'s slow noise and UHFO (``m`` thermal steps):
        independent of any state, so the worker draws them with the block's white noise."""
        fill = _compiled("fill_streams") if self.compiled else None   # one call each
        out: dict[str, Any] = {"slow_draws": self.slow.draws(b, m, fill)}
        if self.r.uhfo is not None:
            out["uhfo_draws"] = self.r.uhfo.draws(self.seed, self.unit, b, m, fill)
        return out

    def _submit_parts(self, b: int, m: int, n: int) -> list[Any]:
        """The worker's tasks for block ``b`` (``m`` steps, ``n`` samples), in the order of
        :meth:`_take_normals`: gyro normals, accelerometer normals, slow-noise and UHFO
        drives."""
        return [self._pool.submit(self._gyro_normals, b, n),
                self._pool.submit(self._accel_normals, b, n),
                self._pool.submit(lambda: {"drive_draws": self._drive_draws(b, m)})]

    def _gyro_normals(self, b: int, n: int) -> dict[str, Any]:
        """The gyros' white-noise normals (numpy's generators release the GIL while they fill
        an array)."""
        return {"zg": self.white("gyro.white", self.r.gyros.axes, self.gyro_white_sigma, b, n)}

    def _accel_normals(self, b: int, n: int) -> dict[str, Any]:
        """The accelerometers' white-noise normals."""
        if self.r.accels is None:
            return {}
        return {"za": self.white("accel.white", self.r.accels.axes, self.accel_white_sigma,
                                 b, n)}

    def _block_size(self, m: int) -> int:
        """IMU samples of a block of ``m`` thermal steps: those whose interval ends inside it
        (a short last block at a low rate may hold none: sample_rate_hz = 0.1,
        duration_s = 605)."""
        return int(math.floor(m * self.step_s * self.rate_hz + 1e-9))

    def _get_inputs(self, b: int, k0: int, m: int, n: int, slow_state: Any
                    ) -> dict[str, Any]:
        """Block ``b``'s inputs: its normals (the worker's; a part it has not started, or a
        block it was not given, drawn here), then — once the normals of the next
        :data:`PREFETCH_BLOCKS` blocks are queued, so the worker does not wait for this
        thread — its kinematics and drives, computed here from the carried slow-noise state
        (their standard normals the worker's too)."""
        normals = self._take_normals((b, k0, m, n))
        drive_draws = normals.pop("drive_draws", None)
        last = self.n_steps is not None and k0 + m >= self.n_steps
        if self.prefetch and not last:
            self._queue_after(b, k0, m)
        kinematics = self._kinematics(b, k0, m, n)
        if last:
            self.close()                        # the last block: nothing to prefetch
        return {**normals, **kinematics, **self._drives(b, m, slow_state, drive_draws)}

    def _take_normals(self, key: tuple[int, int, int, int]) -> dict[str, Any]:
        """The normals of block ``key`` = (b, k0, m, n): the worker's when it queued this
        block (a part it has not started yet is drawn here: this thread would only wait for
        it), else drawn here (and the blocks queued for another layout dropped); with the
        block's slow-noise and UHFO draws (``drive_draws``) when the worker queued them."""
        b, m, n = key[0], key[2], key[3]
        draws = (lambda: self._gyro_normals(b, n), lambda: self._accel_normals(b, n),
                 lambda: {"drive_draws": self._drive_draws(b, m)})
        if self._ahead and self._ahead[0][0] == key:
            out: dict[str, Any] = {}
            for part, draw in zip(self._ahead.popleft()[1], draws):
                out.update(draw() if part.cancel() else part.result())
            return out
        self._cancel_ahead()
        return {k: v for draw in draws[:2] for k, v in draw().items()}

    def _queue_after(self, b: int, k0: int, m: int) -> None:
        """Queue the normals of the blocks after block ``b`` (first step ``k0``, blocks of ``m``
        steps assumed, up to the run's end; a block of another length is drawn when asked for)
        until :data:`PREFETCH_BLOCKS` are queued: one worker thread, three tasks per block (a
        vehicle's kinematics go to their own worker: :meth:`start`)."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rlgsim-imu")
        if self._ahead:
            b, k0 = self._ahead[-1][0][:2]
        while len(self._ahead) < PREFETCH_BLOCKS:
            b, k0 = b + 1, k0 + m
            nm = m if self.n_steps is None else min(m, self.n_steps - k0)
            if nm <= 0:
                break
            n = self._block_size(nm)
            self._ahead.append(((b, k0, nm, n), self._submit_parts(b, nm, n)))

    def _cancel_ahead(self) -> None:
        """Drop the queued normals (those of a block the worker has started are not used)."""
        for _, parts in self._ahead:
            for part in parts:
                part.cancel()
        self._ahead.clear()

    def close(self) -> None:
        """Stop the prefetch threads (blocks queued and not taken are dropped)."""
        self._cancel_ahead()
        for parts in self._motion_ahead.values():
            for part in parts:
                if part is not None:
                    part.cancel()
        self._motion_ahead.clear()
        self._motion_next = self.n_steps or 0   # queue no more
        for pool in (self._pool, self._motion_pool):
            if pool is not None:
                pool.shutdown(wait=True)
        self._pool = self._motion_pool = None

    def block(self, state: ImuState, b: int, trace
              ) -> tuple[dict[str, dict[str, dict[str, np.ndarray]]], ImuState]:
        """Rows of the ``imu``, ``turntable`` and ``truth`` groups for block ``b``.

        ``trace`` a :class:`rlgsim.sim.stages.base.ThermalTrace` (thermal steps of the block); the
        turntable kinematics come from ``motion``.
        """
        dt = self.step_s
        m = len(trace.t_s)
        k0 = int(round(float(trace.t_s[0]) / dt)) - 1           # first step of the block
        n = self._block_size(m)
        inputs = self._get_inputs(b, k0, m, n, state.slow)
        motion_block = inputs["motion"]
        idx = sample_step_index(n, m, self.rate_hz, dt)
        nodes, start = np.asarray(trace.nodes_c), np.asarray(trace.start_c)
        power = np.asarray(trace.power)
        g, acc, uh = self.r.gyros, self.r.accels, self.r.uhfo

        # UHFO and the discharge excitation
        uhfo_dev = None
        imu_time: dict[str, np.ndarray] = {"time": trace.t_s}
        truth_time: dict[str, np.ndarray] = {"time": trace.t_s}
        wander = state.uhfo_wander
        if uh is not None:
            u_true, u_read, wander = uh.block(state.uhfo_wander, self.seed, self.unit, b, nodes,
                                              start, dt, power, draws=inputs["uhfo"])
            uhfo_dev = u_true - uh.u0[None, :]
            imu_time["uhfo"] = u_read
            truth_time["uhfo_true"] = u_true

        # slow noise (flicker, random walk) of every channel, part of the true biases
        slow, slow_state = inputs["slow_block"]

        # gyros
        gp = g.parameters(nodes, start, dt, slow[:, :self.n_gyro], uhfo_dev)
        an = self.anomalies
        if an is not None:                      # mode hops: part of the true bias
            gp.bias = gp.bias + an.gyro_bias_offset(trace)
        dth_t = inputs["dth_t"]
        gyro_pulses, g_rem = count_pulses(state.gyro_remainder, gp.scale_factor, gp.bias,
                                          gp.installation, dth_t, inputs["zg"],
                                          self.gyro_white_sigma, self.sample_dt, idx, power,
                                          g.axis_idx, steps=inputs["steps_g"],
                                          compiled=self.compiled)
        valid = None
        if an is not None:                      # read-out spikes, lost frames (after counting)
            k0_sample = int(math.floor(k0 * dt * self.rate_hz + 1e-9))   # first sample
            gyro_pulses, valid = an.gyro_pulses(b, k0_sample, self.rate_hz, gyro_pulses, start)
        imu_sample = {"gyro_pulses": gyro_pulses}
        if an is not None and an.model.imu_dropout_rate_per_h > 0:
            imu_sample["sample_valid"] = valid.astype(np.int8)
        truth_time.update(gyro_bias=gp.bias, gyro_bias_random=gp.bias_random,
                          gyro_scale_factor=gp.scale_factor,
                          gyro_installation=gp.installation)

        # accelerometers
        a_rem = state.accel_remainder
        dv_t = inputs["dv_t"]
        if acc is not None:
            ap = acc.parameters(nodes, start, dt, slow[:, self.n_gyro:])
            accel_pulses, a_rem = count_pulses(state.accel_remainder, ap.scale_factor_pos,
                                               ap.bias, ap.installation, dv_t, inputs["za"],
                                               self.accel_white_sigma, self.sample_dt, idx,
                                               power, acc.axis_idx,
                                               scale_factor_neg=ap.scale_factor_neg,
                                               steps=inputs["steps_a"],
                                               compiled=self.compiled)
            if valid is not None and not valid.all():     # lost frames lose every channel
                accel_pulses = an.other_pulses(valid, k0_sample, self.rate_hz, accel_pulses,
                                               acc.axes)
            imu_sample["accel_pulses"] = accel_pulses
            truth_time.update(accel_bias=ap.bias, accel_bias_random=ap.bias_random,
                              accel_scale_factor_pos=ap.scale_factor_pos,
                              accel_scale_factor_neg=ap.scale_factor_neg,
                              accel_installation=ap.installation)

        # true inputs summed per thermal step
        truth_time["dtheta_step"] = inputs["dtheta_step"]
        truth_time["dv_step"] = inputs["dv_step"]
        rows = {"imu": {"sample": imu_sample, "time": imu_time},
                "truth": {"time": truth_time}}
        if self.truth_samples:
            rows["truth"]["sample"] = {"dtheta": motion_block.dtheta_rad,
                                       "dv": motion_block.dv_m_per_s}
        # turntable angles and motion index at the end of each thermal step
        if n:                        # the table at the ends of the steps' last samples
            outer, inner, segment = inputs["table"]
        else:                        # no sample in the block: the table at each step's end
            outer, inner, segment = self.motion.angles(trace.t_s)
            segment = np.asarray(segment).astype(np.int32)
        rows["turntable"] = {"time": {
            "time": trace.t_s, "outer_angle": outer, "inner_angle": inner,
            "motion_index": segment}}
        self.last_motion_block = motion_block     # the stage reads a vehicle's states from it
        return rows, ImuState(g_rem, a_rem, slow_state, wander)


def _compiled(name: str):
    """The function ``name`` of :mod:`rlgsim.sim.sensors._normal_kernel` (``fill``: the white
    noise's float32 draws; ``fill_streams``: the drives' float64 ones) when the kernels give
    numpy's draws in this process (the module's self-check, once), else None (numpy's own draw
    is used)."""
    try:
        from rlgsim.sim.sensors import _normal_kernel
    except ImportError:                         # pragma: no cover - numba is a dependency
        return None
    return getattr(_normal_kernel, name) if _normal_kernel.available() else None


def _held_steps(constant: Sequence[tuple[int, int]], m: int, idx: np.ndarray | int
                ) -> list[tuple[int, int]] | None:
    """The runs of steps ``(lo, hi)`` whose ``idx`` samples all lie in one of the
    ``constant`` runs of samples (:attr:`rlgsim.sim.motion.kinematics.MotionBlock.constant`: one
    increment, bit for bit), one per such run; None when the ``m`` steps do not all hold
    ``idx`` samples."""
    if not isinstance(idx, int):
        return None
    runs = [(-(-lo // idx), min(hi // idx, m)) for lo, hi in constant]
    return [(lo, hi) for lo, hi in runs if hi > lo]


def steps_held(x_t: np.ndarray, m: int, idx: int, held: list[tuple[int, int]] | None
               ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rlgsim.sim.sensors.sensor_triad.step_inputs`' (uniform, first) of increments
    ``x_t`` (k, m·idx) known from the motion (k = 3, or 6: a turntable's Δθ and Δv rows in one
    array): the ``held`` runs of steps (:func:`_held_steps`)
    at rest, with their first step's first sample; every other step's own first sample, not
    marked at rest. Only the first step of a held run is read (the others may be unwritten:
    :attr:`rlgsim.sim.motion.kinematics.MotionBlock.unwritten`). A step at rest by its bits
    but not held is counted sample by sample: the same operations on the same numbers, so
    the same pulses (:mod:`rlgsim.sim.sensors._pulse_kernel`)."""
    uniform = np.zeros(m, dtype=np.bool_)
    first = np.array(x_t[:, ::idx])                 # (k, m): each step's first sample
    for lo, hi in held or ():
        uniform[lo:hi] = True
        first[:, lo + 1:hi] = first[:, lo:lo + 1]
    return uniform, first


def _step_sums(x_t: np.ndarray, idx: np.ndarray | int, m: int,
               held: list[tuple[int, int]] | None = None) -> np.ndarray:
    """Sums of per-sample values ``x_t`` (k, n) over each thermal step: (m, k).

    numpy's pairwise summation over each step's samples (contiguous rows). ``held``
    (:func:`_held_steps`): runs of steps whose samples all repeat one value; each run's first
    step is summed (the same row of numbers as every step of the run, so the same sum) and
    its sum repeated."""
    k, n = x_t.shape
    if not isinstance(idx, int):
        out = np.zeros((m, k))
        np.add.at(out, idx, x_t.T)
        return out
    xs = x_t.reshape(k, m, idx)
    if not held:
        return xs.sum(axis=2).T.copy()
    out = np.empty((m, k))
    summed = np.zeros(m, dtype=bool)
    for lo, hi in held:
        out[lo:hi] = xs[:, lo:lo + 1].sum(axis=2).T
        summed[lo:hi] = True
    rest = np.flatnonzero(~summed)
    if rest.size:
        out[rest] = xs[:, rest].sum(axis=2).T
    return out


def _last_sample_of_step(idx: np.ndarray | int, m: int, n: int) -> np.ndarray:
    """Index of the last sample whose mid-point lies in each step (the step's end sample)."""
    if isinstance(idx, int):
        return step_counts(m + 1)[1:] * idx - 1      # arange(1, m + 1): no GIL hand-off
    last = np.searchsorted(idx, np.arange(m), side="right") - 1
    return np.clip(last, 0, n - 1)
