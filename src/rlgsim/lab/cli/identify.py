"""``rlgsim identify RECORDING [--device-template PRESET] [--thermal-template PRESET] -o DIR`` —
a digital twin of the recorded device (docs/identify.md; :func:`rlgsim.lab.identify.identify`).

Registered in :mod:`rlgsim.lab.cli.main` by :func:`add_subparser`; the dispatch calls :func:`run`.
"""

from __future__ import annotations

import argparse

__all__ = ["add_subparser", "run"]


def add_subparser(sub) -> None:
    """Add the ``identify`` subcommand to the ``rlgsim`` subparsers."""
    p = sub.add_parser("identify", help="identify a device and thermal preset (a digital twin) "
                                        "from one chamber recording")
    p.add_argument("recording", metavar="RECORDING",
                   help="a recording (table with a .toml sidecar) or an rlgsim dataset (.h5)")
    p.add_argument("--device-template", metavar="PRESET",
                   help="device preset whose law family and keys the twin takes (name or path; "
                        "default for a dataset: the device it was simulated with)")
    p.add_argument("--thermal-template", metavar="PRESET",
                   help="thermal preset whose topology the twin keeps (default: the device "
                        "template's thermal_preset)")
    p.add_argument("--gyro", metavar="AXIS", help="identify this gyro only (default: every "
                                                  "gyro of the recording, into one device "
                                                  "preset with each gyro's law)")
    p.add_argument("--name", help="name of the twin device (default: <template>_twin)")
    p.add_argument("-o", "--output", metavar="DIR", required=True,
                   help="folder for device.toml, thermal.toml, the replay scenario and the "
                        "report")
    p.add_argument("--suggest-programme", action="store_true",
                   help="also write <name>_next.toml: a chamber programme (a scenario on the "
                        "twin) that would separate the bias-law terms this recording could "
                        "not, with the predicted shrinkage of each standard error")
    p.add_argument("--overwrite", action="store_true",
                   help="replace files in the output folder that an earlier identification did "
                        "not write (never an input, a link or a special file)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Identify for parsed ``args``; returns the exit code."""
    from rlgsim.lab.cli.paths import input_file
    from rlgsim.lab.identify import identify
    src = input_file(args.recording, "a recording or an rlgsim dataset")
    r = identify(src, args.output, device_template=args.device_template,
                 thermal_template=args.thermal_template, name=args.name, gyro=args.gyro,
                 suggest_programme=args.suggest_programme, overwrite=args.overwrite)
    if not args.quiet:
        th = r.thermal
        print(f"identified {r.name} from {args.recording} in {r.seconds:.1f} s")
        for line in (*r.notes, *r.probe_lines):
            print(line)
        print("thermal: " + ", ".join(f"{k} ×{v:.4g}" for k, v in th.multipliers.items()))
        for k, why in th.refused.items():
            print(f"  not identified: {k}: {why}")
        print("probe RMS [°C]: " + ", ".join(f"{k} {v:.3f}" for k, v in th.rms_fitted_c.items()))
        for g in r.gyros or [r]:        # one line per gyro of a several-gyro twin
            who = f"gyro {g.axis} " if r.gyros else ""
            print(f"{who}bias law terms: {', '.join(g.laws.bias.terms) or 'constant'} "
                  f"(window RMS {g.laws.bias_rms_deg_per_h:.4g} °/h)")
            if g.scale_factor is not None:
                for line in g.scale_factor.lines:
                    print(who + line)
        if r.gyros and args.suggest_programme:
            print(f"next experiment: designed for gyro {r.next_gyro} only")
        if args.suggest_programme:
            if r.suggestion is None:
                print("next experiment: none suggested — the recording separates every "
                      "candidate term of the bias law (or gave no noise model to predict with)")
            else:
                print(f"next experiment ({r.suggestion.duration_s / 3600:.1f} h), predicted "
                      f"standard errors:")
                for line in r.suggestion.lines():
                    print(f"  {line}")
        for f in (r.device_path, r.thermal_path, r.scenario_path, r.report_path, r.next_path):
            if f is not None:
                print(f"wrote {f}")
    return 0
