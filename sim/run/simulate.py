"""The streaming simulator: scenario → timeline → blocks of numerics → HDF5 dataset.

The run advances in blocks of fixed simulated length :data:`BLOCK_S` (600 s: a whole number of
thermal steps and of IMU samples, checked by the scenario loader). For block ``b``:

1. the *thermal* part samples the timeline (rate-limited chamber setpoint on the grid points,
   power state over each step) and propagates the thermal network exactly
   (:class:`rlgsim.sim.thermal.integrator.ThermalIntegrator`), giving a :class:`rlgsim.sim.stages.base.ThermalTrace`;
2. every *stage* (:data:`rlgsim.sim.stages.registry.STAGES`: probes, sensors, anomalies) turns
   the trace into its arrays: ``stage.block(state, b, trace, motion) -> (arrays, state)``.

Every carried state (thermal state, probe lags, later pulse remainders and noise-filter states)
goes from block to block, and every random draw of block ``b`` comes from
``rlgsim.sim.rng.generator(seed, unit, purpose, channel, b)``. Each block's rows go to a writer
thread (:class:`_Appender`) that appends them in block order while the next block is computed;
the user's ``chunk_s`` only bounds how many blocks may wait for it (memory stays bounded), so
the stored arrays — and the file — are the same whatever the chunk size.

The thermal part and the stages — where each model meets the dataset schema — live in
:mod:`rlgsim.sim.stages` (:mod:`~rlgsim.sim.stages.base` says how to add one,
:data:`rlgsim.sim.stages.registry.STAGES` lists them in order); this module is only the loop.
"""

from __future__ import annotations

import contextlib
import gc
import math
import pathlib
import threading
from typing import Callable, Iterator

import numpy as np

from rlgsim.sim.rng import BLOCK_S
from rlgsim.sim.run._heap import keep_freed_memory
from rlgsim.sim.run.schedule import build_timeline
from rlgsim.sim.stages.registry import STAGES
from rlgsim.sim.stages.thermal import ThermalPart
from rlgsim.sim.thermal.integrator import one_blas_thread
from rlgsim.sim.writer.dataset import DatasetWriter, GroupWriter, check_writable
from rlgsim.sim.writer.schema import write_timeline

__all__ = ["BLOCK_S", "STAGES", "default_output", "simulate"]


# --------------------------------------------------------------------------- the run


class _Appender:
    """Appends each block's rows to the dataset in a writer thread, in block order.

    The pulses' packing and, where h5py's wheel carries its own HDF5, the chunk writes (HDF5's
    ``H5Dwrite_chunk`` and its ``pwrite``) run in compiled code without the GIL
    (sim/writer/_scaleoffset_kernel.py, sim/writer/_chunk_calls.py), so the writes of block
    ``b`` overlap the arithmetic of block ``b + 1`` on another core; the appends' staging and
    h5py's other calls hold it. The thread makes
    exactly the calls the main thread would make, in the same order — one
    :meth:`GroupWriter.append` per block, group and dimension, in the order the stages
    produced them — so the file does not depend on the thread, nor on ``chunk_s``, which only
    bounds how many blocks may wait (``max_blocks``: memory stays flat in the duration). Before
    the first block the thread calls ``first`` (the file's deferred layout,
    :meth:`rlgsim.sim.writer.dataset.DatasetWriter.lay_out`, made while block 0 is computed). An
    error in the thread is raised in the main thread at the next :meth:`put` or at
    :meth:`close`."""

    def __init__(self, writers: dict[str, GroupWriter], max_blocks: int,
                 first: Callable[[], None] | None = None) -> None:
        import queue

        self._first = first                 # made in the thread before its first block
        self._writers = writers
        self._queue: "queue.Queue" = queue.Queue(maxsize=max(1, int(max_blocks)))
        self._error: BaseException | None = None
        self._cancelled = False
        self._thread = threading.Thread(target=self._run, name="rlgsim-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        if self._first is not None:
            try:
                self._first()
            except BaseException as exc:        # raised again in the main thread
                self._error = exc
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


def _root_attrs(scenario, timeline) -> dict:
    """The dataset's root attributes (docs/dataset.md "Root attributes"): what was run, with
    which seeds, on which grid and where."""
    step = timeline.step_s
    return {
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
    from rlgsim.sim.run.run_budget import check_motions
    from rlgsim.sim.run import run_to_run
    run_attrs = run_to_run.attrs(scenario)
    scenario = run_to_run.applied(scenario)   # this run's turn-on and lab (none without run_seed)
    check_motions(scenario)                 # before the timeline holds them all
    timeline = build_timeline(scenario)
    thermal = ThermalPart(scenario, timeline)
    stages = [s for s in (f(scenario, timeline) for f in STAGES) if s is not None]
    motion = None
    if any(getattr(s, "needs_motion", False) for s in stages):
        if getattr(scenario, "trajectory", None) is not None:     # a vehicle's route
            motion = scenario.trajectory.build(float(timeline.duration_s))
        else:
            from rlgsim.sim.motion.kinematics import Motion
            motion = Motion(timeline.segments, scenario.site)  # exact turntable kinematics

    attrs = {**_root_attrs(scenario, timeline), **run_attrs}
    # Each block's buffers reuse the previous block's pages (no page faults; sim/run/_heap.py).
    keep_freed_memory()
    with contextlib.ExitStack() as started:
        for s in stages:                    # work that needs no file (a vehicle's kinematics)
            if hasattr(s, "start"):         # begins now, while the file is laid out; stopped
                started.callback(s.close)   # by the stage's close() whatever happens
                s.start(motion)
        return _run(scenario, timeline, out, attrs, thermal, stages, motion, chunk,
                    progress, should_stop)


def _run(scenario, timeline, out: pathlib.Path, attrs: dict, thermal, stages: list,
         motion, chunk: float, progress: bool, should_stop: Callable[[], bool] | None
         ) -> pathlib.Path:
    """:func:`simulate`'s file and block loop (the stages made and started)."""
    step = timeline.step_s
    n_steps = timeline.n_steps
    per_block = int(round(BLOCK_S / step))
    n_blocks = math.ceil(n_steps / per_block)
    blocks_per_write = max(1, int(round(chunk / BLOCK_S)))
    from tqdm import tqdm

    from rlgsim.sim.run.run_budget import check_budget, row_bytes_of
    # declared here, the file made and laid out by the writer thread (DatasetWriter.lay_out)
    with DatasetWriter(out, attrs, defer_layout=True) as w:
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
        # a run shorter than one block fills only its length: the honest block; no file yet
        # (the writer thread makes it): the declared row bytes
        check_budget(scenario, out, n_steps=n_steps,
                     steps_per_block=min(per_block, n_steps),
                     buffered_blocks=blocks_per_write + 1,
                     block_s=min(BLOCK_S, n_steps * step),
                     progress=progress,    # refuse what cannot fit (run_budget)
                     row_bytes=row_bytes_of(w.groups))
        t_state = thermal.initial_state()
        s_states = [s.initial_state() for s in stages]
        bar = tqdm(total=round(n_steps * step), unit="s", unit_scale=True, disable=not progress,
                   delay=1.0, desc=f"rlgsim {scenario.name}", leave=False, dynamic_ncols=True)
        # The per-block matrices are small (tens of nodes × hundreds of steps): a threaded BLAS
        # only adds synchronisation (5× slower on a busy 2-core machine), so use one thread.
        appender = _Appender(writers, blocks_per_write, first=w.lay_out)
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
