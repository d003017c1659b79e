"""The same motion definition through gnss-ins-sim and rlgsim: reference position, velocity and
attitude side by side (issue 26's acceptance check; docs/trajectories.md states the result).

gnss-ins-sim (Aceinna, MIT licence) generates its reference trajectory by stepping its motion
commands at the simulation rate with first-order (rectangle-rule) updates of position, velocity
and Euler angles, after a low-pass of the commanded rates (type 1) or a PD controller with
limits (types 2–5). rlgsim's legs are closed forms (attitude, body velocity) and its position
is integrated by DOP853 at rtol 1e-13 (sim/motion/trajectory.py). So for type-1 files the two
must agree up to gnss-ins-sim's discretisation — and the difference must shrink about in
proportion to its step when it runs at a higher internal rate (``osr``, its
simulation-over-sample ratio): that is the evidence of whose integration is exact. Types 2–5
differ by design (its asymptotic controller against minimum-time smooth legs; the docs).

gnss-ins-sim is never copied into this repository: give its source folder with
``--gnss-ins-sim PATH`` (or the environment variable ``GNSS_INS_SIM``); it runs in a subprocess
from a temporary folder, on its own demo motion files (``demo_motion_def_files/``).

Prints, per file and gnss-ins-sim rate, the largest horizontal and vertical position
differences [m], velocity difference [m/s] and attitude difference [°] over the run, beside
the machine line and the load average. Usage: ``python benchmarks/compare_gnss_ins_sim_motion.py
[--gnss-ins-sim PATH] [--files a.csv,b.csv] [--osr 1,10]``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import machine  # noqa: E402

RATE_HZ = 100.0
FILES = ("motion_def-0to100.csv", "motion_def-90deg_turn.csv", "motion_def-3d.csv",
         "motion_def-Holland_tunnel.csv")

#: run in the subprocess: gnss-ins-sim's path generator on one file; its 'nav' rows to .npy
DRIVER = r"""
import sys, numpy as np
from gnss_ins_sim.pathgen import pathgen
path, fs, osr, out = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
ini = np.genfromtxt(path, delimiter=',', skip_header=1, max_rows=1)
wp = np.atleast_2d(np.genfromtxt(path, delimiter=',', skip_header=3))
d2r = np.pi / 180
pva = np.hstack([ini[0:2] * d2r, ini[2:6], ini[6:9] * d2r])
md = wp[:, :9].copy()
md[:, 1:4] *= d2r
md[np.isnan(md)] = 0.0
output_def = np.array([[osr, fs], [-1.0, fs], [-1.0, fs]])
nav = pathgen.path_gen(pva, md, output_def, np.array([1.0, 0.5, 2.0]), 0, False)['nav']
nav[:, 0] /= fs * osr             # sim count -> time [s]
np.save(out, nav)
"""


def gnss_ins_sim_nav(root: pathlib.Path, csv: pathlib.Path, osr: int) -> np.ndarray:
    """gnss-ins-sim's reference rows (time, lat, lon [rad], alt, v_NED, yaw, pitch, roll)."""
    with tempfile.TemporaryDirectory(prefix="gnss-ins-sim-") as tmp:
        out = pathlib.Path(tmp) / "nav.npy"
        env = {**os.environ, "PYTHONPATH": str(root)}
        r = subprocess.run([sys.executable, "-c", DRIVER, str(csv), str(RATE_HZ), str(osr),
                            str(out)], cwd=tmp, env=env, capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"gnss-ins-sim failed on {csv.name}: "
                             f"{(r.stderr.strip().splitlines() or ['?'])[-1]}")
        return np.load(out)


def differences(nav: np.ndarray, csv: pathlib.Path) -> dict[str, float]:
    """Largest differences of gnss-ins-sim's rows from rlgsim's states at the same times."""
    from rlgsim.ground.earth import radii_of_curvature_rad
    from rlgsim.sim.motion.motion_def import read_motion_def
    from rlgsim.sim.motion.trajectory import InitialState, Trajectory
    md = read_motion_def(csv)
    traj = Trajectory(md.legs, InitialState(md.lat_rad, md.lon_rad, md.height_m))
    t = nav[:, 0]
    keep = t <= traj.end_s
    t, nav = t[keep], nav[keep]
    st = traj.states(t)
    rm, rn = radii_of_curvature_rad(st.lat)
    d_n = (nav[:, 1] - st.lat) * (rm + st.height)
    d_e = (nav[:, 2] - st.lon) * (rn + st.height) * np.cos(st.lat)
    v_enu = np.stack([nav[:, 5], nav[:, 4], -nav[:, 6]], axis=1)
    att = np.degrees(np.stack([nav[:, 7], nav[:, 8], nav[:, 9]], axis=1) - st.euler.T)
    att = (att + 180.0) % 360.0 - 180.0
    return {"t_s": float(t[-1]), "horizontal_m": float(np.max(np.hypot(d_n, d_e))),
            "vertical_m": float(np.max(np.abs(nav[:, 3] - st.height))),
            "velocity_m_s": float(np.max(np.linalg.norm(v_enu - st.v_n, axis=1))),
            "attitude_deg": float(np.max(np.abs(att)))}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gnss-ins-sim", default=os.environ.get("GNSS_INS_SIM"))
    ap.add_argument("--files", default=",".join(FILES))
    ap.add_argument("--osr", default="1,10")
    args = ap.parse_args()
    if not args.gnss_ins_sim or not (pathlib.Path(args.gnss_ins_sim) / "gnss_ins_sim").is_dir():
        print("compare_gnss_ins_sim_motion: give gnss-ins-sim's source folder with "
              "--gnss-ins-sim PATH (or GNSS_INS_SIM)", file=sys.stderr)
        return 1
    root = pathlib.Path(args.gnss_ins_sim).resolve()
    print(machine())
    print(f"load average before: {os.getloadavg()}")
    print(f"{'file':34s} {'osr':>4s} {'t [s]':>8s} {'horiz [m]':>11s} {'vert [m]':>10s} "
          f"{'vel [m/s]':>10s} {'att [deg]':>10s}")
    for name in args.files.split(","):
        csv = root / "demo_motion_def_files" / name
        for osr in (int(x) for x in args.osr.split(",")):
            d = differences(gnss_ins_sim_nav(root, csv, osr), csv)
            print(f"{name:34s} {osr:4d} {d['t_s']:8.1f} {d['horizontal_m']:11.4g} "
                  f"{d['vertical_m']:10.4g} {d['velocity_m_s']:10.4g} "
                  f"{d['attitude_deg']:10.4g}")
    print(f"load average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
