"""Estimator benchmarks (Compensators I and II): prints fit times and optimiser throughput.

Each section lives in its own module ``benchmarks/estimators_<topic>.py`` exposing ``run()``,
which prints its own figures (timing verdicts through ``_machine.shared_watch()``: only with ≥ 5
runs and the others' load at most 1.5 on 2 cores); this script prints the load average before
and after and runs them all (or those named on the command line:
``python benchmarks/bench_estimators.py lssvm rvr``).
"""

from __future__ import annotations

import importlib
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _machine import load_text, machine, shared_watch  # noqa: E402


def main(argv: list[str]) -> None:
    watch = shared_watch()
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    sections = sorted(p.stem for p in HERE.glob("estimators_*.py"))
    wanted = [f"estimators_{name}" for name in argv] or sections
    for name in wanted:
        if name not in sections:
            sys.exit(f"bench_estimators: no section '{name[11:]}'; have: "
                     f"{', '.join(s[11:] for s in sections)}")
        print(f"\n== {name[11:]} ==")
        importlib.import_module(name).run()
    print()
    print(watch.line())


if __name__ == "__main__":
    main(sys.argv[1:])
