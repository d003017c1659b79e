"""What every benchmark prints beside its figures: the machine, the load, medians and spreads of
alternated runs, and a verdict only when the machine was quiet enough for one.

The machine is often shared (two cores, several people): a wall-clock figure then measures the
others as much as the code. The rules every ``bench_*.py`` / ``compare_*.py`` follows:

* a figure is the **median of at least** :data:`MIN_PAIRS` **runs** (pairs when two things are
  compared), with its spread (smallest and largest) printed beside it; two things compared are
  run in alternation — A B, B A, A B, … (:func:`alternate`) — so that a drift of the load hits
  both alike;
* the load average is printed **before and after** (:class:`LoadWatch`);
* a verdict against a target ("met" / "missed") is printed only when the others' load stayed
  at or below :func:`max_load` — 1.5 on 2 cores (0.75 per core) — and the median stands on at
  least :data:`MIN_PAIRS` runs; otherwise the figure is printed with "no verdict" and why
  (:meth:`LoadWatch.verdict`).

The others' load: the load average before the benchmark starts is theirs alone; after it, the
average also counts the benchmark's own threads. :class:`LoadWatch` takes off the benchmark's
own mean CPU use (its CPU seconds, threads and reaped worker processes, per wall second) — an
upper bound of the others' share, since the benchmark's threads that wait for a core count in
the load as well: the rule errs towards refusing.
"""

from __future__ import annotations

import os
import platform
import resource
import statistics
import time
from typing import Callable, Sequence

#: the fewest runs (or alternated pairs) a median must stand on for a verdict
MIN_PAIRS = 5
#: load average per core above which no verdict is printed (1.5 on 2 cores)
MAX_LOAD_PER_CORE = 0.75


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = ""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
        mem = f", {pages * size / 2**30:.0f} GiB"
    except (ValueError, OSError):
        pass
    return (f"{cpu}, {cores()} cores{mem}, Python {platform.python_version()}, "
            f"{platform.system()} {platform.release()}")


def cores() -> int:
    """Cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def max_load() -> float:
    """The others' load average above which a benchmark prints no verdict (1.5 on 2 cores)."""
    return MAX_LOAD_PER_CORE * cores()


def load_text() -> str:
    """The 1, 5 and 15 min load averages."""
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def own_cpu() -> float:
    """CPU seconds (user + system) of this process's threads and of its reaped children."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + ch.ru_utime + ch.ru_stime


def spread(values: Sequence[float], fmt: str = ".2f", unit: str = "") -> str:
    """``median M (min A – max B, n runs)`` of ``values``."""
    v = list(values)
    if not v:
        return "no runs"
    return (f"median {statistics.median(v):{fmt}}{unit} (spread {min(v):{fmt}}–"
            f"{max(v):{fmt}}{unit}, {len(v)} run{'s' if len(v) != 1 else ''})")


def alternate(a: Callable[[], float], b: Callable[[], float], pairs: int,
              report: Callable[[int, float, float], None] | None = None
              ) -> tuple[list[float], list[float]]:
    """Run ``a`` and ``b`` ``pairs`` times each, alternating the order of each pair (A B, B A,
    A B, …) so that a load that rises or falls during the run hits both alike; returns the
    two lists of their results (in pair order). ``report(i, ra, rb)`` is called after each
    pair (1-based ``i``)."""
    ra: list[float] = []
    rb: list[float] = []
    for i in range(pairs):
        if i % 2 == 0:
            x = a()
            y = b()
        else:
            y = b()
            x = a()
        ra.append(x)
        rb.append(y)
        if report is not None:
            report(i + 1, x, y)
    return ra, rb


class LoadWatch:
    """The load average before, during (:meth:`sample`) and after a benchmark, and the others'
    share of it (the load less this benchmark's own mean CPU use since :meth:`start`)."""

    def __init__(self) -> None:
        self.start()

    def start(self) -> None:
        self.t0, self.cpu0 = time.perf_counter(), own_cpu()
        self.before = os.getloadavg()[0]
        self.samples: list[tuple[float, float]] = [(self.before, self.before)]

    def sample(self) -> float:
        """Record the 1-min load now; returns the others' estimated share of it."""
        load = os.getloadavg()[0]
        dt = time.perf_counter() - self.t0
        own = (own_cpu() - self.cpu0) / dt if dt > 0 else 0.0
        others = max(0.0, load - own)
        self.samples.append((load, others))
        return others

    def others(self) -> float:
        """The largest estimate of the others' load over the samples taken so far."""
        return max(o for _, o in self.samples)

    def quiet(self) -> bool:
        return self.others() <= max_load()

    def line(self, what: str = "load average") -> str:
        """``load average before B, after A (1 min; others' share at most O; limit L)``; takes
        a sample now."""
        self.sample()
        after = self.samples[-1][0]
        return (f"{what}: before {self.before:.2f}, after {after:.2f} (1 min; others' share "
                f"at most {self.others():.2f} — the load less this benchmark's own CPU use; "
                f"verdicts only at ≤ {max_load():.2f} on {cores()} cores); now {load_text()}")

    def verdict(self, ok: bool, runs: int = MIN_PAIRS) -> str:
        """"met" / "missed", or "no verdict" with the reason (a busy machine, too few runs).
        Takes a sample now."""
        self.sample()
        if not self.quiet():
            return (f"no verdict (the others' load reached {self.others():.2f} > "
                    f"{max_load():.2f} on {cores()} cores)")
        if runs < MIN_PAIRS:
            return f"no verdict ({runs} run{'s' if runs != 1 else ''} < {MIN_PAIRS})"
        return "met" if ok else "missed"


_SHARED: LoadWatch | None = None


def shared_watch() -> LoadWatch:
    """One :class:`LoadWatch` per process, started at the first call: for benchmarks whose
    sections live in other modules (``bench_estimators.py``)."""
    global _SHARED
    if _SHARED is None:
        _SHARED = LoadWatch()
    return _SHARED


if __name__ == "__main__":
    print(machine())
    print(f"load average: {load_text()} (verdicts only at ≤ {max_load():.2f})")
