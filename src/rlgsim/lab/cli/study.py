"""``rlgsim study``: run a study (src/rlgsim/lab/study.py) into a report folder; ``rlgsim demo`` uses it.

    rlgsim study STUDY [-o DIR] [--quiet] [--export-models]
                                              run a shipped study (name) or a study file (path)
    rlgsim study --list                       one line per shipped study

The report folder holds report.md, report.html (figures embedded), one CSV per table, the
figures as PNG and, under data/, the simulated datasets (reused when the study is run again
with the same scenarios, seeds and unit). With ``--export-models`` (or ``export_models = true``
in the study file) it also holds models/<compensator>.json, .c and .h: every fitted compensator
as JSON and as a C function (docs/compensator_export.md).
"""

from __future__ import annotations

import pathlib
import time

from rlgsim.ground.errors import UserInputError

DEMO_STUDY = "demo"
DEMO_DIR = "rlgsim-demo"


def add_subparser(sub) -> None:
    """Add the ``study`` subcommand to the ``rlgsim`` subparsers."""
    s = sub.add_parser("study", help="run a study (device, scenarios, compensators, scores) "
                                     "into a report folder")
    s.add_argument("study", metavar="STUDY", nargs="?",
                   help="a shipped study's name (see 'rlgsim study --list') or a path to a "
                        ".toml study file")
    s.add_argument("-o", "--output", metavar="DIR",
                   help="report folder (default: ./<study name>-study/)")
    s.add_argument("--list", action="store_true", help="list the shipped studies")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bars, no summary")
    s.add_argument("--export-models", action="store_true",
                   help="also write every fitted compensator as models/<name>.json and as a C "
                        "function (.c, .h) into the report folder")
    s.set_defaults(handler=main)


def list_studies() -> None:
    from rlgsim.lab.study import list_studies as shipped
    studies = shipped()
    width = max((len(n) for n, _ in studies), default=0)
    for name, desc in studies:
        print(f"{name:<{width}}  {desc}")


def run(ref: str, out_dir: str | pathlib.Path | None, *, quiet: bool,
        summary: bool = True, export_models: bool | None = None) -> pathlib.Path:
    """Run study ``ref`` into ``out_dir``; unless ``quiet``, show progress and (with
    ``summary``) print where the report is. ``export_models``: see
    :func:`rlgsim.lab.study.run_study`. Returns the path of report.md."""
    from rlgsim.lab.study import load_study, run_study
    from rlgsim.lab.cli.paths import name_path, output_folder
    study = load_study(ref)
    out = output_folder(out_dir if out_dir else
                        name_path(study.name, suffix="-study", source=study.source,
                                  key="study.name"), inputs=[study.source])
    t0 = time.perf_counter()
    if not quiet and summary:
        print(f"study {study.name}: {study.description}")
    md = run_study(study, out, progress=not quiet, export_models=export_models)
    if not quiet and summary:
        print(f"study {study.name} done in {time.perf_counter() - t0:.1f} s")
        print(f"  report: {md}")
        print(f"  report (HTML, figures embedded): {md.with_name('report.html')}")
    return md


def main(args) -> int:
    """Handler of ``rlgsim study`` (argparse namespace)."""
    if args.list:
        if args.study:
            raise UserInputError("give either STUDY or --list, not both "
                                 "(see 'rlgsim study --help')")
        list_studies()
        return 0
    if not args.study:
        raise UserInputError("missing STUDY: a shipped study's name (rlgsim study --list) or a "
                             "path to a .toml study file (see 'rlgsim study --help')")
    run(args.study, args.output, quiet=args.quiet,
        export_models=True if getattr(args, "export_models", False) else None)
    return 0


def demo(quiet: bool) -> pathlib.Path:
    """``rlgsim demo``: the demo study into ./rlgsim-demo/."""
    out = pathlib.Path(DEMO_DIR)
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"{out}: cannot create the demo directory "
                             f"({exc.strerror or exc})") from None
    md = run(DEMO_STUDY, out, quiet=quiet, summary=False)
    print(f"demo study done: report {md} (Markdown) and {md.with_name('report.html')} "
          f"(HTML, figures embedded)")
    return md
