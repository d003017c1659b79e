"""``rlgsim export DATASET_OR_RECORDING [--format csv|parquet] [-o PATH]`` — a simulated dataset
(or a recording) as a recording: one table with units in the column names, its TOML sidecar
and, for a run with calibration windows, the commanded programme (docs/recordings.md;
:mod:`rlgsim.ground.recording_export`).

Registered in :mod:`rlgsim.lab.cli` by :func:`add_subparser`; the dispatch calls :func:`run`.
"""

from __future__ import annotations

import argparse

__all__ = ["add_subparser", "run"]


def add_subparser(sub) -> None:
    """Add the ``export`` subcommand to the ``rlgsim`` subparsers."""
    e = sub.add_parser("export", help="a dataset or recording as a recording (CSV or Parquet "
                                      "table + TOML sidecar)")
    e.add_argument("source", metavar="DATASET_OR_RECORDING",
                   help="an rlgsim dataset (.h5) or a recording (table with a .toml sidecar)")
    from rlgsim.ground.recording_formats import EXPORT_FORMATS
    e.add_argument("--format", choices=tuple(EXPORT_FORMATS), default="csv",
                   help="table format (default: csv)")
    e.add_argument("-o", "--output", metavar="PATH",
                   help="output table (default: <stem>_recording.csv or .parquet next to the "
                        "source); the sidecar is PATH with .toml, the programme "
                        "<stem>_programme.csv")
    e.add_argument("--overwrite", action="store_true",
                   help="replace existing files that are not an earlier export of this table "
                        "(never an input, a link or a special file)")
    e.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    e.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Export for parsed ``args``; returns the exit code."""
    from rlgsim.ground.recording_export import export
    done = export(args.source, args.format, args.output, overwrite=args.overwrite)
    if not args.quiet:
        print(f"table: {done.table} ({done.rows} rows)")
        print(f"sidecar: {done.sidecar}")
        if done.programme is not None:
            print(f"programme: {done.programme}")
        if done.trajectory is not None:
            print(f"trajectory: {done.trajectory} (the drive's truth; the sidecar says "
                  f"platform = \"vehicle\")")
    return 0
