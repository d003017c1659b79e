"""The simulator's throughput on a vehicle's route beside a static run's (issue 26's target:
the trajectory run within 25 % of the static one, i.e. a throughput ratio >= 0.75).

Both runs are the RLG-IMU (rlg_imu_000: three gyros, three accelerometers, UHFO, probes, truth)
at 100 Hz for ``--hours`` (default 4) in a bay/chamber held at 20 °C, written to HDF5:

* static — the turntable at rest (the simulator's fastest path: every sample of a thermal step
  holds one increment);
* trajectory — the same, riding the shipped ``vehicle_land_cold`` route from its start (city
  driving: corners, stops, accelerations, then the motorway; 2 h, its segments repeated as
  often as ``--hours`` needs, so a longer run keeps the route's mix of driving and standing
  instead of parking after 2 h), its increments by the compiled kernels
  (sim/motion/_trajectory_block.py: Gauss–Legendre, the fitted quintic and Chebyshev chunks)
  and its ``trajectory`` truth group (13 float64 states per sample) written too.

**Throughput, not set-up.** A run has fixed costs apart from its epochs: laying out the file
(~70 datasets with their dimension scales and attributes), the memory check, closing the file
— and, on a vehicle, building the route (the positions' DOP853 integration and the range check
over every leg, once per run). At 1 h (0.1 s static) these were most of the static run, which
hid how the per-epoch costs compare; the default is therefore 4 h (1.44 M epochs). Each run is
timed whole, like for like: the same rate, duration, block and chunk layout and outputs; the
route is built afresh inside every timed trajectory run (a scenario's build is cached on the
scenario object, and a real ``rlgsim run`` pays it once); the previous run's output file is
deleted before the clock starts (replacing a 200 MB file costs the file system tens of ms that
belong to neither run).

Pairs alternate their order (static first, then trajectory first, …) so a changing load hits
both alike; the median ratio and its spread are printed beside the target (a verdict only with
≥ 5 pairs and the others' load at most 1.5 on 2 cores: ``benchmarks/_machine.py``), with the machine
line and the load average before and after. ``python benchmarks/bench_sim.py --trajectory``
runs it too.

**What bounds it** (``--floor``): the same pairs with the trajectory's kinematics free — the
route built beforehand and every block's increments, step sums and truth rows computed in a
first run and handed out again (the IMU stage's ``_kinematics_now`` and ``_truth_rows``
replaced by a look-up) — so what is left is what a vehicle costs beyond them: the
``trajectory`` group's 13 float64 a sample through the writer, and the sensor equation per
sample instead of per thermal step. Its ratio is the ceiling no faster kinematics can pass.
With ``--unwritten`` the ``trajectory`` group's rows are dropped before the writer too (its
datasets stay empty: a counterfactual, not a product) — what is left is the sensor equation per
sample and the route's build: the ceiling if a vehicle stored no truth states at the sample
rate.

**Where the time goes** (printed unless ``--no-parts``; not with ``--floor``): the same
pairs, each run's CPU seconds thread by thread (main, the normals worker, the motion workers'
increments and truth rows, the writer and its share for the ``trajectory`` group) and the wall
seconds the main thread waits for its workers and for the writer (benchmarks/_sim_threads.py) —
on two cores the wall time is at least the CPU over two and at least the writer's chain, which
starts with the first block.
The wrappers that count them cost a few microseconds per block (~100 calls a run of 0.2-0.4 s).

Usage: ``python benchmarks/bench_sim_trajectory.py [--hours H] [--repeat N] [--floor
[--unwritten]] [--no-parts]``.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import pathlib
import statistics
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import MIN_PAIRS, LoadWatch, alternate, load_text, machine, spread  # noqa: E402
from _sim_threads import ThreadParts  # noqa: E402

TARGET = 0.75
STATIC = """
name = "static"
device = "rlg_imu_000"
seed = 5
duration_h = {hours}
[acquisition]
sample_rate_hz = 100
[chamber]
start_c = 20.0
"""


ROUTE = "vehicle_land_cold"
ROUTE_HOURS = 2.0                      # the shipped route's length (its segments' durations)


def scenarios(hours: float):
    """(static, trajectory) scenarios of ``hours``: the trajectory the :data:`ROUTE`'s
    segments, repeated to cover ``hours``."""
    from rlgsim.sim import presets
    from rlgsim.sim.run.scenario import parse_scenario
    static = parse_scenario(STATIC.format(hours=hours), "static.toml")
    land = presets.load_scenario_file(ROUTE).text
    route = land[land.index("[trajectory]"):]
    first = route.index("[[trajectory.segment]]")
    repeat = max(1, math.ceil(hours / ROUTE_HOURS - 1e-9))
    moving = parse_scenario(STATIC.format(hours=hours) + route[:first] + route[first:] * repeat,
                            "trajectory.toml")
    return static, moving


def route_hours(sc) -> float:
    """Length [h] of a scenario's route (its segments, without the hold to the run's end)."""
    return sum(leg.duration_s for leg in sc.trajectory.legs) / 3600.0


CPU: dict[str, list[float]] = {"static": [], "trajectory": []}


def run_once(sc, out: pathlib.Path, kind: str = "") -> float:
    """Wall time [s] of one run (its CPU seconds, all threads, kept in :data:`CPU`): the
    previous output deleted first, a vehicle's route built inside the timed run."""
    from rlgsim.sim.run.simulate import simulate
    out.unlink(missing_ok=True)
    if getattr(sc, "trajectory", None) is not None:
        sc.trajectory.__dict__.pop("_built", None)      # build the route in this run
    t0, c0 = time.perf_counter(), time.process_time()
    simulate(sc, out, progress=False)
    if kind:
        CPU[kind].append(time.process_time() - c0)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=4.0,
                    help="simulated hours of each run (default 4: module docstring)")
    ap.add_argument("--repeat", type=int, default=MIN_PAIRS,
                    help=f"alternating pairs (default {MIN_PAIRS}, the fewest for a verdict)")
    ap.add_argument("--floor", action="store_true",
                    help="the trajectory's kinematics free: what bounds the ratio (docstring)")
    ap.add_argument("--unwritten", action="store_true",
                    help="with --floor: the trajectory group's rows not written either "
                         "(a counterfactual bound; docstring)")
    ap.add_argument("--no-parts", dest="parts", action="store_false",
                    help="leave out each thread's CPU and waits per run (printed by default, "
                         "not with --floor: benchmarks/_sim_threads.py; docstring)")
    args = ap.parse_args(argv)
    if args.unwritten and not args.floor:
        ap.error("--unwritten needs --floor")
    static, moving = scenarios(args.hours)
    epochs = int(round(static.duration_s * 100))
    with tempfile.TemporaryDirectory(prefix="rlgsim-bench-traj-") as name:   # ~0.4 GB at 4 h
        if args.floor:
            return _floor(args, static, moving, epochs, pathlib.Path(name))
        return _measure(args, static, moving, epochs, pathlib.Path(name))


def _floor(args, static, moving, epochs: int, tmp: pathlib.Path) -> int:
    """The pairs of :func:`_measure` with the vehicle's kinematics computed beforehand (module
    docstring: ``--floor``)."""
    from rlgsim.sim.run.simulate import simulate
    from rlgsim.sim.sensors.imu import ImuSimulator
    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    from rlgsim.sim.writer.dataset import GroupWriter
    kin, rows = ImuSimulator._kinematics_now, ImuSimulator._truth_rows
    append = GroupWriter.append
    made: dict = {}
    what = "free kinematics" + (", its rows unwritten" if args.unwritten else "")

    def unwritten(self, dim, arrays):       # --unwritten: the trajectory group's rows dropped
        if self.name != "trajectory":
            append(self, dim, arrays)

    def record(name, f):
        def g(self, *a):
            if self._is_vehicle():
                if (name, a) not in made:
                    made[name, a] = f(self, *a)
                return made[name, a]
            return f(self, *a)
        return g
    ImuSimulator._kinematics_now = record("k", kin)     # a first run fills ``made``; the
    ImuSimulator._truth_rows = record("t", rows)        # timed ones only look them up
    if args.unwritten:
        GroupWriter.append = unwritten
    try:
        simulate(moving, tmp / "warm.h5", progress=False)   # the route stays built (cached)
        run_once(static, tmp / "warm.h5")

        def timed(sc, out, kind):
            out.unlink(missing_ok=True)
            t0, c0 = time.perf_counter(), time.process_time()
            simulate(sc, out, progress=False)
            CPU[kind].append(time.process_time() - c0)
            return time.perf_counter() - t0

        def report(i: int, s: float, m: float) -> None:
            print(f"  pair {i}: static {s:.2f} s, trajectory with {what} {m:.2f} s, "
                  f"ratio {s / m:.2f}; CPU {CPU['static'][-1]:.2f} / "
                  f"{CPU['trajectory'][-1]:.2f} s; load {load_text()}", flush=True)
            watch.sample()
        ws, wm = alternate(lambda: timed(static, tmp / "s.h5", "static"),
                           lambda: timed(moving, tmp / "m.h5", "trajectory"),
                           max(1, args.repeat), report)
    finally:
        ImuSimulator._kinematics_now, ImuSimulator._truth_rows = kin, rows
        GroupWriter.append = append
    ratios = [s / m for s, m in zip(ws, wm)]
    cpu = [s / m for s, m in zip(CPU["static"], CPU["trajectory"])]
    print(f"{args.hours:g} h at 100 Hz = {epochs:,} epochs; static {spread(ws, unit=' s')}, "
          f"trajectory with {what} {spread(wm, unit=' s')}")
    print(f"ceiling of the trajectory / static throughput ({what}): {spread(ratios)} "
          f"(target >= {TARGET:.2f}: {watch.verdict(statistics.median(ratios) >= TARGET, len(ratios))}); "
          f"CPU: static {spread(CPU['static'], unit=' s')}, trajectory "
          f"{spread(CPU['trajectory'], unit=' s')}, ratio {spread(cpu)}")
    print(watch.line())
    return 0


def _measure(args, static, moving, epochs: int, tmp: pathlib.Path) -> int:
    """The pairs of :func:`main`, written into ``tmp`` (deleted afterwards)."""
    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    run_once(static, tmp / "warm.h5")          # imports, numba caches: outside the pairs
    run_once(moving, tmp / "warm.h5")

    def report(i: int, s: float, m: float) -> None:
        print(f"  pair {i}: static {s:.2f} s ({epochs / s / 1e6:.2f} M epochs/s), trajectory "
              f"{m:.2f} s ({epochs / m / 1e6:.2f} M epochs/s), ratio {s / m:.2f}; CPU "
              f"{CPU['static'][-1]:.2f} / {CPU['trajectory'][-1]:.2f} s; load {load_text()}",
              flush=True)
        watch.sample()
    with contextlib.ExitStack() as stack:
        parts = stack.enter_context(ThreadParts()) if args.parts else None
        ws, wm = alternate(lambda: _timed(parts, "static", static, tmp / "s.h5"),
                           lambda: _timed(parts, "trajectory", moving, tmp / "m.h5"),
                           max(1, args.repeat), report)
    ratios = [s / m for s, m in zip(ws, wm)]
    print(f"{args.hours:g} h at 100 Hz = {epochs:,} epochs (the route: {route_hours(moving):g} h "
          f"of segments); static {spread(ws, unit=' s')}, trajectory {spread(wm, unit=' s')}")
    print(f"trajectory / static throughput: {spread(ratios)}  (target >= {TARGET:.2f}: "
          f"{watch.verdict(statistics.median(ratios) >= TARGET, len(ratios))})")
    cpu = [s / m for s, m in zip(CPU["static"], CPU["trajectory"])]
    print(f"CPU seconds (all threads): static {spread(CPU['static'], unit=' s')}, trajectory "
          f"{spread(CPU['trajectory'], unit=' s')}; ratio {spread(cpu)} (less sensitive to "
          f"others' load than the wall clock; on an idle 2-core machine the wall-clock ratio "
          f"can differ, the simulator's worker threads overlapping its main thread)")
    if parts is not None:
        print("CPU seconds by thread and wall seconds waiting (benchmarks/_sim_threads.py; "
              "'kinematics' is the main thread's own on a static run):")
        print("\n".join(parts.lines()))
    print(watch.line())
    return 0


def _timed(parts, kind: str, sc, out: pathlib.Path) -> float:
    """:func:`run_once`, its threads' parts kept when ``parts`` (not ``--no-parts``)."""
    if parts is None:
        return run_once(sc, out, kind)
    return parts.run(kind, lambda: run_once(sc, out, kind))


if __name__ == "__main__":
    raise SystemExit(main())
