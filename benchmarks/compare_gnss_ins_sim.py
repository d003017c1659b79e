"""rlgsim against gnss-ins-sim on the same static high-accuracy IMU run (issue 16: ≥ 100×).

gnss-ins-sim (Aceinna, MIT licence; https://github.com/Aceinna/gnss-ins-sim) is the usual
open-source IMU data generator in Python. Both simulators produce the same thing here: a
static six-axis IMU (three gyros, three accelerometers) at 100 Hz for ``--hours`` (default
1 h), with a high-accuracy error model:

* gnss-ins-sim: ``imu_model.IMU(accuracy="high-accuracy", axis=6, gps=False)`` (its built-in
  navigation-grade model: bias, bias instability with a Gauss–Markov correlation time, angle
  and velocity random walk), a motion definition with one static command of the duration
  (latitude 34°, level), ``ins_sim.Sim([100, 0, 0], …).run(1)``: the reference trajectory and
  the sensor outputs, in memory; ``sim.results(folder)`` then writes its CSV files (timed
  apart: "with its output files").
* rlgsim: the RLG-IMU device ``rlg_imu_000`` (its full model: thermal network with the
  IMU's heat sources, probes, temperature laws, flicker and random-walk noise, UHFO, pulse
  counting, truth groups) in a chamber held at 20 °C on a static turntable at the same
  latitude, written to an HDF5 dataset — the whole ``simulate()`` call, setup included.

The like-for-like figure (the one issue 16's target is read against) is **with output files**:
gnss-ins-sim's run plus ``sim.results()`` writing its files, against our run, which always
writes its dataset. The in-memory figure (its run alone, ours still writing) is printed too,
as the ratio least favourable to rlgsim.

gnss-ins-sim is never copied into this repository: give its source folder with
``--gnss-ins-sim PATH`` (or the environment variable ``GNSS_INS_SIM``), e.g. a clone in a
temporary folder, or have it installed (``pip install`` from that clone into a virtual
environment; it needs only numpy and matplotlib). It runs in a subprocess. When it cannot be
found or fails, the script says why in one line and exits with status 1.

Prints both wall times, samples per second and the ratio beside the target (≥ 100), with the
machine line and the load average. Usage: ``python benchmarks/compare_gnss_ins_sim.py
[--gnss-ins-sim PATH] [--hours H] [--rounds N]``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _machine import machine  # noqa: E402

#: issue 16: rlgsim at least this many times faster on the same machine
TARGET = 100.0
RATE_HZ = 100.0
LATITUDE_DEG = 34.0

#: run in the subprocess: one static high-accuracy gnss-ins-sim run, timed; one JSON line
GIS_DRIVER = r"""
import json, os, sys, tempfile, time, io, contextlib
seconds, rate, lat = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
from gnss_ins_sim.sim import imu_model, ins_sim
tmp = tempfile.mkdtemp(prefix="gnss-ins-sim-")
motion = os.path.join(tmp, "static.csv")
with open(motion, "w") as fh:
    fh.write("ini lat (deg),ini lon (deg),ini alt (m),ini vx_body (m/s),ini vy_body (m/s),"
             "ini vz_body (m/s),ini yaw (deg),ini pitch (deg),ini roll (deg)\n"
             f"{lat},120,0,0,0,0,0,0,0\n"
             "command type,yaw (deg),pitch (deg),roll (deg),vx_body (m/s),vy_body (m/s),"
             "vz_body (m/s),command duration (s),GPS visibility\n"
             f"1,0,0,0,0,0,0,{seconds},0\n")
imu = imu_model.IMU(accuracy="high-accuracy", axis=6, gps=False)
quiet = io.StringIO()
with contextlib.redirect_stdout(quiet):
    sim = ins_sim.Sim([rate, 0.0, 0.0], motion, ref_frame=1, imu=imu, mode=None, env=None,
                      algorithm=None)
    t0, c0 = time.perf_counter(), time.process_time()
    sim.run(1)
    run, run_cpu = time.perf_counter() - t0, time.process_time() - c0
    t0 = time.perf_counter()
    sim.results(os.path.join(tmp, "out"))
    files = time.perf_counter() - t0
n = len(sim.dmgr.get_data_all("gyro").data[0])
import shutil
shutil.rmtree(tmp, ignore_errors=True)
print(json.dumps({"run": run, "run_cpu": run_cpu, "files": files, "samples": n,
                  "module": sys.modules["gnss_ins_sim"].__file__}))
"""


def scenario_text(hours: float) -> str:
    """A static run of the RLG-IMU at 20 °C (no turntable table: the table stays still)."""
    return f"""
name = "static_high_accuracy"
description = "RLG-IMU static at 20 °C, 100 Hz (comparison with gnss-ins-sim)"
device = "rlg_imu_000"
seed = 16
duration_h = {hours}

[site]
latitude_deg = {LATITUDE_DEG}
height_m = 0.0

[acquisition]
sample_rate_hz = {RATE_HZ:g}
thermal_step_s = 1

[power]
on_at_s = 0

[chamber]
start_c = 20.0

[[chamber.segments]]
type = "hold"
duration_h = {hours}
"""


def find_gnss_ins_sim(given: str | None) -> tuple[dict, str]:
    """(environment for the subprocess, where it was found) or SystemExit with the reason."""
    env = dict(os.environ)
    path = given or os.environ.get("GNSS_INS_SIM")
    if path:
        p = pathlib.Path(path).expanduser().resolve()
        if not (p / "gnss_ins_sim" / "__init__.py").is_file():
            raise SystemExit(f"gnss-ins-sim: {p} is not its source folder (no "
                             f"gnss_ins_sim/__init__.py there)")
        env["PYTHONPATH"] = os.pathsep.join([str(p), env.get("PYTHONPATH", "")]).rstrip(
            os.pathsep)
        return env, str(p)
    probe = subprocess.run([sys.executable, "-c", "import gnss_ins_sim"], env=env,
                           capture_output=True, text=True)
    if probe.returncode != 0:
        raise SystemExit("gnss-ins-sim is not available here: give its source folder with "
                         "--gnss-ins-sim PATH (a clone of github.com/Aceinna/gnss-ins-sim "
                         "outside this repository) or install it into this environment")
    return env, "installed package"


def time_rlgsim(hours: float) -> dict:
    from rlgsim.sim.run.scenario import parse_scenario
    from rlgsim.sim.run.simulate import simulate
    tmp = tempfile.mkdtemp(prefix="rlgsim-gis-")
    out = pathlib.Path(tmp) / "static.h5"
    t0, c0 = time.perf_counter(), time.process_time()
    sc = parse_scenario(scenario_text(hours), "static_high_accuracy.toml")
    simulate(sc, out, progress=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    size = out.stat().st_size
    out.unlink()
    os.rmdir(tmp)
    return {"wall": wall, "cpu": cpu, "samples": int(round(sc.duration_s * RATE_HZ)),
            "bytes": size}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gnss-ins-sim", default=None, help="gnss-ins-sim source folder")
    ap.add_argument("--hours", type=float, default=1.0, help="simulated hours (default 1)")
    ap.add_argument("--rounds", type=int, default=3, help="rlgsim runs (median)")
    args = ap.parse_args(argv)
    try:
        env, where = find_gnss_ins_sim(args.gnss_ins_sim)
    except SystemExit as exc:
        print(exc, file=sys.stderr)
        return 1
    seconds = args.hours * 3600.0
    print(f"machine: {machine()}")
    print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    ours = [time_rlgsim(args.hours) for _ in range(max(1, args.rounds))]
    proc = subprocess.run([sys.executable, "-c", GIS_DRIVER, repr(seconds), repr(RATE_HZ),
                           repr(LATITUDE_DEG)], env=env, capture_output=True, text=True,
                          cwd=tempfile.gettempdir())
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
        print(f"gnss-ins-sim ({where}) failed here: {tail}", file=sys.stderr)
        return 1
    gis = json.loads(proc.stdout.strip().splitlines()[-1])
    ours += [time_rlgsim(args.hours) for _ in range(max(1, args.rounds))]
    wall = statistics.median(r["wall"] for r in ours)
    n = ours[0]["samples"]
    print(f"scenario: static, level, latitude {LATITUDE_DEG:g}°, {args.hours:g} h at "
          f"{RATE_HZ:g} Hz = {n:,} samples of 3 gyros + 3 accelerometers")
    print(f"gnss-ins-sim ({gis['module']}): high-accuracy IMU model, {gis['samples']:,} "
          f"samples: run {gis['run']:.2f} s ({gis['samples'] / gis['run']:,.0f} samples/s); "
          f"writing its CSV files {gis['files']:.2f} s more")
    print(f"rlgsim: rlg_imu_000 with its thermal network, probes, UHFO, pulses and truth, "
          f"written to HDF5 ({ours[0]['bytes'] / 1e6:.1f} MB): median {wall:.3f} s of "
          f"{len(ours)} runs around it ({n / wall / 1e6:.2f} million samples/s)")
    print(f"rlgsim / gnss-ins-sim, like for like (both write their output files: its CSV, "
          f"our HDF5): {(gis['run'] + gis['files']) / wall:.0f}×  (target >= {TARGET:.0f}×)")
    print(f"rlgsim / gnss-ins-sim against its in-memory run (it writes nothing, we still "
          f"write the dataset): {gis['run'] / wall:.0f}×")
    cpu = statistics.median(r["cpu"] for r in ours)
    print(f"CPU seconds (steadier on a shared machine): gnss-ins-sim run {gis['run_cpu']:.2f} s, "
          f"rlgsim {cpu:.3f} s (all its threads): {gis['run_cpu'] / cpu:.0f}×")
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
