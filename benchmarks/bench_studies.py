"""Wall time of every shipped study (``rlgsim.sim.study.list_studies()``), run as ``rlgsim study`` does.

Each study runs twice in a fresh temporary folder: "cold" simulates its datasets, "warm" reuses
them (the second ``rlgsim study`` of the same study), so the difference is the simulation time
and the warm figure is the fitting, scoring and report time. Printed with the machine line.

    python benchmarks/bench_studies.py [STUDY ...] [--cold-only]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from _machine import machine  # noqa: E402
from rlgsim.sim.study import list_studies, load_study, run_study  # noqa: E402


#: Issue 16: every shipped study cold in at most a minute on 2 cores.
TARGET_S = 60.0


def time_study(name: str, warm: bool) -> tuple[float, float | None]:
    study = load_study(name)
    with tempfile.TemporaryDirectory(prefix=f"bench-study-{name}-") as tmp:
        t0 = time.perf_counter()
        run_study(study, tmp, progress=False)
        cold = time.perf_counter() - t0
        second = None
        if warm:
            t0 = time.perf_counter()
            run_study(study, tmp, progress=False)
            second = time.perf_counter() - t0
    return cold, second


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("studies", nargs="*", help="studies to time (default: every shipped one)")
    p.add_argument("--cold-only", action="store_true", help="skip the warm (reused data) run")
    args = p.parse_args(argv)
    names = args.studies or [n for n, _ in list_studies()]
    print(f"machine: {machine()}")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'study':<12} {'cold [s]':>10} {'warm [s]':>10} {'target':>8}   (cold: simulate + "
          f"fit + report; warm: datasets reused; target: cold <= 60 s on 2 cores)")
    for name in names:
        try:
            cold, warm = time_study(name, not args.cold_only)
        except Exception as exc:            # a study another engineer is still writing
            print(f"{name:<12} failed: {type(exc).__name__}: {exc}")
            continue
        warm_s = f"{warm:10.1f}" if warm is not None else f"{'—':>10}"
        verdict = "met" if cold <= TARGET_S else "missed"
        print(f"{name:<12} {cold:10.1f} {warm_s} {TARGET_S:6.0f} s {verdict}  (load "
              f"{os.getloadavg()[0]:.2f})", flush=True)


if __name__ == "__main__":
    main()
