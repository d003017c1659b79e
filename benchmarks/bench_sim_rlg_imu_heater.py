"""What the IMU's temperature control costs the simulator: paper000_ramp with and without it.

The paper-000 thermal preset ``rlg_imu`` carries the IMU's own temperature control (a heater
with a PI controller and a power limit, ``[thermal.heaters.thermostat]``; docs/thermal.md §4.3).
Its clip makes the network nonlinear at the grid points, so the thermal part runs step by step
instead of in vectorised blocks (docs/thermal.md §1.2b). This runs the ``benchmarks/bench_sim.py``
workload — paper000_ramp at 100 Hz written to HDF5 (120.7 h, 43.4 million epochs) — twice in one
process, in alternating order: as shipped, and as before the heater — the same preset minus its
heater table (the network linear and exact in blocks) on the 1 s thermal grid the paper-000
scenarios had (they now run a 5 s grid, which keeps the controller's cost; the loop's
time constants are tens of minutes) — in ``--repeat`` (default 5) pairs whose order
alternates, and prints the median and spread of the epochs/s of
both and of their ratio per pair beside the target (the issue: throughput no more than 20 % below), the
machine and the load average before and after (a verdict only with ≥ 5 pairs and the others'
load at most 1.5 on 2 cores: ``benchmarks/_machine.py``). ``--hours`` cuts the programme (the ratio is the figure; the
absolute rate is bench_sim.py's).

Usage: ``python benchmarks/bench_sim_rlg_imu_heater.py [--hours H] [--repeat N]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import statistics
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import MIN_PAIRS, LoadWatch, alternate, load_text, machine, spread  # noqa: E402
from rlgsim.sim import presets  # noqa: E402
from rlgsim.sim.run.scenario import parse_scenario  # noqa: E402
from rlgsim.sim.run.simulate import simulate  # noqa: E402

TARGET_RATIO = 0.8
#: the paper-000 scenarios' thermal step before the heater (now 5 s: docs/thermal.md §4.3)
BEFORE_STEP_S = 1.0


def without_heater(text: str) -> str:
    """The thermal preset's text without its ``[thermal.heaters.*]`` tables."""
    out = re.sub(r"\n\[thermal\.heaters\.[^\]]+\]\n(?:[^\[\n].*\n|\n)*?(?=\n?\[)", "\n", text)
    if "[thermal.heaters" in out:
        raise SystemExit("could not remove the heater table")
    return out


def scenarios(tmp: pathlib.Path, hours: float | None) -> dict[str, object]:
    thermal = presets.load_thermal_file("rlg_imu").text
    device = presets.load_device_file("rlg_imu_000").text
    (tmp / "rlg_imu_noheater.toml").write_text(without_heater(thermal))
    (tmp / "dev.toml").write_text(device.replace('thermal_preset = "rlg_imu"',
                                                 'thermal_preset = "rlg_imu_noheater.toml"'))
    base = presets.load_scenario_file("paper000_ramp").text
    if hours is not None:
        base = f"duration_h = {hours}\n" + base
    out = {"shipped (heater, 5 s)": parse_scenario(base, "paper000_ramp.toml")}
    alt = base.replace('device = "rlg_imu_000"', f'device = "{tmp / "dev.toml"}"')
    alt = re.sub(r"thermal_step_s\s*=\s*[\d.]+", f"thermal_step_s = {BEFORE_STEP_S:g}", alt)
    out["before (no heater, 1 s)"] = parse_scenario(alt, str(tmp / "paper000_ramp.toml"))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=None)
    ap.add_argument("--repeat", type=int, default=MIN_PAIRS,
                    help=f"pairs, alternating which runs first (default {MIN_PAIRS}, the "
                         f"fewest for a verdict)")
    args = ap.parse_args()
    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="rlgsim-heater-bench-"))
    runs = scenarios(tmp, args.hours)
    shipped, before = "shipped (heater, 5 s)", "before (no heater, 1 s)"

    def timed(label: str):
        def go() -> float:
            path = tmp / "run.h5"
            t0 = time.perf_counter()
            simulate(runs[label], path, progress=False)
            wall = time.perf_counter() - t0
            path.unlink()
            return wall
        return go

    def report(i: int, w_s: float, w_b: float) -> None:
        watch.sample()
        print(f"  pair {i} ({'shipped' if i % 2 else 'before'} first): shipped {w_s:.2f} s, "
              f"before {w_b:.2f} s, ratio {w_b / w_s:.3f}; load {os.getloadavg()[0]:.2f}",
              flush=True)
    walls_s, walls_b = alternate(timed(shipped), timed(before), max(1, args.repeat), report)
    hours = next(iter(runs.values())).duration_s / 3600.0
    for label, walls in ((shipped, walls_s), (before, walls_b)):
        sc = runs[label]
        n = int(round(sc.duration_s * sc.acquisition.sample_rate_hz))
        print(f"paper000_ramp {hours:.1f} h, {label:<24}: {spread(walls, '.1f', ' s')} wall, "
              f"{spread([n / w / 1e6 for w in walls])} M epochs/s")
    ratios = [b / s for s, b in zip(walls_s, walls_b)]
    print(f"throughput with / without the heater: {spread(ratios, '.3f')} (target ≥ "
          f"{TARGET_RATIO:.2f}: {watch.verdict(statistics.median(ratios) >= TARGET_RATIO, len(ratios))})")
    print(watch.line())

if __name__ == "__main__":
    main()
