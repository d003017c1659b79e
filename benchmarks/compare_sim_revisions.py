"""Simulator throughput of this tree against an earlier revision, measured in one run.

Issue 12 asks that the realism mechanisms (real chamber, anomalies, heaters, boundaries, …)
leave ``benchmarks/bench_sim.py``'s throughput no more than 20 % below the build before them.
This script times both builds on this machine in the same run, in ``--rounds`` (default 5)
pairs whose order alternates (old new, new old, …) so that a change of load hits both, and
prints the median and spread of the epochs/s of each and of their ratio per pair beside the
target, with the machine and the load average before and after; a verdict only with ≥ 5 pairs
and the others' load at most 1.5 on 2 cores (``benchmarks/_machine.py``).

The earlier revision (default: the parent of the first commit that added
``sim/thermal/chamber_controller.py`` or ``sim/sensors/anomalies.py`` — the start of the issue-12 work) is
unpacked with ``git archive`` into a temporary folder (the repository is not touched) and run
in a subprocess whose import path points there: the ``rlgsim`` namespace layout (``src/rlgsim``
with ``sim/``, ``estimators/``, ``scenarios/`` mapped to ``rlgsim.sim``, …) is assembled from
the archive with symbolic links; a revision from before the namespace move (top-level ``sim``
and ``estimators`` packages) is imported as it was. Each build simulates its *own* shipped
``paper000_ramp`` scenario and presets (what ``bench_sim.py`` of that build measures), cut to
``--hours`` (default 12 h: 4.3 million epochs at 100 Hz) and written to HDF5.

Usage: ``python benchmarks/compare_sim_revisions.py [--rev REV] [--hours H] [--rounds N]``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import io

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from _machine import MIN_PAIRS, LoadWatch, alternate, load_text, machine, spread  # noqa: E402

#: the largest slowdown issue 12 allows against the build before the realism mechanisms
MAX_SLOWDOWN = 0.20

#: run inside the subprocess: import whichever layout the tree has, simulate its own
#: paper000_ramp cut to the given hours, print one JSON line
DRIVER = r"""
import json, os, sys, tempfile, time
hours = float(sys.argv[1]); root = sys.argv[2]
try:                                        # the simulator in rooms (sim/run/, ...)
    from rlgsim.sim.run.scenario import parse_scenario
    from rlgsim.sim.run.simulate import simulate
except ImportError:
    try:                                    # the rlgsim namespace, sim/ flat
        from rlgsim.sim.scenario import parse_scenario
        from rlgsim.sim.simulate import simulate
    except ImportError:                     # before the rlgsim namespace: top-level packages
        from sim.scenario import parse_scenario
        from sim.simulate import simulate
text = open(os.path.join(root, "scenarios", "paper000_ramp.toml"), encoding="utf-8").read()
text = f"duration_h = {hours}\n" + text     # a top-level key: before the first table
sc = parse_scenario(text, "paper000_ramp.toml")
epochs = int(round(sc.duration_s * sc.acquisition.sample_rate_hz))
tmp = tempfile.mkdtemp(prefix="rlgsim-cmp-")
out = os.path.join(tmp, "run.h5")
t0, c0 = time.perf_counter(), time.process_time()
simulate(sc, out, progress=False)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
size = os.path.getsize(out)
os.unlink(out); os.rmdir(tmp)
print(json.dumps({"epochs": epochs, "wall": wall, "cpu": cpu, "bytes": size,
                  "file": sys.modules[simulate.__module__].__file__}))
"""


def git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def default_revision() -> str:
    """The parent of the first commit touching the issue-12 modules."""
    first = git("log", "--format=%H", "--reverse", "--", "sim/chamber_controller.py",
                "sim/anomalies.py", "sim/thermal/chamber_controller.py",
                "sim/sensors/anomalies.py").splitlines()     # their paths then and now
    if not first:
        raise SystemExit("no commit touches sim/thermal/chamber_controller.py or sim/sensors/anomalies.py; "
                         "give --rev")
    return git("rev-parse", f"{first[0]}^")


def unpack(rev: str, dest: pathlib.Path) -> pathlib.Path:
    """``git archive REV`` into ``dest/tree``; returns the folder to put on the import path."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev],
                          check=True, capture_output=True).stdout
    tree = dest / "tree"
    tree.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(tree, filter="data")
    if (tree / "src" / "rlgsim" / "__init__.py").exists():
        # the namespace layout: rlgsim/ from src/rlgsim, its sim/estimators/scenarios linked in
        path = dest / "path"
        pkg = path / "rlgsim"
        shutil.copytree(tree / "src" / "rlgsim", pkg)
        for sub in ("sim", "estimators", "scenarios"):
            if (tree / sub).is_dir() and not (pkg / sub).exists():
                (pkg / sub).symlink_to(tree / sub, target_is_directory=True)
        return path
    return tree                                 # top-level sim, estimators


def run(path: pathlib.Path, root: pathlib.Path, hours: float) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(path)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    proc = subprocess.run([sys.executable, "-c", DRIVER, str(hours), str(root)], env=env,
                          capture_output=True, text=True, cwd=tempfile.gettempdir())
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise SystemExit(f"the run of {root} failed: {tail}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", default=None, help="earlier revision (default: before issue 12)")
    ap.add_argument("--hours", type=float, default=12.0, help="simulated hours per run")
    ap.add_argument("--rounds", type=int, default=MIN_PAIRS,
                    help=f"(old, new) pairs, alternating which runs first (default "
                         f"{MIN_PAIRS}, the fewest for a verdict)")
    args = ap.parse_args(argv)
    rev = git("rev-parse", args.rev) if args.rev else default_revision()
    head = git("rev-parse", "HEAD")
    dirty = bool(git("status", "--porcelain", "--", "sim", "src", "scenarios"))
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="rlgsim-rev-"))
    watch = LoadWatch()
    try:
        old_path = unpack(rev, tmp)
        old_root = tmp / "tree"
        new_path = tmp / "new"
        new_pkg = new_path / "rlgsim"
        shutil.copytree(ROOT / "src" / "rlgsim", new_pkg,
                        ignore=shutil.ignore_patterns("__pycache__"))
        for sub in ("sim", "estimators", "scenarios"):
            (new_pkg / sub).symlink_to(ROOT / sub, target_is_directory=True)
        print(f"machine: {machine()}")
        print(f"load average before: {load_text()}", flush=True)

        def report(i: int, o: dict, n: dict) -> None:
            watch.sample()
            print(f"pair {i} ({'old' if i % 2 else 'new'} first): old "
                  f"{o['epochs'] / o['wall'] / 1e6:.2f} M epochs/s ({o['wall']:.2f} s, CPU "
                  f"{o['cpu']:.2f} s), new {n['epochs'] / n['wall'] / 1e6:.2f} M epochs/s "
                  f"({n['wall']:.2f} s, CPU {n['cpu']:.2f} s); load {os.getloadavg()[0]:.2f}",
                  flush=True)
        old, new = alternate(lambda: run(old_path, old_root, args.hours),
                             lambda: run(new_path, ROOT, args.hours), max(1, args.rounds),
                             report)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ratio = [(n["epochs"] / n["wall"]) / (o["epochs"] / o["wall"]) for o, n in zip(old, new)]
    ratio_cpu = [(n["epochs"] / n["cpu"]) / (o["epochs"] / o["cpu"]) for o, n in zip(old, new)]
    print(f"scenario: each build's own paper000_ramp, {args.hours:g} h at 100 Hz "
          f"({old[0]['epochs']:,} epochs); files {old[0]['bytes'] / 1e6:.0f} MB (old), "
          f"{new[0]['bytes'] / 1e6:.0f} MB (new)")
    print(f"old: {rev[:10]} (before the issue-12 realism work unless --rev)")
    print(f"new: {head[:10]}{' + uncommitted changes' if dirty else ''} (this tree)")
    print(f"throughput, M epochs/s: old {spread([r['epochs'] / r['wall'] / 1e6 for r in old])}, "
          f"new {spread([r['epochs'] / r['wall'] / 1e6 for r in new])}")
    print(f"new / old per pair: {spread(ratio)}  (target >= {1 - MAX_SLOWDOWN:.2f}: "
          f"{watch.verdict(statistics.median(ratio) >= 1 - MAX_SLOWDOWN, len(ratio))})")
    print(f"per CPU second (less sensitive to load), new / old: {spread(ratio_cpu)}")
    print(watch.line())

if __name__ == "__main__":
    main()
