"""Speed and accuracy of the navigator (rlgsim.estimators.ins), and gnss-ins-sim's free
integration on the same increments (issue 25).

1. **Speed**: an 8 h, 100 Hz run (2.88 M samples) of the paper-000 turntable programme's exact
   increments through :func:`rlgsim.estimators.ins.integrate` (1 Hz output), timed over
   ``--rounds`` runs: median and spread, samples/s beside the target (≥ 10 M samples/s, i.e.
   < 0.3 s), the machine and the load average before and after.
2. **gnss-ins-sim** (Aceinna, MIT; https://github.com/Aceinna/gnss-ins-sim): its demo
   algorithm ``demo_algorithms/free_integration.py`` (``FreeIntegration``, ref_frame 0: NED,
   latitude/longitude/altitude) on the same exact increments given as rates (Δθ/Δt, Δv/Δt),
   run in a subprocess from its source folder (``--gnss-ins-sim PATH`` or the environment
   variable ``GNSS_INS_SIM``; never copied into this repository). Its speed is measured on
   ``--gis-minutes`` of the data (a per-sample Python loop; ``--pairs`` alternated pairs with
   ours on the same samples) and the ratio of samples/s printed.
3. **Accuracy**, both navigators on exact increments (the error is the algorithm's own):
   static 1 h, a level IMU spinning in azimuth at 10 °/s for 1 h, and the 19-position
   sequence (40 min). Ours with the height held and with the vertical channel free (gnss-ins-
   sim's is always free), horizontal error at the end and the largest attitude error.

Usage: ``python benchmarks/bench_navigate.py [--gnss-ins-sim PATH] [--rounds N]
[--gis-minutes M]``. Without gnss-ins-sim parts 2–3 say why in one line and part 1 still runs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import LoadWatch, alternate, machine, spread  # noqa: E402

from rlgsim.estimators.ins import InsState, attitude_error, integrate  # noqa: E402
from rlgsim.ground.earth import radii_of_curvature  # noqa: E402
from rlgsim.ground.units import DEG  # noqa: E402
from rlgsim.sim.motion.kinematics import Motion, segments_from_program  # noqa: E402
from rlgsim.sim.motion.site import Site  # noqa: E402
from rlgsim.sim.motion.turntable import Spin, TurntableProgram  # noqa: E402

TARGET_SAMPLES_PER_S = 10e6
RATE_HZ = 100.0
LAT = 34.0
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

GIS_DRIVER = r"""
import json, sys, time
import numpy as np
src, folder, lat, fs, every = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
sys.path.insert(0, src)
from demo_algorithms.free_integration import FreeIntegration
from gnss_ins_sim.attitude import attitude
d = np.load(folder + "/in.npz")
ini = np.zeros(9)
ini[0] = np.radians(lat)
ini[6:9] = attitude.dcm2euler(d["c_b_ned"].T)     # its DCM maps n -> b
alg = FreeIntegration(ini)
t0 = time.perf_counter()
alg.run([0, fs, d["gyro"], d["accel"]])
el = time.perf_counter() - t0
att, pos, vel = alg.get_results()
c = np.array([attitude.euler2dcm(a).T for a in att[::every]])   # b -> NED
np.savez(folder + "/out.npz", c=c, pos=pos[::every], vel=vel[::every])
print(json.dumps({"seconds": el, "n": int(d["gyro"].shape[0])}))
"""


def increments(kind: str, seconds: float):
    """Exact Δθ, Δv (n, 3) and the true attitude function of one motion case."""
    site = Site(LAT, 0.0)
    if kind == "static":
        prog = TurntableProgram.static(0.0, 30.0)
    elif kind == "spin":
        prog = TurntableProgram((Spin("inner", 10.0, seconds + 10.0, "spin"),), name="spin")
    else:
        prog = TurntableProgram.calibration19(rate_deg_s=20.0)
    motion = Motion(segments_from_program(prog, seconds + 10.0), site)
    blk = motion.increments(0.0, int(round(seconds * RATE_HZ)), RATE_HZ, angles=False)
    return blk.dtheta_rad, blk.dv_m_per_s, motion


def ours(dth, dv, motion, free: bool, every: int):
    c0 = motion.attitude(np.array([0.0]))[0]
    sol = integrate(InsState.at_rest(c0, LAT), dth, dv, 1.0 / RATE_HZ,
                    height=None if free else "initial", output_every=every)
    r_m, r_e = radii_of_curvature(LAT)
    horiz = np.hypot((sol.lat - LAT * DEG) * r_m, sol.lon * r_e * math.cos(LAT * DEG))
    att = np.abs(attitude_error(sol.attitude(), motion.attitude(sol.t_s))).max()
    return float(horiz[-1]), float(att), float(sol.h[-1])


def theirs(src: str, dth, dv, motion, every: int) -> tuple[dict, tuple | None]:
    with tempfile.TemporaryDirectory(prefix="bench-nav-") as tmp:
        c0 = motion.attitude(np.array([0.0]))[0]
        np.savez(f"{tmp}/in.npz", gyro=dth * RATE_HZ, accel=dv * RATE_HZ, c_b_ned=ENU_TO_NED @ c0)
        r = subprocess.run([sys.executable, "-c", GIS_DRIVER, src, tmp, str(LAT), str(RATE_HZ),
                            str(every)], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(r.stderr.strip().splitlines()[-1] if r.stderr else "failed")
        info = json.loads(r.stdout.strip().splitlines()[-1])
        out = np.load(f"{tmp}/out.npz")
        # its output i is the state after samples 0..i-1: time i/f
        t = np.arange(out["pos"].shape[0]) * every / RATE_HZ
        keep = t > 0
        r_m, r_e = radii_of_curvature(LAT)
        pos = out["pos"][keep]
        horiz = np.hypot((pos[:, 0] - LAT * DEG) * r_m, pos[:, 1] * r_e * math.cos(LAT * DEG))
        c_enu = ENU_TO_NED.T @ out["c"][keep]
        att = np.abs(attitude_error(c_enu, motion.attitude(t[keep])))
        att = float(np.nanmax(att)) if np.isfinite(att).all() else float("nan")
        return info, (float(horiz[-1]), att, float(pos[-1, 2]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gnss-ins-sim", default=os.environ.get("GNSS_INS_SIM"), metavar="PATH")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--gis-minutes", type=float, default=2.0)
    ap.add_argument("--pairs", type=int, default=5)
    args = ap.parse_args()
    print(f"machine: {machine()}")
    watch = LoadWatch()
    dth, dv, motion = increments("calib", 8 * 3600.0)
    c0 = motion.attitude(np.array([0.0]))[0]
    start = InsState.at_rest(c0, LAT)
    integrate(start, dth[:100], dv[:100], 1 / RATE_HZ)                  # compile / load cache
    n = dth.shape[0]
    times, cpu = [], []
    for _ in range(args.rounds):
        t0, c0_ = time.perf_counter(), time.process_time()
        integrate(start, dth, dv, 1 / RATE_HZ, output_every=int(RATE_HZ))
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0_)
        watch.sample()
    med, med_cpu = statistics.median(times), statistics.median(cpu)
    print(f"navigate 8 h at 100 Hz ({n} samples), wall: {spread(times, '.3f', ' s')} = "
          f"{n / med / 1e6:.1f} M samples/s; CPU: {spread(cpu, '.3f', ' s')} = "
          f"{n / med_cpu / 1e6:.1f} M samples/s (target >= {TARGET_SAMPLES_PER_S / 1e6:.0f} "
          f"M samples/s, i.e. < 0.3 s): wall {watch.verdict(med < 0.3, len(times))}")
    print(watch.line())
    src = args.gnss_ins_sim
    if not src or not (pathlib.Path(src) / "demo_algorithms" / "free_integration.py").is_file():
        print("gnss-ins-sim: not found (give --gnss-ins-sim PATH to its source folder); "
              "comparison skipped")
        return 0
    m = int(args.gis_minutes * 60 * RATE_HZ)
    watch.start()

    def run_ours() -> float:
        t0 = time.perf_counter()
        integrate(start, dth[:m], dv[:m], 1 / RATE_HZ, output_every=int(RATE_HZ))
        return m / (time.perf_counter() - t0)

    def run_theirs() -> float:
        info, _ = theirs(src, dth[:m], dv[:m], motion, int(RATE_HZ))
        return info["n"] / info["seconds"]

    r_ours, r_gis = alternate(run_ours, run_theirs, args.pairs,
                              lambda i, a, b: watch.sample())
    ratio = [a / b for a, b in zip(r_ours, r_gis)]
    print(f"same {m} samples ({args.gis_minutes:g} min of the 19-position sequence), "
          f"{args.pairs} alternated pairs: ours {spread([r / 1e6 for r in r_ours], '.2f', ' M/s')}"
          f"; gnss-ins-sim free integration {spread([r / 1e3 for r in r_gis], '.2f', ' k/s')}; "
          f"ratio {spread(ratio, '.0f', 'x')}")
    print(watch.line())
    print("accuracy on exact increments (horizontal error at the end [m], largest attitude "
          "error [arcsec], final height [m]):")
    for kind, secs in (("static", 3600.0), ("spin", 3600.0), ("calib", 2400.0)):
        d1, d2, mo = increments(kind, secs)
        held = ours(d1, d2, mo, False, int(RATE_HZ))
        free = ours(d1, d2, mo, True, int(RATE_HZ))
        try:
            _, gis = theirs(src, d1, d2, mo, int(RATE_HZ))
        except RuntimeError as exc:
            gis = None
            print(f"  gnss-ins-sim failed on {kind}: {exc}")
        label = {"static": "static 1 h", "spin": "azimuth spin 10 deg/s, 1 h",
                 "calib": "19-position sequence, 40 min"}[kind]
        row = [f"ours (height held) {held[0]:.3g} m, {held[1] / (DEG / 3600):.3g}\"",
               f"ours (free) {free[0]:.3g} m, {free[1] / (DEG / 3600):.3g}\", h {free[2]:.3g} m"]
        if gis:
            row.append(f"gnss-ins-sim {gis[0]:.3g} m, {gis[1] / (DEG / 3600):.3g}\", "
                       f"h {gis[2]:.3g} m")
        print(f"  {label}: " + "; ".join(row))
    print(watch.line())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
