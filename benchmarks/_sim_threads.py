"""Where a simulator run's CPU and waiting go, thread by thread (printed by
``bench_sim_trajectory.py`` unless ``--no-parts``).

A run (:func:`rlgsim.sim.run.simulate.simulate`) has up to five threads: the main thread (the
thermal part, the sensor equation and pulses), the IMU stage's worker drawing the white noise
(``rlgsim-imu``), a vehicle's two motion workers (increments with their step sums; truth rows:
``rlgsim-motion``) and the writer (``rlgsim-writer``: every group's rows into the HDF5 file).
On two cores its wall time is bounded below by its CPU over two and by its longest chain of
work that cannot overlap: the writer can only write a block the main thread has made, and the
main thread can only make one whose kinematics and normals are ready.

:class:`ThreadParts` wraps the functions each thread runs (the simulator's own, unchanged) and
adds up, per run, the CPU seconds of each (``time.thread_time`` inside the thread) and the
wall seconds the main thread waits for the workers (``Future.result``) and for the writer
(``Queue.put`` of a full queue), and the writer waits for work (``Queue.get``). The wrappers
cost a few microseconds per block (~100 calls a run). Written by hand: a profiler samples
functions, not the CPU clock of each thread with its waits, which is what the bound needs.
"""

from __future__ import annotations

import concurrent.futures
import functools
import queue
import statistics
import threading
import time
from collections import defaultdict

#: (label, module, class, method) of what each thread runs; "cpu" parts add thread CPU seconds
_CPU_PARTS = (
    ("writer", "rlgsim.sim.run.simulate", "_Appender", "_run"),
    ("writer: trajectory group", "rlgsim.sim.writer.dataset", "GroupWriter", "append"),
    ("normals", "rlgsim.sim.sensors.imu", "ImuSimulator", "_gyro_normals"),
    ("normals", "rlgsim.sim.sensors.imu", "ImuSimulator", "_accel_normals"),
    ("normals", "rlgsim.sim.sensors.imu", "ImuSimulator", "_drive_draws"),
    ("kinematics", "rlgsim.sim.sensors.imu", "ImuSimulator", "_kinematics_now"),
    ("kinematics: truth rows", "rlgsim.sim.sensors.imu", "ImuSimulator", "_truth_rows"),
    ("kinematics: increments", "rlgsim.sim.motion.trajectory", "Trajectory", "increments"),
)


class ThreadParts:
    """Per-run CPU and wait seconds of a simulator run's threads (module docstring); use as a
    context manager around the runs, calling :meth:`run` for each."""

    def __init__(self) -> None:
        self.runs: dict[str, list[dict[str, float]]] = defaultdict(list)
        self._now: dict[str, float] = defaultdict(float)
        self._lock = threading.Lock()
        self._undo: list[tuple[object, str, object]] = []

    def _add(self, key: str, seconds: float) -> None:
        with self._lock:
            self._now[key] += seconds

    def __enter__(self) -> "ThreadParts":
        import importlib
        for label, module, cls, name in _CPU_PARTS:
            owner = getattr(importlib.import_module(module), cls)
            self._wrap_cpu(owner, name, label)
        self._wrap_wait(concurrent.futures.Future, "result", "main waits for workers",
                        main=True)
        self._wrap_wait(queue.Queue, "put", "main waits for the writer", main=True)
        self._wrap_wait(queue.Queue, "get", "writer waits for blocks", main=False)
        return self

    def __exit__(self, *exc) -> None:
        for owner, name, f in reversed(self._undo):
            setattr(owner, name, f)
        self._undo.clear()

    def _wrap(self, owner, name: str, label: str, clock, applies) -> None:
        """Replace ``owner.name`` by a wrapper that adds the ``clock`` seconds of each call for
        which ``applies(self_)`` holds to ``label`` (restored by :meth:`__exit__`)."""
        f = getattr(owner, name)
        parts = self

        @functools.wraps(f)
        def g(self_, *a, **k):
            if not applies(self_):
                return f(self_, *a, **k)
            t0 = clock()
            try:
                return f(self_, *a, **k)
            finally:
                parts._add(label, clock() - t0)
        self._undo.append((owner, name, f))
        setattr(owner, name, g)

    def _wrap_cpu(self, owner, name: str, label: str) -> None:
        """The thread CPU seconds of ``owner.name`` (the trajectory group's appends only, for
        the writer's "trajectory group" part)."""
        group_only = label == "writer: trajectory group"
        self._wrap(owner, name, label, time.thread_time,
                   lambda w: not group_only or getattr(w, "name", "") == "trajectory")

    def _wrap_wait(self, owner, name: str, label: str, main: bool) -> None:
        """The wall seconds of ``owner.name`` called in the main thread (``main``) or in
        another one."""
        self._wrap(owner, name, label, time.perf_counter,
                   lambda _: (threading.current_thread() is threading.main_thread()) == main)

    def run(self, kind: str, call) -> object:
        """``call()`` (one run) with its parts kept under ``kind``; the main thread's CPU too."""
        self._now.clear()
        c0 = time.thread_time()
        try:
            return call()
        finally:
            self._add("main thread", time.thread_time() - c0)
            self.runs[kind].append(dict(self._now))

    def lines(self) -> list[str]:
        """One line per kind of run: the median seconds of each part over its runs."""
        out = []
        for kind, runs in self.runs.items():
            keys = sorted({k for r in runs for k in r}, key=_order)
            cells = [f"{k} {statistics.median(r.get(k, 0.0) for r in runs):.3f}" for k in keys]
            out.append(f"  {kind} ({len(runs)} runs, median s): " + "; ".join(cells))
        return out


def _order(key: str) -> tuple[int, str]:
    first = ("main thread", "normals", "kinematics", "writer", "main waits", "writer waits")
    for i, head in enumerate(first):
        if key.startswith(head):
            return i, key
    return len(first), key
