"""A long run's resident memory is flat in its duration (issue 26: "streaming as today").

Reference: the process's resident set (``VmRSS``) before every block of one 24 h run in a fresh
process (a process that ran other tests first may reuse its freed heap and hide a growth), from
6 h to the last block (the file's closing, the same at any duration, is left out). The rule is benchmarks/bench_sim_memory.py's: at most 5 MB (the spread of equal
runs) plus 0.66 KB per chunk the file indexes (HDF5's version-1 B-tree nodes in its metadata
cache; the benchmark's docstring derives the figure) — counted here over the whole file, an
upper bound of the chunks written after 6 h. The run is static at 10 Hz (the growth this guards
against did not depend on the IMU's rate: HDF5's chunk cache kept the 1 Hz series — thermal
network, probes, truth — until the file closed: +48 MB from 6 h to 24 h, against +2.4 MB with
the cache off), ~2 s of CPU.
"""

from __future__ import annotations

import json
import subprocess
import sys

#: the spread of equal runs [MB] and what the chunk index may hold per chunk [MB]
SPREAD_MB = 5.0
INDEX_MB_PER_CHUNK = 0.66e-3

CHILD = r"""
import json, re, sys, pathlib
import h5py
from rlgsim.sim import presets
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate
text = presets.load_scenario_file("vehicle_land_cold").text
text = text[:text.index("\n[vehicle_bay]")]                     # no route: a static run
text = re.sub(r"(?m)^duration_h = .*$", "duration_h = 24", text)
text = re.sub(r"(?m)^sample_rate_hz = .*$", "sample_rate_hz = 10", text)
rss = []
def sample():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            rss.append(int(line.split()[1]) / 1024)
    return False
out = pathlib.Path(sys.argv[1])
simulate(parse_scenario(text, "memory.toml"), out, progress=False, should_stop=sample,
         chunk_s=600)
chunks = []
with h5py.File(out, "r") as f:
    f.visititems(lambda n, o: chunks.append(o.id.get_num_chunks())
                 if isinstance(o, h5py.Dataset) and o.chunks else None)
print(json.dumps({"rss_mb": rss, "chunks": sum(chunks)}))
"""


def test_resident_memory_is_flat_from_6_h_to_24_h(tmp_path):
    if not sys.platform.startswith("linux"):
        import pytest
        pytest.skip("reads /proc/self/status")
    r = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path / "static.h5")],
                       capture_output=True, text=True, check=True)
    got = json.loads(r.stdout.strip().splitlines()[-1])
    rss = got["rss_mb"]
    assert len(rss) == 24 * 6                          # one sample before each 600 s block
    growth = max(rss) - rss[6 * 6]
    allowed = SPREAD_MB + INDEX_MB_PER_CHUNK * got["chunks"]
    assert growth <= allowed, (growth, allowed, rss[::6])
