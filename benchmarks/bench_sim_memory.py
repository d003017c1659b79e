"""Peak memory of a run against its duration (issue 26: "streaming as today: memory flat in
duration"), with a verdict.

Each figure is the peak resident set (``ru_maxrss``) of a fresh process that simulates for
``--hours`` (default 2, 8, 24, 48) and writes the run to HDF5, the median of ``--repeat`` runs
(default 3; the spread beside it):

* **vehicle** — the shipped ``vehicle_land_cold`` scenario (RLG-IMU at 100 Hz; after the route's
  2 h the vehicle stays parked);
* **static** — the same device, thermal programme and duration without ``[trajectory]``;
* **HDF5 cache** — the vehicle again (one run) with HDF5's default chunk cache (8 MiB per
  dataset since HDF5 2.0), which the writer used until it switched it off
  (``rlgsim.sim.writer.dataset.CHUNK_CACHE_BYTES``): what grew before.

Every run imports numba first, as a vehicle run and a static run of 5 M epochs or more do
(``rlgsim.sim.sensors.imu.COMPILED_MIN_EPOCHS``: 13.9 h at 100 Hz): a shorter static run stays
on NumPy and would miss numba's ~100 MB, a one-off step at that duration, not a growth. A
first, unreported run loads (or compiles) numba's cached kernels, so the first figure is not a
compilation. The runs use ``chunk_s = 600`` (``--chunk-s``): the writer queue then holds one
600 s block; with the default (3600 s: six blocks, ~10 MB each on the vehicle) how many blocks
wait depends on how far the writer thread lags — the machine's load, not the duration — and
moved a run's peak by tens of MB.

**The rule (the verdict):** from ``--ref-hours`` (8) to the longest run, the median peak may
grow by at most 5 MB (the spread of equal runs: which blocks the worker threads hold) plus what
the file's own chunk index may hold in HDF5's metadata cache: 0.66 KB per chunk written in
between. A version-1 B-tree node (the index of a chunked dataset with the writer's ``libver``)
holds up to 64 chunk entries, each with a native key of 272 B (H5Dbtree.c ``H5D_btree_key_t``:
33 offsets of 8 B, size, filter mask) and an address, plus the node's file image; nodes
at least half full give ≤ 0.66 KB per chunk. The chunks are counted in the written files.
Usage: ``python benchmarks/bench_sim_memory.py [--hours 2 8 24 48] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import LoadWatch, machine  # noqa: E402

#: the spread of equal runs' peaks allowed [MB]
SPREAD_MB = 5.0
#: what the chunk index may hold per chunk [MB] (module docstring)
INDEX_MB_PER_CHUNK = 0.66e-3

CHILD = r"""
import json, re, resource, sys, time, pathlib
hours, kind, out, cache, chunk_s = (float(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4],
                                    float(sys.argv[5]))
import h5py
import numba                               # loaded as a long or a vehicle run loads it (docstring)
from rlgsim.sim.writer import dataset
if cache == "default":                     # HDF5's own chunk cache (the writer's before)
    dataset.CHUNK_CACHE_BYTES = None
from rlgsim.sim import presets
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate
text = presets.load_scenario_file("vehicle_land_cold").text
text = re.sub(r"(?m)^duration_h = .*$", f"duration_h = {hours}", text)
if kind == "static":
    text = text[:text.index("\n[vehicle_bay]")]
sc = parse_scenario(text, "memory.toml")
t = time.process_time()
simulate(sc, pathlib.Path(out), progress=False, chunk_s=chunk_s)
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
cpu = time.process_time() - t
chunks = []
with h5py.File(out, "r") as f:
    f.visititems(lambda n, o: chunks.append(o.id.get_num_chunks())
                 if isinstance(o, h5py.Dataset) and o.chunks else None)
print(json.dumps({"rss_mb": rss, "cpu_s": cpu, "chunks": sum(chunks)}))
"""


def peak(hours: float, kind: str, cache: str, out: pathlib.Path, chunk_s: float) -> dict:
    """Peak RSS [MB], CPU [s] and chunks written of one fresh process."""
    r = subprocess.run([sys.executable, "-c", CHILD, str(hours), kind, str(out), cache,
                        str(chunk_s)], capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"bench_sim_memory: the {kind} run of {hours:g} h failed:\n{r.stderr}")
    out.unlink()
    return json.loads(r.stdout.strip().splitlines()[-1])


def verdict(name: str, rows: list[dict], ref: float) -> str:
    """The rule's line for one column: growth from ``ref`` hours to the longest against its
    allowance."""
    by_h = {r["hours"]: r for r in rows}
    if ref not in by_h or max(by_h) <= ref:
        return f"{name}: no verdict (needs a run of --ref-hours {ref:g} and a longer one)"
    a, b = by_h[ref], by_h[max(by_h)]
    growth = b["rss_mb"] - a["rss_mb"]
    allowed = SPREAD_MB + INDEX_MB_PER_CHUNK * (b["chunks"] - a["chunks"])
    flat = "flat" if growth <= allowed else "NOT flat"
    return (f"{name}: peak {a['rss_mb']:.0f} MB at {ref:g} h -> {b['rss_mb']:.0f} MB at "
            f"{max(by_h):g} h: {growth:+.1f} MB; target ≤ {allowed:.1f} MB ({SPREAD_MB:g} MB + "
            f"{INDEX_MB_PER_CHUNK * 1e3:.2f} KB × {b['chunks'] - a['chunks']} chunks indexed "
            f"in between): {flat}")


def _cell(runs: list[dict], hours: float) -> dict:
    """The median of equal runs (and their spread)."""
    rss = [r["rss_mb"] for r in runs]
    return {"hours": hours, "rss_mb": statistics.median(rss), "lo": min(rss), "hi": max(rss),
            "chunks": runs[0]["chunks"], "cpu_s": statistics.median(r["cpu_s"] for r in runs)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, nargs="+", default=[2.0, 8.0, 24.0, 48.0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure (median)")
    ap.add_argument("--ref-hours", type=float, default=8.0)
    ap.add_argument("--chunk-s", type=float, default=600.0)
    args = ap.parse_args(argv)
    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"start {time.strftime('%H:%M UTC', time.gmtime())}, chunk_s = {args.chunk_s:g}, "
          f"median of {args.repeat} fresh processes per figure", flush=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="rlgsim-bench-mem-"))
    peak(0.2, "trajectory", "off", tmp / "warm.h5", args.chunk_s)   # numba's caches
    print(f"{'hours':>6} {'vehicle':>17} {'static':>17} {'HDF5 cache':>11}   "
          f"(peak RSS, MB: median [spread]; chunks; CPU s)")
    cols: dict[str, list[dict]] = {"vehicle": [], "static": []}
    for h in sorted(args.hours):
        cells = {}
        for kind, col in (("trajectory", "vehicle"), ("static", "static")):
            runs = [peak(h, kind, "off", tmp / f"{col}.h5", args.chunk_s)
                    for _ in range(max(1, args.repeat))]
            cells[col] = _cell(runs, h)
            cols[col].append(cells[col])
        c = peak(h, "trajectory", "default", tmp / "cache.h5", args.chunk_s)
        v, s = cells["vehicle"], cells["static"]
        print(f"{h:6g} {v['rss_mb']:5.0f} [{v['lo']:.0f}-{v['hi']:.0f}] {s['rss_mb']:7.0f} "
              f"[{s['lo']:.0f}-{s['hi']:.0f}] {c['rss_mb']:11.0f}   (chunks {v['chunks']} / "
              f"{s['chunks']}; CPU {v['cpu_s']:.1f} / {s['cpu_s']:.1f} / {c['cpu_s']:.1f} s)",
              flush=True)
        watch.sample()
    print("rule: the median peak from --ref-hours to the longest run grows by at most "
          f"{SPREAD_MB:g} MB + {INDEX_MB_PER_CHUNK * 1e3:.2f} KB per chunk indexed in between "
          "(the docstring says why)")
    for col, rows in cols.items():
        print(verdict(col, rows, args.ref_hours))
    print(watch.line())
    print("(a memory figure, not a timing: the verdict is printed at any load; a busy machine "
          "may widen the spread of equal runs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
