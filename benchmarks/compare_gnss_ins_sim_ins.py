"""Navigation on the same motion definition in gnss-ins-sim and in rlgsim (issue 26, item 3).

The issue names gnss-ins-sim's loosely coupled ``ins_loose`` as the peer of rlgsim's aided filter
(estimators/ins/aided.py). This script first tries it — ``demo_algorithms/ins_loose.InsLoose``
in ``ins_sim.Sim`` with GNSS on ``motion_def-90deg_turn.csv`` — and prints in one line what
happens: in gnss-ins-sim as published its ``prediction`` and ``correction`` are empty and it
returns no results (its demo says it is still under development), so ``Sim.run`` stops with an
error and there is no error figure to compare; its other INS, ``aceinna_ins``, is a Windows DLL.

What both can run is the strapdown part, on error-free sensors: the INS on each simulator's own
sensor data from its own reference, started from the true state, with no aiding — its error
is then the data's and the integration's own inconsistency (docs/trajectories.md):

* gnss-ins-sim: ``imu_model.IMU`` with every error zero, ``ins_sim.Sim([100, 0, 0], file,
  ref_frame=0, …)`` and its ``demo_algorithms/free_integration.FreeIntegration`` from the file's
  initial state; its position against its ``ref_pos``;
* rlgsim: the file read by ``rlgsim.sim.motion.motion_def``, the exact increments of the
  trajectory at 100 Hz, the navigator ``rlgsim.estimators.ins.mechanization.integrate`` (free
  vertical channel) from the true state; its position against the trajectory's truth.

gnss-ins-sim runs in a subprocess from its own folder (``--gnss-ins-sim PATH`` or the
environment variable ``GNSS_INS_SIM``); nothing of it is in this repository. Prints per file the
duration, the largest horizontal and the final vertical error of both, the machine line and the
load average. Usage: ``python benchmarks/compare_gnss_ins_sim_ins.py [--gnss-ins-sim PATH]
[--files a.csv,b.csv]``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import load_text, machine  # noqa: E402

RATE_HZ = 100.0
FILES = ("motion_def-90deg_turn.csv", "motion_def-0to100.csv", "motion_def-3d.csv")

#: in the subprocess: gnss-ins-sim's loosely coupled INS (GNSS at 10 Hz) on one file
LOOSE = r"""
import sys
from gnss_ins_sim.sim import imu_model, ins_sim
from demo_algorithms import ins_loose
imu = imu_model.IMU(accuracy="high-accuracy", axis=6, gps=True)
sim = ins_sim.Sim([100.0, 10.0, 0.0], sys.argv[1], ref_frame=0, imu=imu, mode=None, env=None,
                  algorithm=ins_loose.InsLoose())
try:
    sim.run(1)
    print("ran")
except Exception as e:
    print(f"{type(e).__name__}: {e}")
"""

#: in the subprocess: error-free sensors, free integration, horizontal and vertical errors
FREE = r"""
import json, math, sys
import numpy as np
from gnss_ins_sim.sim import imu_model, ins_sim
from demo_algorithms import free_integration
z = np.zeros(3)
err = {"gyro_b": z, "gyro_arw": z, "gyro_b_stability": z, "gyro_b_corr": np.full(3, 100.0),
       "accel_b": z, "accel_vrw": z, "accel_b_stability": z, "accel_b_corr": np.full(3, 200.0)}
path = sys.argv[1]
ini = np.genfromtxt(path, delimiter=",", skip_header=1, max_rows=1)
ini[0:2] *= math.pi / 180.0
ini[6:9] *= math.pi / 180.0
sim = ins_sim.Sim([float(sys.argv[2]), 0.0, 0.0], path, ref_frame=0,
                  imu=imu_model.IMU(accuracy=err, axis=6, gps=False), mode=None, env=None,
                  algorithm=free_integration.FreeIntegration(ini))
sim.run(1)
ref = sim.dmgr.get_data_all("ref_pos").data
pos = list(sim.dmgr.get_data_all("pos").data.values())[0]
np.save(sys.argv[3], np.stack([ref, pos]))
"""


def _run(root: pathlib.Path, code: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-c", code, *args], cwd=root, env=env,
                          capture_output=True, text=True, timeout=3600)


def errors(lat_ref, lon_ref, h_ref, lat, lon, h) -> tuple[float, float]:
    """Largest horizontal [m] and final vertical [m] error of (lat, lon, h) [rad, rad, m]."""
    from rlgsim.ground.earth import radii_of_curvature_rad
    rm, rn = radii_of_curvature_rad(lat_ref)
    north = (lat - lat_ref) * (rm + h_ref)
    east = (lon - lon_ref) * (rn + h_ref) * np.cos(lat_ref)
    return float(np.max(np.hypot(north, east))), float(h[-1] - h_ref[-1])


def theirs(root: pathlib.Path, csv: pathlib.Path) -> dict:
    with tempfile.TemporaryDirectory() as d:
        out = pathlib.Path(d) / "p.npy"
        r = _run(root, FREE, str(csv), str(RATE_HZ), str(out))
        if r.returncode != 0:
            return {"error": (r.stderr.strip().splitlines() or ["failed"])[-1]}
        ref, pos = np.load(out)
    hor, ver = errors(ref[:, 0], ref[:, 1], ref[:, 2], pos[:, 0], pos[:, 1], pos[:, 2])
    return {"duration_s": ref.shape[0] / RATE_HZ, "horizontal_m": hor, "vertical_m": ver}


def ours(csv: pathlib.Path) -> dict:
    from rlgsim.estimators.ins.mechanization import InsState, integrate
    from rlgsim.sim.motion.motion_def import read_motion_def
    from rlgsim.sim.motion.trajectory import InitialState, Trajectory
    md = read_motion_def(csv)
    route = Trajectory(md.legs, InitialState(md.lat_rad, md.lon_rad, md.height_m))
    n = int(np.floor(route.end_s * RATE_HZ + 1e-9))
    mb = route.increments(0.0, n, RATE_HZ, angles=False)
    s0 = route.states(np.array([0.0]))
    start = InsState.at_rest(s0.c_bn[0], np.degrees(s0.lat[0]), np.degrees(s0.lon[0]),
                             s0.height[0], s0.v_n[0])
    sol = integrate(start, mb.dtheta_rad, mb.dv_m_per_s, 1.0 / RATE_HZ,
                    height=None, output_every=max(1, int(RATE_HZ) // 10))
    truth = route.states(sol.t_s)
    hor, ver = errors(truth.lat, truth.lon, truth.height, sol.lat, sol.lon, sol.h)
    return {"duration_s": n / RATE_HZ, "horizontal_m": hor, "vertical_m": ver}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gnss-ins-sim", default=os.environ.get("GNSS_INS_SIM"))
    ap.add_argument("--files", default=",".join(FILES))
    args = ap.parse_args()
    if not args.gnss_ins_sim or not (pathlib.Path(args.gnss_ins_sim) / "gnss_ins_sim").is_dir():
        print("gnss-ins-sim not found: give its source folder with --gnss-ins-sim PATH")
        return 1
    root = pathlib.Path(args.gnss_ins_sim).resolve()
    demo = root / "demo_motion_def_files"
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    r = _run(root, LOOSE, str(demo / FILES[0]))
    said = (r.stdout.strip().splitlines() or r.stderr.strip().splitlines() or ["no output"])[-1]
    print(f"gnss-ins-sim ins_loose on {FILES[0]} with GNSS: {said}", flush=True)
    print("free integration, error-free sensors, no aiding (largest horizontal error; final "
          "vertical error):")
    for name in args.files.split(","):
        csv = demo / name
        a, b = theirs(root, csv), ours(csv)
        if "error" in a:
            print(f"  {name}: gnss-ins-sim failed ({a['error']})")
            continue
        print(f"  {name} ({a['duration_s']:g} s): gnss-ins-sim {a['horizontal_m']:.3g} m, "
              f"{a['vertical_m']:+.3g} m; rlgsim ({b['duration_s']:g} s) "
              f"{b['horizontal_m']:.3g} m, {b['vertical_m']:+.3g} m", flush=True)
    print(f"load average after: {load_text()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
