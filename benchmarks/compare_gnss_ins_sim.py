"""rlgsim against gnss-ins-sim on the same static high-accuracy IMU run (issue 30: ≥ 200×).

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

What is timed, on both sides: the run and the writing of its files, never the imports.
gnss-ins-sim's timer starts after its imports and after ``ins_sim.Sim(…)`` has read the motion
definition and set up the IMU model; ours starts before the scenario text is parsed (the device
and thermal presets read and checked, the thermal network built) and stops when the dataset is
renamed into place. Before the pairs, one rlgsim run of the same scenario loads our imports —
numba and the compiled kernels from its cache included (the pulse counter, the normals, the
scale-offset packer: a process that has run anything long has them; a fresh process counting a
short run would use the NumPy paths instead, the same bytes, ~0.04 s more CPU per simulated
hour, and pay ~0.5 s once to load numba if asked to: ``sim/sensors/imu.py``
``COMPILED_MIN_EPOCHS``).

The two run in ``--pairs`` (default 5) alternated pairs (gnss-ins-sim first, then rlgsim first,
…) after that first rlgsim run; printed: each pair's ratio, the median and
spread of both wall times and of the ratios beside the target (≥ 200×), the machine line and
the load average before and after; a verdict only with ≥ 5 pairs and the others' load at most
1.5 on 2 cores (``benchmarks/_machine.py``). Usage: ``python
benchmarks/compare_gnss_ins_sim.py [--gnss-ins-sim PATH] [--hours H] [--pairs N]``.
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

from _machine import MIN_PAIRS, LoadWatch, alternate, load_text, machine, spread  # noqa: E402

#: issue 30: rlgsim at least this many times faster on the same machine (issue 16: 100)
TARGET = 200.0
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


def _counter_line() -> str:
    """Which pulse counter and normals our runs use here (compiled once numba is loaded)."""
    from rlgsim.sim.sensors.imu import ImuSimulator
    from rlgsim.sim.sensors._normal_kernel import available
    compiled = "numba" in sys.modules
    return (f"imports, numba and the compiled kernels loaded by a first run (outside the "
            f"pairs): pulse counter {'compiled' if compiled else 'NumPy'}, normals "
            f"{'compiled' if compiled and available() else 'NumPy'} "
            f"({ImuSimulator.__module__})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gnss-ins-sim", default=None, help="gnss-ins-sim source folder")
    ap.add_argument("--hours", type=float, default=1.0, help="simulated hours (default 1)")
    ap.add_argument("--pairs", type=int, default=MIN_PAIRS,
                    help=f"(gnss-ins-sim, rlgsim) pairs run in alternating order (default "
                         f"{MIN_PAIRS}, the fewest for a verdict)")
    args = ap.parse_args(argv)
    try:
        env, where = find_gnss_ins_sim(args.gnss_ins_sim)
    except SystemExit as exc:
        print(exc, file=sys.stderr)
        return 1
    seconds = args.hours * 3600.0
    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)

    def theirs() -> dict:
        proc = subprocess.run([sys.executable, "-c", GIS_DRIVER, repr(seconds), repr(RATE_HZ),
                               repr(LATITUDE_DEG)], env=env, capture_output=True, text=True,
                              cwd=tempfile.gettempdir())
        if proc.returncode != 0:
            tail = (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
            raise RuntimeError(f"gnss-ins-sim ({where}) failed here: {tail}")
        return json.loads(proc.stdout.strip().splitlines()[-1])

    def report(i: int, g: dict, o: dict) -> None:
        watch.sample()
        print(f"  pair {i} ({'gnss-ins-sim' if i % 2 else 'rlgsim'} first): gnss-ins-sim run "
              f"{g['run']:.2f} s + files {g['files']:.2f} s, rlgsim {o['wall']:.3f} s: "
              f"{(g['run'] + g['files']) / o['wall']:.0f}× like for like; load "
              f"{os.getloadavg()[0]:.2f}", flush=True)

    import numba  # noqa: F401 - imports and numba's compiled kernels, loaded outside the pairs
    time_rlgsim(args.hours)                     # by a first run of the same scenario
    print(f"rlgsim: {_counter_line()}", flush=True)
    try:
        gis, ours = alternate(theirs, lambda: time_rlgsim(args.hours), max(1, args.pairs),
                              report)
    except RuntimeError as exc:
        print(exc, file=sys.stderr)
        return 1
    n = ours[0]["samples"]
    like = [(g["run"] + g["files"]) / o["wall"] for g, o in zip(gis, ours)]
    mem = [g["run"] / o["wall"] for g, o in zip(gis, ours)]
    cpu = [g["run_cpu"] / o["cpu"] for g, o in zip(gis, ours)]
    print(f"scenario: static, level, latitude {LATITUDE_DEG:g}°, {args.hours:g} h at "
          f"{RATE_HZ:g} Hz = {n:,} samples of 3 gyros + 3 accelerometers")
    print(f"gnss-ins-sim ({gis[0]['module']}): high-accuracy IMU model, {gis[0]['samples']:,} "
          f"samples: run {spread([g['run'] for g in gis], unit=' s')}; writing its CSV files "
          f"{spread([g['files'] for g in gis], unit=' s')} more")
    walls = [o["wall"] for o in ours]
    print(f"rlgsim: rlg_imu_000 with its thermal network, probes, UHFO, pulses and truth, "
          f"written to HDF5 ({ours[0]['bytes'] / 1e6:.1f} MB): {spread(walls, '.3f', ' s')} "
          f"({n / statistics.median(walls) / 1e6:.2f} million samples/s)")
    print(f"rlgsim / gnss-ins-sim, like for like (both write their output files: its CSV, "
          f"our HDF5): {spread(like, '.0f', '×')}  (target >= {TARGET:.0f}×, issue 30: "
          f"{watch.verdict(statistics.median(like) >= TARGET, len(like))})")
    print(f"rlgsim / gnss-ins-sim against its in-memory run (it writes nothing, we still "
          f"write the dataset): {spread(mem, '.0f', '×')}")
    print(f"CPU seconds (steadier on a shared machine), gnss-ins-sim run / rlgsim (all its "
          f"threads): {spread(cpu, '.0f', '×')}")
    print(watch.line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
