"""A run on a vehicle streams: its working set does not grow with the run's duration.

Reference: the run's own Python/NumPy allocations (``tracemalloc``: every NumPy buffer is
traced) at two durations, 6× apart (40 min and 4 h at 10 Hz, blocks of 600 s; the process
warmed by a first run, whose peak holds one-off allocations). A whole-run array of the route's
truth (13 float64 per sample) would add 13·8·(144 000 − 24 000) B ≈ 12.5 MB to the longer
run's peak, one of its increments (6 float64) 5.8 MB; what the blocks need is the same for both.
The peak of one run depends on how many blocks the prefetch worker holds at that moment (thread
scheduling: a few 600 s blocks of about 1 MB each, so runs of the same duration differ by
megabytes), so each duration's figure is the smallest peak of three runs, and the bound is
half the smallest whole-run array. (Memory outside tracemalloc — HDF5's — is held by
tests/test_run_memory.py and benchmarks/bench_sim_memory.py: the writer's files have no chunk
cache.)
"""

from __future__ import annotations

import gc
import tracemalloc

from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate
from test_trajectory_runs import drive


def traced_peak(tmp_path, seconds: int) -> int:
    """Peak traced bytes of a ``seconds``-long drive at 10 Hz (blocks of 600 s)."""
    text = drive().replace("duration_s = 1200\n", f"duration_s = {seconds}\n", 1)
    sc = parse_scenario(text, str(tmp_path / "drive.toml"), base_dir=tmp_path)
    gc.collect()
    tracemalloc.start()
    try:
        simulate(sc, tmp_path / f"d{seconds}.h5", progress=False, chunk_s=600)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_working_set_does_not_grow_with_duration(tmp_path):
    traced_peak(tmp_path, 1200)                 # imports, kernels, one-off buffers
    short = min(traced_peak(tmp_path, 2400) for _ in range(3))
    long = min(traced_peak(tmp_path, 14400) for _ in range(3))
    assert long - short < 0.5 * 6 * 8 * (144_000 - 24_000), (short, long)
