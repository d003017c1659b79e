"""Peak memory of a run on a vehicle against its duration (issue 26: memory flat in duration).

Each figure is the peak resident set (``ru_maxrss``) of a fresh process that simulates the
shipped ``vehicle_land_cold`` scenario (RLG-IMU at 100 Hz, its route; after the route's 2 h the
vehicle stays parked) for ``--hours`` (default 0.5, 2, 4, 8) and writes it to HDF5. Beside it:

* the same run with HDF5's chunk cache switched off for the file (``rdcc_nbytes=0``) — HDF5
  keeps up to 1 MiB of chunks per dataset by default (dirty chunks wait there until evicted or
  closed), and a run writes ~80 growing datasets, so that cache fills over hours of a run and
  then stops growing: the difference between the two columns is that cache, and the second
  column is the simulator's own working set (its blocks and their buffers);
* a static run of the same device, thermal programme and duration (no ``[trajectory]``).

The simulator writes with the default cache (the file's bytes — the order in which chunks reach
the disk — depend on it, and the reference datasets do not change); the cache-off column is a
diagnosis only. Usage: ``python benchmarks/bench_sim_memory.py [--hours 0.5 2 4 8]``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import load_text, machine  # noqa: E402

CHILD = r"""
import json, re, resource, sys, time, pathlib
hours, kind, out, cache = float(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4]
if cache == "off":                          # HDF5's chunk cache off for the written file
    import h5py
    _init = h5py.File.__init__
    def _no_cache(self, *a, **k):
        if len(a) > 1 and a[1] == "w":
            k.setdefault("rdcc_nbytes", 0)
        _init(self, *a, **k)
    h5py.File.__init__ = _no_cache
from rlgsim.sim import presets
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate
text = presets.load_scenario_file("vehicle_land_cold").text
text = re.sub(r"(?m)^duration_h = .*$", f"duration_h = {hours}", text)
if kind == "static":
    text = text[:text.index("\n[vehicle_bay]")]
sc = parse_scenario(text, "memory.toml")
t = time.process_time()
simulate(sc, pathlib.Path(out), progress=False)
print(json.dumps({"rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "cpu_s": time.process_time() - t}))
"""


def peak(hours: float, kind: str, cache: str, out: pathlib.Path) -> dict:
    """Peak RSS [MB] and CPU [s] of one fresh process."""
    r = subprocess.run([sys.executable, "-c", CHILD, str(hours), kind, str(out), cache],
                       capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, nargs="+", default=[0.5, 2.0, 4.0, 8.0])
    args = ap.parse_args(argv)
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}  ({time.strftime('%H:%M UTC', time.gmtime())})",
          flush=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="rlgsim-bench-mem-"))
    print(f"{'hours':>6} {'vehicle':>9} {'cache off':>10} {'static':>8}   (peak RSS, MB; CPU s)")
    rows = []
    for h in args.hours:
        v = peak(h, "trajectory", "on", tmp / "v.h5")
        n = peak(h, "trajectory", "off", tmp / "n.h5")
        s = peak(h, "static", "on", tmp / "s.h5")
        rows.append((h, v, n, s))
        print(f"{h:6g} {v['rss_mb']:9.0f} {n['rss_mb']:10.0f} {s['rss_mb']:8.0f}   "
              f"(CPU {v['cpu_s']:.1f} / {n['cpu_s']:.1f} / {s['cpu_s']:.1f} s)", flush=True)
    first, last = rows[0], rows[-1]
    growth = last[2]["rss_mb"] - first[2]["rss_mb"]
    print(f"the simulator's own working set (cache off) from {first[0]:g} h to {last[0]:g} h: "
          f"{growth:+.0f} MB; with HDF5's chunk cache: "
          f"{last[1]['rss_mb'] - first[1]['rss_mb']:+.0f} MB (bounded: ≤ 1 MiB per dataset)")
    print(f"load average after: {load_text()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
