"""``rlgsim navigate DATASET|RECORDING [--models FILE.json|DIR ...] [--span-h H] [-o DIR]`` —
align on the first static segment and navigate free-inertially (docs/navigation.md;
:mod:`rlgsim.lab.navigation`): solution with errors, summary, figure and report.

Registered in :mod:`rlgsim.lab.cli` by :func:`add_subparser`; the dispatch calls :func:`run`.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib

__all__ = ["add_subparser", "run"]


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"value {text!r} not allowed; must be a number > 0")
    return v


def add_subparser(sub) -> None:
    """Add the ``navigate`` subcommand to the ``rlgsim`` subparsers."""
    n = sub.add_parser("navigate", help="align and navigate a dataset or recording "
                                        "free-inertially: position, velocity, heading errors")
    n.add_argument("source", metavar="DATASET|RECORDING")
    n.add_argument("--models", nargs="+", metavar="FILE.json|DIR", default=[],
                   help="exported compensators (rlgsim study --export-models), one per gyro "
                        "axis: files named *_x.json, *_y.json, *_z.json, or a folder of them")
    n.add_argument("--temperature-probe", metavar="PROBE",
                   help="the probe behind the models' inputs T and dT/dt")
    n.add_argument("--span-h", type=_positive, metavar="H",
                   help="hours to navigate after the alignment (default: the rest of the run)")
    n.add_argument("--align-s", type=_positive, default=600.0, metavar="S",
                   help="longest alignment on the first static segment (default 600 s)")
    n.add_argument("--format", choices=("csv", "parquet"), default="csv",
                   help="solution table format (default csv)")
    n.add_argument("-o", "--output", metavar="DIR",
                   help="output folder (default ./<source stem>-navigation/)")
    n.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    n.set_defaults(handler=run)


def _output(args: argparse.Namespace, src: pathlib.Path) -> pathlib.Path:
    """The output folder, checked before any work: not an existing file, and none of the
    files it will hold (:func:`rlgsim.lab.navigation_report.write`) an input, a folder or a
    link (one line, exit status 2)."""
    from rlgsim.ground.paths import sweep_temporaries
    from rlgsim.ground.recording_sidecar import sidecar_path
    from rlgsim.lab.cli.paths import output_file, output_folder
    inputs = [src, sidecar_path(src), *args.models]      # a recording's sidecar beside it
    out = output_folder(args.output or f"{src.stem}-navigation", inputs=inputs)
    for name in (f"solution.{args.format}", "summary.csv", "navigation.png", "report.md"):
        output_file(out / name, inputs=inputs)
        sweep_temporaries(out / name)       # a killed navigate's (rlgsim.ground.atomic)
    return out


def _missing_folders(out: pathlib.Path) -> list[pathlib.Path]:
    """The folders making ``out`` will create, deepest first (``out`` and each missing
    parent), so a refusal after it can remove them all again."""
    missing = []
    out = pathlib.Path(os.path.abspath(out))
    for folder in (out, *out.parents):
        if folder.exists() or folder.is_symlink():
            break
        missing.append(folder)
    return missing


def run(args: argparse.Namespace) -> int:
    """Navigate for parsed ``args``; returns the exit code."""
    from rlgsim.lab.navigation import navigate_source
    from rlgsim.lab.navigation_models import load_models
    from rlgsim.lab.navigation_report import markdown_table, write
    from rlgsim.lab.navigation_source import open_source
    from rlgsim.lab.report import output_folder
    src = pathlib.Path(args.source)
    out = _output(args, src)
    made = _missing_folders(out)
    output_folder(out)                 # made before the work (one line if it cannot be)
    try:
        source = open_source(src)      # checked (one line) before the models read it
        try:
            models = (load_models(args.models, src, temperature_probe=args.temperature_probe)
                      if args.models else None)
            ds = navigate_source(source, models=models, align_s=args.align_s,
                                 span_s=None if args.span_h is None else args.span_h * 3600)
        finally:
            source.close()
    except BaseException:
        for folder in made:            # a refused input leaves no empty folder behind
            try:                       # (each level -o made: p1/p2/p3 made p1 and p2 too)
                folder.rmdir()
            except OSError:            # not empty after all (another process): left alone
                break
        raise
    paths = write(ds, out, args.format)
    if not args.quiet:
        print(markdown_table(ds))
        print(f"report: {paths['report']}")
    return 0
