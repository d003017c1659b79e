"""The IMU: a *model* (nominal values + tolerances of a device preset) versus one drawn
*realisation* (the truth of one unit), and the simulation stage that turns thermal state and
motion into pulses, UHFO and ground truth.

Model and realisation (as in pyins' ``sim`` or any Monte Carlo of a sensor lot): the device
preset's ``[gyro]``, ``[accelerometer]``, ``[uhfo]`` and ``[noise]`` tables give nominal laws and
noise levels; ``[tolerance]`` gives the unit-to-unit spread (1σ). :meth:`ImuModel.realise` draws
one unit: every coefficient of every law of every axis, and the noise levels, from keyed
sub-streams of the given generator (adding a coefficient never changes the others). The
realisation is the truth of that unit — stored in the dataset's ``truth`` group as a table.

The stage (:class:`ImuSimulator`) runs block by block inside :func:`rlgsim.sim.run.simulate.simulate`:

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
the run took ~10 % longer (paper000 at 100 Hz, bench_sim pairs). The samples at rest are
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
:func:`true_increments` recomputes the per-sample values bit for bit; ``truth_samples=True``
stores them per sample as well (48 bytes per epoch — at 100 Hz over paper 000's 121 h
programme that is 2 GB, several times the rest of the file, which is why it is not the
default; see benchmarks/bench_sim.py).
"""

from __future__ import annotations

import json
import math
import sys
import zlib
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from rlgsim.sim.sensors.accelerometer import AccelerometerModel, Accelerometers
from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_table
from rlgsim.sim.writer.schema import (DESCRIPTIONS, declare_imu, declare_sample_valid,
                                       declare_trajectory, declare_truth, declare_turntable,
                                       trajectory_rows)
from rlgsim.ground.dataset_format import IMU, TRAJECTORY, TRUTH, TURNTABLE
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.sensors.gyro import BODY_AXES, GyroModel, Gyros, sample_step_index
from rlgsim.sim.sensors.noise import NOISE_LEVELS, NoiseModel, SlowNoise
from rlgsim.sim.rng import generator
from rlgsim.sim.sensors.sensor_triad import count_pulses, step_inputs
from rlgsim.sim.sensors.uhfo import Uhfo, UhfoModel

_NOISE_REL_KEYS = tuple(f"{k}_rel" for k in NOISE_LEVELS)

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


@dataclass(frozen=True)
class Tolerance:
    """The ``[tolerance]`` preset table: unit-to-unit spreads (1σ).

    Sub-tables ``gyro`` / ``accelerometer`` (one sub-table per law, same keys as the law),
    ``uhfo`` (law keys, ``wander_rel``, ``noise_rel``) and ``noise`` (relative spreads
    ``gyro_arw_rel``, ``gyro_bi_rel``, ``gyro_rrw_rel``, ``accel_vrw_rel``, ``accel_bi_rel``,
    ``accel_rrw_rel``). Law sub-tables are checked against their laws when the model is built.
    """

    gyro: Mapping | None
    accelerometer: Mapping | None
    uhfo: Mapping | None
    noise: Mapping[str, float]
    ctx: Ctx

    @classmethod
    def from_config(cls, table: Mapping, ctx: Ctx) -> "Tolerance":
        check_known_keys(table, ("gyro", "accelerometer", "uhfo", "noise"), ctx)
        noise = get_table(table, "noise", ctx, {})
        nctx = ctx.child("noise")
        check_known_keys(noise, _NOISE_REL_KEYS, nctx)
        rel = {k[:-4]: get_float(noise, k, nctx, 0.0, min=0.0, max=1.0) for k in _NOISE_REL_KEYS}
        return cls(gyro=get_table(table, "gyro", ctx, None),
                   accelerometer=get_table(table, "accelerometer", ctx, None),
                   uhfo=get_table(table, "uhfo", ctx, None), noise=rel, ctx=ctx)


def _keyed_draw(rng: np.random.Generator):
    """``draw(name, shape)``: standard normals from a sub-stream keyed by ``name``."""
    base = int(rng.integers(0, 2**63 - 1))

    def draw(name: str, shape: tuple[int, ...]) -> np.ndarray:
        sub = np.random.Generator(np.random.PCG64(
            np.random.SeedSequence(entropy=base, spawn_key=(zlib.crc32(name.encode()),))))
        return sub.standard_normal(shape)
    return draw


@dataclass(frozen=True)
class ImuModel:
    """A device's sensors: nominal laws + tolerances (the *model*, not a unit).

    ``gyro`` always; ``accel`` and ``uhfo`` optional; ``noise`` levels; ``noise_rel`` relative
    1σ spreads of the noise levels; ``source`` the preset file (for messages).
    """

    gyro: GyroModel
    accel: AccelerometerModel | None
    uhfo: UhfoModel | None
    noise: NoiseModel
    noise_rel: Mapping[str, float]
    source: str = ""

    @classmethod
    def from_device(cls, device) -> "ImuModel | None":
        """The model of a :class:`rlgsim.sim.run.scenario.Device` (None when it has no ``[gyro]``)."""
        parts = dict(getattr(device, "parts", {}) or {})
        tables = dict(getattr(device, "tables", {}) or {})
        return cls.from_tables(tables, device.source, parts=parts)

    @classmethod
    def from_tables(cls, tables: Mapping[str, Mapping], source: str = "",
                    parts: Mapping[str, Any] | None = None) -> "ImuModel | None":
        """Build from raw preset tables (``gyro``, ``accelerometer``, ``uhfo``, ``noise``,
        ``tolerance``); already validated ``parts`` are reused. Raises UserInputError."""
        parts = dict(parts or {})
        ctx = Ctx(source)

        def part(name: str, cls_):
            if name in parts:
                return parts[name]
            if name in tables:
                return cls_.from_config(tables[name], ctx.child(name))
            return None
        gyro = part("gyro", GyroModel)
        if gyro is None:
            for other in ("accelerometer", "uhfo", "noise", "tolerance"):
                if other in tables:
                    raise ctx.error(other, "needs a [gyro] table in the same device preset")
            return None
        accel = part("accelerometer", AccelerometerModel)
        uhfo = part("uhfo", UhfoModel)
        noise = part("noise", NoiseModel) or NoiseModel()
        tol = part("tolerance", Tolerance) or Tolerance(None, None, None, {}, ctx)
        tctx = ctx.child("tolerance")
        gyro = gyro.with_tolerance(tol.gyro, tctx.child("gyro"))
        if tol.accelerometer is not None:
            if accel is None:
                raise tctx.error("accelerometer", "there is no [accelerometer] table to spread")
            accel = accel.with_tolerance(tol.accelerometer, tctx.child("accelerometer"))
        if uhfo is not None:
            uhfo = uhfo.for_axes(len(gyro.axes)).with_tolerance(tol.uhfo, tctx.child("uhfo"))
        elif tol.uhfo is not None:
            raise tctx.error("uhfo", "there is no [uhfo] table to spread")
        if gyro.bias.nominal["uhfo"].any() and uhfo is None:
            raise ctx.child("gyro").child("bias").error(
                "uhfo_deg_per_h_per_v", "the bias depends on UHFO but the device has no [uhfo]")
        return cls(gyro=gyro, accel=accel, uhfo=uhfo, noise=noise,
                   noise_rel=dict(tol.noise), source=source)

    def realise(self, rng: np.random.Generator) -> "ImuRealisation":
        """Draw one unit from ``rng`` (see the module docstring)."""
        draw = _keyed_draw(rng)
        gyros = self.gyro.realise(draw)
        accels = self.accel.realise(draw) if self.accel is not None else None
        uhfo = (self.uhfo.realise(draw, gyros.axes, gyros.blocks)
                if self.uhfo is not None else None)
        levels = {}
        for key in NOISE_LEVELS:
            n = gyros.n if key.startswith("gyro") else (accels.n if accels else 0)
            rel = self.noise_rel.get(key, 0.0)
            z = draw(f"noise.{key}", (n,)) if rel > 0 else np.zeros(n)
            levels[key] = getattr(self.noise, key) * np.abs(1.0 + rel * z)
        return ImuRealisation(gyros=gyros, accels=accels, uhfo=uhfo, noise=self.noise,
                              levels=levels)


@dataclass
class ImuRealisation:
    """One unit: realised gyros, accelerometers, UHFO and per-axis noise levels (SI)."""

    gyros: Gyros
    accels: Accelerometers | None
    uhfo: Uhfo | None
    noise: NoiseModel
    levels: dict[str, np.ndarray]

    def bind(self, node_names: Sequence[str], source: str = "") -> None:
        """Resolve every law's nodes in the thermal network; a missing node is a
        UserInputError naming the preset and the node."""
        try:
            self.gyros.bind(node_names)
            if self.accels is not None:
                self.accels.bind(node_names)
            if self.uhfo is not None:
                self.uhfo.bind(node_names)
        except KeyError as exc:
            raise UserInputError(
                f"{source + ': ' if source else ''}sensor laws refer to thermal node "
                f"{exc.args[0]!r}, which the device's thermal network does not have; nodes: "
                f"{', '.join(node_names)}") from None

    def coefficient_table(self) -> tuple[list[str], np.ndarray, list[str]]:
        """(names, values, units) of every drawn coefficient, one row per component."""
        names, values, unit_list = [], [], []

        def add(law, comps: Sequence[str]):
            for name, vals, unit in law.table():
                for comp, v in zip(comps, vals):
                    names.append(f"{name}[{comp}]")
                    values.append(float(v))
                    unit_list.append(unit)
        g = self.gyros
        gm = [f"{a}{o}" for a in g.axes for o in BODY_AXES if o != a]
        add(g.bias, g.axes)
        add(g.scale_factor, g.axes)
        add(g.misalignment, gm)
        for a in g.axes:
            names.append(f"gyro.k0[{a}]")
            values.append(g.k0)
            unit_list.append("pulses/rad")
        if self.accels is not None:
            acc = self.accels
            am = [f"{a}{o}" for a in acc.axes for o in BODY_AXES if o != a]
            for law in acc.laws():
                add(law, am if law is acc.misalignment else acc.axes)
            for a in acc.axes:
                names.append(f"accel.k0[{a}]")
                values.append(acc.k0)
                unit_list.append("pulses/(m/s)")
        if self.uhfo is not None:
            add(self.uhfo.law, self.uhfo.axes)
            for a, w, e in zip(self.uhfo.axes, self.uhfo.wander_v, self.uhfo.noise_v):
                names += [f"uhfo.wander_v[{a}]", f"uhfo.noise_v[{a}]"]
                values += [float(w), float(e)]
                unit_list += ["V", "V"]
        si = {"gyro_arw": "rad/s^0.5", "gyro_bi": "rad/s", "gyro_rrw": "rad/s^1.5",
              "accel_vrw": "m/s^1.5", "accel_bi": "m/s^2", "accel_rrw": "m/s^2.5"}
        for key, vals in self.levels.items():
            axes = g.axes if key.startswith("gyro") else (self.accels.axes if self.accels else ())
            for a, v in zip(axes, vals):
                names.append(f"noise.{key}[{a}]")
                values.append(float(v))
                unit_list.append(si[key])
        return names, np.array(values), unit_list


# --------------------------------------------------------------------------- the stage


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
        self._pool = None
        #: queued blocks in order: ((b, k0, m, n), [futures of its gyro and accel normals])
        self._ahead: deque[tuple[tuple[int, int, int, int], list[Any]]] = deque()
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
        fill = _compiled_normals() if self.compiled else None
        if fill is not None:                    # the same draws, compiled (_normal_kernel)
            fill(generators, z, advance=False)
        else:
            for g, row in zip(generators, z):
                g.standard_normal(n, dtype=np.float32, out=row)
        return z

    # ---- one block ------------------------------------------------------------------------
    def _kinematics(self, b: int, k0: int, m: int, n: int) -> dict[str, Any]:
        """The motion's exact increments (``dth_t``, ``dv_t`` (3, n) rows of the body axes),
        the steps at rest of each, their sums per thermal step and the table at each step's
        end."""
        mb = self.motion.increments(k0 * self.step_s, n, self.rate_hz, angles=False)
        idx = sample_step_index(n, m, self.rate_hz, self.step_s)
        dth_t, dv_t = mb.dtheta_rad.T, mb.dv_m_per_s.T          # (3, n) C-contiguous
        held = _held_steps(mb.constant, m, idx)
        out: dict[str, Any] = {
            "motion": mb, "dth_t": dth_t, "dv_t": dv_t,
            # steps at rest (one increment for all their samples): evaluated once per step
            "steps_g": step_inputs(dth_t, m, idx),
            "steps_a": step_inputs(dv_t, m, idx) if self.r.accels is not None else None,
            "dtheta_step": _step_sums(dth_t, idx, m, held),
            "dv_step": _step_sums(dv_t, idx, m, held)}
        if n:                               # the table at the ends of each step's last sample
            outer, inner, segment = self.motion.angles(
                mb.end_times(_last_sample_of_step(idx, m, n)))
            out["table"] = (outer, inner, np.asarray(segment).astype(np.int32))
        return out

    def _drives(self, b: int, m: int, slow_state: Any) -> dict[str, Any]:
        """The block's slow noise ``slow_block`` = (slow noise (m, C), state after) from the
        carried ``slow_state`` and the block's own draws, and the UHFO drives (each channel has
        its own generator)."""
        draws = self.slow.draws(b, m)
        out: dict[str, Any] = {"slow_block": self.slow.block(slow_state, b, m, draws)}
        if self.r.uhfo is not None:
            out["uhfo"] = self.r.uhfo.draws(self.seed, self.unit, b, m)
        return out

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
        thread — its kinematics and drives, computed here from the carried slow-noise state."""
        normals = self._take_normals((b, k0, m, n))
        if self.n_steps is not None and k0 + m >= self.n_steps:
            self.close()                        # the last block: nothing to prefetch
        elif self.prefetch:
            self._queue_after(b, k0, m)
        return {**normals, **self._kinematics(b, k0, m, n), **self._drives(b, m, slow_state)}

    def _take_normals(self, key: tuple[int, int, int, int]) -> dict[str, Any]:
        """The normals of block ``key`` = (b, k0, m, n): the worker's when it queued this
        block (a part it has not started yet is drawn here: this thread would only wait for
        it), else drawn here (and the blocks queued for another layout dropped)."""
        b, n = key[0], key[3]
        draws = (self._gyro_normals, self._accel_normals)
        if self._ahead and self._ahead[0][0] == key:
            out: dict[str, Any] = {}
            for part, draw in zip(self._ahead.popleft()[1], draws):
                out.update(draw(b, n) if part.cancel() else part.result())
            return out
        self._cancel_ahead()
        return {k: v for draw in draws for k, v in draw(b, n).items()}

    def _queue_after(self, b: int, k0: int, m: int) -> None:
        """Queue the normals of the blocks after block ``b`` (first step ``k0``, blocks of ``m``
        steps assumed, up to the run's end; a block of another length is drawn when asked for)
        until :data:`PREFETCH_BLOCKS` are queued: one worker thread, two tasks per block."""
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
            self._ahead.append(((b, k0, nm, n),
                                [self._pool.submit(self._gyro_normals, b, n),
                                 self._pool.submit(self._accel_normals, b, n)]))

    def _cancel_ahead(self) -> None:
        for _, parts in self._ahead:
            for part in parts:
                part.cancel()
        self._ahead.clear()

    def close(self) -> None:
        """Stop the prefetch thread (blocks queued and not taken are dropped)."""
        self._cancel_ahead()
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def block(self, state: ImuState, b: int, trace
              ) -> tuple[dict[str, dict[str, dict[str, np.ndarray]]], ImuState]:
        """Rows of the ``imu``, ``turntable`` and ``truth`` groups for block ``b``.

        ``trace`` a :class:`rlgsim.sim.run.simulate.ThermalTrace` (thermal steps of the block); the
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
        if getattr(self.motion, "kind", "turntable") == "trajectory":   # a vehicle's states
            rows[TRAJECTORY] = {"sample": trajectory_rows(self.motion, motion_block.t_s)}
        return rows, ImuState(g_rem, a_rem, slow_state, wander)


def _compiled_normals():
    """:func:`rlgsim.sim.sensors._normal_kernel.fill` when it gives numpy's draws in this process (its
    self-check, once), else None (numpy's own draw is used)."""
    try:
        from rlgsim.sim.sensors._normal_kernel import available, fill
    except ImportError:                         # pragma: no cover - numba is a dependency
        return None
    return fill if available() else None


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
        return np.arange(1, m + 1) * idx - 1
    last = np.searchsorted(idx, np.arange(m), side="right") - 1
    return np.clip(last, 0, n - 1)


# --------------------------------------------------------------------------- simulate stage


class ImuStage:
    """The sensor stage of :func:`rlgsim.sim.run.simulate.simulate`: groups ``imu`` (pulses, UHFO),
    ``turntable`` (table angles, motion labels) and ``truth`` (true parameters, inputs and the
    drawn unit). docs/dataset.md describes every variable."""

    needs_motion = True

    groups = {name: DESCRIPTIONS[name] for name in (IMU, TURNTABLE, TRUTH)}

    def __init__(self, scenario, timeline, model: ImuModel, *, unit: int = 0) -> None:
        network = scenario.device.thermal.network
        if network is None:
            raise UserInputError(f"{scenario.device.source}: the device has sensor tables but "
                                 f"no thermal network; sensors need node temperatures")
        self.scenario = scenario
        self.timeline = timeline
        self.model = model
        self.unit = int(unit)
        self.realisation = model.realise(generator(scenario.realisation_seed, self.unit,
                                                   "realisation", "imu", 0))
        self.turntable_segments = [s for s in timeline.segments if s.track == "turntable"]
        #: a vehicle's route (rlgsim.sim.motion.trajectory_config.TrajectoryProgram) or None
        self.trajectory = getattr(scenario, "trajectory", None)
        if self.trajectory is not None:
            self.groups = {**type(self).groups, TRAJECTORY: DESCRIPTIONS[TRAJECTORY]}
        self.truth_samples = bool(getattr(scenario.acquisition, "truth_samples", False))
        self.sim = ImuSimulator(self.realisation, network.node_names, seed=scenario.seed,
                                unit=self.unit, rate_hz=scenario.acquisition.sample_rate_hz,
                                step_s=timeline.step_s, motion=None,
                                truth_samples=self.truth_samples,
                                source=scenario.device.source, n_steps=timeline.n_steps)
        from rlgsim.sim.sensors.anomalies import AnomalyRun
        self.sim.anomalies = AnomalyRun.of(scenario, timeline)   # None unless [anomalies]

    @classmethod
    def create(cls, scenario, timeline) -> "ImuStage | None":
        """The stage for ``scenario`` (None when its device has no ``[gyro]`` table)."""
        model = ImuModel.from_device(scenario.device)
        if model is None:
            return None
        return cls(scenario, timeline, model, unit=scenario.unit)

    # ---- dataset layout -------------------------------------------------------------------
    def declare(self, writers: Mapping[str, Any]) -> None:
        """Declare the three groups' dimensions and variables (:mod:`rlgsim.sim.writer.schema`,
        docs/dataset.md)."""
        r, sim = self.realisation, self.sim
        declare_imu(writers[IMU], r, rate_hz=sim.rate_hz, step_s=sim.step_s)
        if sim.anomalies is not None and sim.anomalies.model.imu_dropout_rate_per_h > 0:
            declare_sample_valid(writers[IMU])           # frame dropouts on
        declare_turntable(writers[TURNTABLE], self.turntable_segments)
        if self.trajectory is not None:
            declare_trajectory(writers[TRAJECTORY],
                               self.trajectory.build(float(self.timeline.duration_s)))
        declare_truth(writers[TRUTH], r, seed=self.scenario.seed, unit=self.unit,
                      rate_hz=sim.rate_hz, step_s=sim.step_s,
                      gyro_white_sigma=sim.gyro_white_sigma,
                      accel_white_sigma=sim.accel_white_sigma, truth_samples=self.truth_samples)

    # ---- running --------------------------------------------------------------------------
    def initial_state(self) -> ImuState:
        return self.sim.initial_state()

    def close(self) -> None:
        """Stop the simulator's worker thread (:meth:`ImuSimulator.close`)."""
        self.sim.close()

    def block(self, state: ImuState, b: int, trace, motion) -> tuple[dict, ImuState]:
        """Rows ``{group: {dim: {variable: array}}}`` of block ``b``; ``motion`` the run's
        :class:`rlgsim.sim.motion.kinematics.Motion` (the stage's own when None)."""
        if self.sim.motion is None:                 # first block: adopt the run's kinematics
            from rlgsim.sim.motion.kinematics import Motion
            if motion is None and self.trajectory is not None:
                motion = self.trajectory.build(float(self.timeline.duration_s))
            self.sim.motion = (motion if motion is not None
                               else Motion(self.turntable_segments, self.scenario.site))
        return self.sim.block(state, b, trace)


def dataset_motion(dataset):
    """The run's turntable kinematics (:class:`rlgsim.sim.motion.kinematics.Motion`) rebuilt
    from a dataset's timeline (turntable track) and site. ``dataset``: an open
    :class:`h5py.File` of a run."""
    from rlgsim.sim.motion.site import Site
    from rlgsim.sim.motion.kinematics import Motion, TurntableSegment

    def text(v):
        return v.decode() if isinstance(v, bytes) else str(v)
    tl = dataset["timeline"]
    details = tl["details"] if "details" in tl else tl["attrs"]      # format version 1: attrs
    segs = [TurntableSegment(float(a), float(b), "turntable", text(lab), json.loads(text(at)))
            for a, b, tr, lab, at in zip(tl["t0"][...], tl["t1"][...], tl["track"][...],
                                         tl["label"][...], details[...])
            if text(tr) == "turntable"]
    site = Site(float(dataset.attrs["latitude_deg"]), float(dataset.attrs["height_m"]))
    return Motion(segs, site)


def true_increments(dataset, t0_s: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample true (Δθ (n, 3) [rad], Δv (n, 3) [m/s]) of ``n`` samples from ``t0_s``,
    recomputed from a dataset's timeline (turntable track) and site — bit for bit what the run
    used (:class:`rlgsim.sim.motion.kinematics.Motion`). ``dataset``: an open :class:`h5py.File` of a run."""
    mb = dataset_motion(dataset).increments(t0_s, n, float(dataset.attrs["sample_rate_hz"]))
    return mb.dtheta_rad, mb.dv_m_per_s
