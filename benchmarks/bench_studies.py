"""Wall time of the shipped studies (``rlgsim.lab.study.list_studies()``), run as ``rlgsim study``
does, each beside issue 30's target (cold ≤ 30 s on 2 cores), with the machine and load.

``--repeat N`` (default 5) rounds over the studies, the order reversed every other round so
that a drift of the load hits every study alike; per study the median and spread of its
runs; a verdict only with ≥ 5 runs and the others' load at most 1.5 on 2 cores
(``benchmarks/_machine.py``; ``--repeat 1`` for a quick look without one).

Each study runs in a fresh temporary folder: "cold" simulates its datasets, "warm" (unless
``--cold-only``) reuses them (the second ``rlgsim study`` of the same study), so the difference
is the simulation time and the warm figure is the fitting, scoring and report time. Beside the
wall time: the CPU seconds of this process and its worker processes (user + system; the
worker pool is shut down after each run so that its CPU is counted) — on a
shared machine the wall time grows with the load, the CPU time much less, so CPU / cores is
what the study would take on an idle machine if its work spread over all cores — and the load
average before and after. Studies whose report has a timing table (paper000: timing.csv)
print its steps' wall times too.

    python benchmarks/bench_studies.py [STUDY ...] [--cold-only] [--repeat N]
    python benchmarks/bench_studies.py paper000 paper001 --cold-only
"""

from __future__ import annotations

import argparse
import os
import pathlib
import resource
import statistics
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from _machine import (MIN_PAIRS, LoadWatch, cores, load_text, machine,  # noqa: E402
                      spread)
from rlgsim.lab.study import list_studies, load_study, run_study  # noqa: E402

#: Issue 30: every shipped study cold in at most half a minute on 2 cores (issue 16: a minute).
TARGET_S = 30.0


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
    p.add_argument("--repeat", type=int, default=MIN_PAIRS,
                   help=f"rounds over the studies (default {MIN_PAIRS}, the fewest for a "
                        f"verdict)")
    args = p.parse_args(argv)
    shipped = [n for n, _ in list_studies()]
    unknown = [n for n in args.studies if n not in shipped]
    if unknown:
        p.error(f"unknown study {unknown[0]!r}; shipped: {', '.join(shipped)}")
    names = args.studies or shipped
    n_cores = cores()
    watch = LoadWatch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}")
    print(f"{'round':<5} {'study':<10} {'cold [s]':>9} {'CPU [s]':>8} {'CPU/' + str(n_cores):>7} "
          f"{'warm [s]':>9}   load before → after")
    runs: dict[str, list[dict]] = {n: [] for n in names}
    for rnd in range(max(1, args.repeat)):      # round-robin: a load drift hits every study
        for name in (names if rnd % 2 == 0 else names[::-1]):
            try:
                r = time_study(name, not args.cold_only)
            except Exception as exc:            # a study another engineer is still writing
                print(f"{rnd + 1:<5} {name:<10} failed: {type(exc).__name__}: {exc}")
                continue
            watch.sample()
            runs[name].append(r)
            warm_s = f"{r['warm']:9.1f}" if r["warm"] is not None else f"{'—':>9}"
            print(f"{rnd + 1:<5} {name:<10} {r['cold']:9.1f} {r['cold_cpu']:8.1f} "
                  f"{r['cold_cpu'] / n_cores:7.1f} {warm_s}   {r['load0']:.2f} → "
                  f"{r['load1']:.2f}", flush=True)
            for step, sec in r["steps"].items():
                print(f"      {step:<40} {sec:7.1f} s")
    print(f"summary (target: cold ≤ {TARGET_S:.0f} s on {n_cores} cores, issue 30):")
    for name in names:
        rs = runs[name]
        if not rs:
            continue
        cold = [r["cold"] for r in rs]
        cpu = [r["cold_cpu"] for r in rs]
        warm = [r["warm"] for r in rs if r["warm"] is not None]
        ok = statistics.median(cold) <= TARGET_S
        print(f"  {name:<10} cold {spread(cold, '.1f', ' s')}; CPU {spread(cpu, '.1f', ' s')}"
              + (f"; warm {spread(warm, '.1f', ' s')}" if warm else "")
              + f": {watch.verdict(ok, len(cold))}")
    print(watch.line())


if __name__ == "__main__":
    main()
