"""Thermal benchmark: the full paper-000 chamber programme (-5 °C for 4 h, then to 65 °C over
7000 min: 124.7 h) at a 1 s thermal step, every probe, streamed to HDF5.

Prints the machine, the median and spread of the wall time of ``--repeat`` runs (default 5) and
simulated time / wall time, and the load average before and after. Target: under 5 s on a
2-core machine (a verdict only with ≥ 5 runs and the others' load at most 1.5 on 2 cores:
``benchmarks/_machine.py``). ``python benchmarks/bench_thermal.py [SCENARIO] [--repeat N]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _machine import MIN_PAIRS, LoadWatch, load_text, machine, spread  # noqa: E402


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="paper000_ramp")
    p.add_argument("--repeat", type=int, default=MIN_PAIRS,
                   help=f"runs; their median and spread are reported (default {MIN_PAIRS}, "
                        f"the fewest for a verdict)")
    p.add_argument("--all-stages", action="store_true",
                   help="also run the sensor stages (default: thermal + probes only)")
    args = p.parse_args(argv)

    import h5py
    import rlgsim.sim.run.simulate
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    from rlgsim.sim.stages.probes import ProbeStage

    if not args.all_stages:            # the thermal benchmark: chamber, network, probes
        rlgsim.sim.run.simulate.STAGES = [ProbeStage.create]

    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    t0 = time.perf_counter()
    scenario = load_scenario(args.scenario)
    load_s = time.perf_counter() - t0
    net = scenario.device.thermal.network
    probes = scenario.device.thermal.probes
    print(f"scenario: {scenario.name} ({scenario.duration_s / 3600:.2f} h simulated, thermal step "
          f"{scenario.acquisition.thermal_step_s:g} s, "
          f"{0 if net is None else len(net.node_names)} nodes, "
          f"{0 if probes is None else len(probes.names)} probes); load {load_s:.3f} s")
    walls, cpus = [], []
    print(f"stages: {'all' if args.all_stages else 'thermal + probes'}")
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "bench.h5"
        for _ in range(max(1, args.repeat)):
            t0, c0 = time.perf_counter(), time.process_time()
            simulate(scenario, out, progress=False)
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
            watch.sample()
        size = out.stat().st_size
        with h5py.File(out) as f:
            steps = f["thermal/time"].shape[0]
    med = statistics.median(walls)
    print(f"wall time: {spread(walls, unit=' s')}")
    print(f"simulated time / wall time: {scenario.duration_s / med:,.0f} (median)")
    print(f"CPU time of the process: {spread(cpus, unit=' s')} (wall > CPU means waiting: disk "
          f"or other load)")
    print(f"thermal steps: {steps:,} ({steps / med:,.0f} steps/s); file {size / 2**20:.1f} MiB")
    print(f"target < 5 s (median): {watch.verdict(med < 5.0, len(walls))}")
    print(watch.line())

if __name__ == "__main__":
    main(sys.argv[1:])
