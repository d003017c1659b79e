"""Wall time of the shipped studies (``rlgsim.lab.study.list_studies()``), run as ``rlgsim study``
does, each beside issue 16's target (cold ≤ 60 s on 2 cores), with the machine and load.

Each study runs in a fresh temporary folder: "cold" simulates its datasets, "warm" (unless
``--cold-only``) reuses them (the second ``rlgsim study`` of the same study), so the difference
is the simulation time and the warm figure is the fitting, scoring and report time. Beside the
wall time: the CPU seconds of this process and its worker processes (user + system; the
worker pool is shut down after each run so that its CPU is counted) — on a
shared machine the wall time grows with the load, the CPU time much less, so CPU / cores is
what the study would take on an idle machine if its work spread over all cores — and the load
average before and after. Studies whose report has a timing table (paper000: timing.csv)
print its steps' wall times too.

    python benchmarks/bench_studies.py [STUDY ...] [--cold-only]
    python benchmarks/bench_studies.py paper000 paper001 --cold-only
"""

from __future__ import annotations

import argparse
import os
import pathlib
import resource
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from _machine import machine  # noqa: E402
from rlgsim.lab.study import list_studies, load_study, run_study  # noqa: E402

#: Issue 16: every shipped study cold in at most a minute on 2 cores.
TARGET_S = 60.0


def _cpu() -> float:
    """User + system CPU seconds of this process and its finished children."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + ch.ru_utime + ch.ru_stime


def _timed(study, folder: str) -> tuple[float, float]:
    """Wall and CPU seconds of one run. The worker pool a recipe started (joblib's reusable
    loky executor) is shut down after the wall time is taken: its processes are then reaped by
    this one, so their CPU counts in ``RUSAGE_CHILDREN`` (a live worker's CPU does not), and
    the next study starts its own pool, as a fresh ``rlgsim study`` command does."""
    from joblib.externals.loky import get_reusable_executor
    t0, c0 = time.perf_counter(), _cpu()
    run_study(study, folder, progress=False)
    wall = time.perf_counter() - t0
    get_reusable_executor().shutdown(wait=True)
    return wall, _cpu() - c0


def _steps(folder: str) -> dict[str, float]:
    """The recipe's own wall time per step, when its report has a ``timing.csv`` (paper000)."""
    path = pathlib.Path(folder) / "timing.csv"
    if not path.is_file():
        return {}
    rows = [line.rsplit(",", 1) for line in path.read_text().splitlines()[1:] if "," in line]
    return {k.strip('"'): float(v) for k, v in rows}


def time_study(name: str, warm: bool) -> dict:
    study = load_study(name)
    with tempfile.TemporaryDirectory(prefix=f"bench-study-{name}-") as tmp:
        load0 = os.getloadavg()[0]
        cold, cold_cpu = _timed(study, tmp)
        out = dict(cold=cold, cold_cpu=cold_cpu, load0=load0, load1=os.getloadavg()[0],
                   steps=_steps(tmp), warm=None, warm_cpu=None)
        if warm:
            out["warm"], out["warm_cpu"] = _timed(study, tmp)
    return out


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("studies", nargs="*", help="studies to time (default: every shipped one)")
    p.add_argument("--cold-only", action="store_true", help="skip the warm (reused data) run")
    args = p.parse_args(argv)
    shipped = [n for n, _ in list_studies()]
    unknown = [n for n in args.studies if n not in shipped]
    if unknown:
        p.error(f"unknown study {unknown[0]!r}; shipped: {', '.join(shipped)}")
    names = args.studies or shipped
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"machine: {machine()}")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'study':<10} {'cold [s]':>9} {'CPU [s]':>8} {'CPU/' + str(cores):>7} "
          f"{'warm [s]':>9} {'target':>8}  verdict (cold wall)   load before → after")
    for name in names:
        try:
            r = time_study(name, not args.cold_only)
        except Exception as exc:            # a study another engineer is still writing
            print(f"{name:<10} failed: {type(exc).__name__}: {exc}")
            continue
        warm_s = f"{r['warm']:9.1f}" if r["warm"] is not None else f"{'—':>9}"
        verdict = "met" if r["cold"] <= TARGET_S else "missed"
        print(f"{name:<10} {r['cold']:9.1f} {r['cold_cpu']:8.1f} {r['cold_cpu'] / cores:7.1f} "
              f"{warm_s} {TARGET_S:6.0f} s  {verdict:<20} {r['load0']:.2f} → {r['load1']:.2f}",
              flush=True)
        for step, s in r["steps"].items():
            print(f"    {step:<40} {s:7.1f} s")


if __name__ == "__main__":
    main()
