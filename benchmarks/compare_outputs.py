"""Are two builds' outputs the same? The reference datasets and every shipped study's tables.

A restructuring (issue 24's move of the lab wing, a function split, a speed-up that must change
no figure) is checked by making the outputs with the build before it and with the build after
it, then comparing them:

    python benchmarks/compare_outputs.py make BEFORE_DIR      # with the build before
    python benchmarks/compare_outputs.py make AFTER_DIR       # with the build after
    python benchmarks/compare_outputs.py compare BEFORE_DIR AFTER_DIR

``make`` runs the installed ``rlgsim`` (``python -m rlgsim`` of this interpreter) on the
reference scenarios (``rlgsim run``) and the shipped studies (``rlgsim study``); ``--studies``
and ``--scenarios`` choose a subset. ``compare`` prints one line per file that differs or is
missing and exits 1 if any does, 0 if none:

* **HDF5 datasets** are compared by content: every group, every array (dtype, shape and raw
  bytes; text arrays element by element), the dimension scales each array is attached to (by
  name), and every attribute, except ``scenario_source`` — the path of the scenario file the run
  read, which names the checkout. Two files whose contents agree but were written by different
  h5py/HDF5 releases may differ in their layout bytes; the content is what a build decides.
* **Tables** (CSV, Markdown), **exported models** (JSON, C, TOML): by text, except what a run's
  duration decides — a CSV column or row naming a time (``time``, ``wall``, ``elapsed``,
  ``cpu``), a Markdown table whose header or caption names one, and the report's provenance lines that
  state the run time. Figures (PNG) are not compared: their bytes carry matplotlib's metadata.

Written by hand: no library compares two HDF5 files by content with named exceptions
(``h5diff`` is a separate C tool not installed with h5py).
"""

from __future__ import annotations

import argparse
import csv
import io
import pathlib
import re
import subprocess
import sys
from typing import Iterator

import h5py
import numpy as np

REFERENCE_SCENARIOS = ("quickstart", "paper000_short", "paper003_cycles", "demo_cycle",
                       "paper001_test")
SHIPPED_STUDIES = ("demo", "paper001", "paper002", "paper003", "paper000", "vehicle")
PATH_ATTRIBUTES = frozenset({"scenario_source"})
# HDF5's dimension-scale bookkeeping holds object references (addresses); the scales each
# dataset is attached to are compared by name instead (``#dims``)
SCALE_LINKS = frozenset({"DIMENSION_LIST", "REFERENCE_LIST"})
TEXT_SUFFIXES = (".csv", ".md", ".json", ".c", ".h", ".toml")
TIMING = re.compile(r"time|wall|elapsed|cpu", re.IGNORECASE)


def make(out: pathlib.Path, scenarios: list[str], studies: list[str]) -> None:
    """Run the installed build's reference scenarios and studies into ``out``."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SystemExit(f"compare_outputs: {out} is not an empty folder; make the outputs "
                         f"into a new one")
    out.mkdir(parents=True, exist_ok=True)
    rlgsim = [sys.executable, "-m", "rlgsim"]
    commands = [(f"run {name}", ["run", name, "-o", str(out / f"{name}.h5")])
                for name in scenarios]
    commands += [(f"study {name}", ["study", name, "-o", str(out / f"{name}-study")])
                 for name in studies]
    for label, args in commands:
        print(label, flush=True)
        done = subprocess.run([*rlgsim, *args, "--quiet"], stdout=subprocess.DEVNULL)
        if done.returncode:        # rlgsim has printed its own one-line reason
            raise SystemExit(f"compare_outputs: `rlgsim {' '.join(args)}` failed "
                             f"(exit {done.returncode})")


def _scale_names(ds: h5py.Dataset) -> object:
    """The names of the dimension scales each axis of ``ds`` is attached to; a dimension list
    HDF5 cannot follow (references into another file) is a value of its own, not a crash."""
    try:
        return [[scale.name for scale in dim.values()] for dim in ds.dims]
    except (RuntimeError, KeyError, ValueError) as err:
        return f"unreadable dimension list ({type(err).__name__})"


def _h5_items(path: pathlib.Path) -> dict[str, object]:
    """Every attribute and array of an HDF5 file, keyed by its path, as comparable values."""
    items: dict[str, object] = {}

    def attrs(name: str, obj: h5py.HLObject) -> None:
        for key, value in obj.attrs.items():
            if key not in PATH_ATTRIBUTES and key not in SCALE_LINKS:
                items[f"{name}@{key}"] = _comparable(value)

    with h5py.File(path, "r") as f:
        attrs("/", f)

        def visit(name: str, obj: h5py.HLObject) -> None:
            attrs(name, obj)
            if isinstance(obj, h5py.Dataset):
                items[name] = (str(obj.dtype), obj.shape, _comparable(obj[()]))
                items[f"{name}#dims"] = _scale_names(obj)

        f.visititems(visit)
    return items


def _comparable(value: object) -> object:
    """A value's content: raw bytes of a numeric array, the elements of a text/object one."""
    if isinstance(value, (str, bytes)):
        return value
    array = np.asarray(value)
    if array.dtype.kind == "O":
        return [str(v) for v in array.ravel().tolist()]
    return array.tobytes()


def _csv_rows(text: str) -> list[list[str]]:
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return rows
    keep = [i for i, head in enumerate(rows[0]) if not TIMING.search(head)]
    return [[row[i] for i in keep if i < len(row)] for row in rows
            if not (row and TIMING.search(" ".join(row[:2])))]


#: A Markdown table's caption (the text line above it) that says the table is a run's timing.
TIMING_CAPTION = re.compile(r"wall time|running time|elapsed|cpu time", re.IGNORECASE)


def _md_tables(text: str) -> list[str]:
    """The Markdown tables' rows, a table whose header names a time, or whose caption names a
    wall/CPU time (paper000's "Wall time" table of steps: header ``step | s``), left out."""
    rows: list[str] = []
    in_table = skip = False
    caption = ""
    for line in text.splitlines():
        if line.startswith("|"):
            if not in_table:
                skip = bool(TIMING.search(line) or TIMING_CAPTION.search(caption))
            if not skip and not re.search(r"running time|wall|elapsed", line, re.IGNORECASE):
                rows.append(line)
            in_table = True
        else:
            in_table = False
            if line.strip():
                caption = line
    return rows


def _same(a: pathlib.Path, b: pathlib.Path) -> bool:
    if a.suffix == ".h5":
        left, right = _h5_items(a), _h5_items(b)
        return left.keys() == right.keys() and all(
            _equal(left[k], right[k]) for k in left)
    text_a, text_b = a.read_text(encoding="utf-8"), b.read_text(encoding="utf-8")
    if a.suffix == ".csv":
        return _csv_rows(text_a) == _csv_rows(text_b)
    if a.suffix == ".md":
        return _md_tables(text_a) == _md_tables(text_b)
    return text_a == text_b


def _equal(x: object, y: object) -> bool:
    return bool(x == y) if not isinstance(x, tuple) else (
        x[0] == y[0] and x[1] == y[1] and x[2] == y[2])  # type: ignore[index]


def _files(root: pathlib.Path) -> Iterator[pathlib.Path]:
    for path in sorted(root.rglob("*")):
        if path.is_file() and path.suffix in (".h5", *TEXT_SUFFIXES) \
                and path.name != "timing.csv":
            yield path


def compare(a: pathlib.Path, b: pathlib.Path) -> int:
    """Print what differs between two output folders; the number of such files."""
    bad = n = 0
    for path in _files(a):
        other = b / path.relative_to(a)
        n += 1
        if not other.exists():
            print(f"missing  {other}")
            bad += 1
        elif not _same(path, other):
            print(f"differs  {path.relative_to(a)}")
            bad += 1
    extra = [p for p in _files(b) if not (a / p.relative_to(b)).exists()]
    for path in extra:
        print(f"only in {b}: {path.relative_to(b)}")
    print(f"{n} files compared (scenario_source and timing aside): {bad} differ or are missing,"
          f" {len(extra)} only in the second folder")
    return bad + len(extra)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    mk = sub.add_parser("make", help="make the outputs of the installed build")
    mk.add_argument("out", type=pathlib.Path)
    mk.add_argument("--scenarios", nargs="*", default=list(REFERENCE_SCENARIOS))
    mk.add_argument("--studies", nargs="*", default=list(SHIPPED_STUDIES))
    cmp = sub.add_parser("compare", help="compare two output folders")
    cmp.add_argument("a", type=pathlib.Path)
    cmp.add_argument("b", type=pathlib.Path)
    args = ap.parse_args(argv)
    if args.command == "make":
        try:
            make(args.out, args.scenarios, args.studies)
        except SystemExit as stop:
            print(stop, file=sys.stderr)
            return 2
        return 0
    for folder in (args.a, args.b):
        if not folder.is_dir() or next(_files(folder), None) is None:
            print(f"compare_outputs: {folder} is not a folder of outputs", file=sys.stderr)
            return 2
    return 1 if compare(args.a, args.b) else 0


if __name__ == "__main__":
    sys.exit(main())
