"""``rlgsim calibrate DATASET [-o table.csv] [--plot]`` — the turntable calibration campaign.

Runs :func:`rlgsim.estimators.calibration.run_campaign` on a dataset (one Kalman calibration per
calibration window, in parallel processes), writes the parameter-versus-temperature table as
CSV, adds it to the dataset as the group ``calibration`` (docs/dataset.md), and with ``--plot``
draws every parameter against temperature with ±1σ and the truth.

Registered in :mod:`rlgsim.lab.cli` by :func:`add_subparser`; the dispatch calls :func:`run`. User
mistakes (a missing file, not a dataset, no calibration windows, an unknown probe) become
:class:`~rlgsim.ground.errors.UserInputError` (one line, exit code 2). Windows that cannot be calibrated
do not stop the campaign: the table says which and why, and they are listed on stderr.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import ARCSEC, G0
from rlgsim.lab.cli.arg_types import number, whole_number

#: UDUNITS spelling of the table's units.
_UDUNITS = {"deg/h": "degree h-1", "ppm": "1e-6", "arcsec": "arcsecond",
            "ug": "1e-6 standard_free_fall", "degC": "degC", "s": "s", "1": "1",
            "mm s-1": "mm s-1", "arcsec-1": "arcsecond-1", "s-1": "s-1"}


def add_subparser(sub) -> None:
    """Add the ``calibrate`` subcommand to the ``rlgsim`` subparsers."""
    def positive(name: str):
        return number(0.0, strict=True, name=name)
    c = sub.add_parser("calibrate", help="turntable Kalman calibration of every calibration "
                                         "window of a dataset → parameter-vs-temperature table")
    c.add_argument("dataset", metavar="DATASET", help="an rlgsim dataset (.h5) or a recording "
                                                      "(docs/recordings.md)")
    c.add_argument("--programme", metavar="PROGRAMME",
                   help="a recording's commanded turntable programme: a programme CSV or the "
                        "scenario it ran (name or .toml)")
    c.add_argument("-o", "--output", metavar="TABLE.csv",
                   help="output table (default: <dataset stem>_calibration.csv next to it)")
    c.add_argument("--plot", action="store_true",
                   help="also draw every parameter vs temperature (PNG next to the table)")
    c.add_argument("--probe", metavar="NAME",
                   help="probe whose temperature is the x axis of the plots (default: first)")
    c.add_argument("--workers", type=whole_number(), metavar="N",
                   help="processes (default: min(2, CPUs))")
    c.add_argument("--no-dataset", action="store_true",
                   help="do not add the calibration group to the dataset")
    c.add_argument("--arw-deg-per-sqrt-h", type=positive("ARW"), metavar="X",
                   help="gyro angle random walk for the filter (default: the dataset's device "
                        "preset, else 0.002)")
    c.add_argument("--vrw-ug-per-sqrt-hz", type=positive("VRW"), metavar="X",
                   help="accelerometer velocity random walk (default: device preset, else 10)")
    c.add_argument("--gyro-sf-pulse-per-arcsec", type=positive("the scale factor"),
                   metavar="K", help="nominal gyro scale factor (default: device preset, 2.14)")
    c.add_argument("--accel-sf-pulse-per-s-per-g", type=positive("the scale factor"),
                   metavar="K", help="nominal accelerometer scale factor (default: device "
                                     "preset, 5000)")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary")
    c.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the campaign for parsed ``args``; returns the exit code (0, also when some windows
    failed — the table says why)."""
    from rlgsim.estimators.calibration import (CampaignError, CampaignSettings, find_windows,
                                               open_reader, run_campaign)
    from rlgsim.ground.recording import is_recording as _is_recording
    from rlgsim.estimators.strapdown import SensorModel

    from rlgsim.lab.cli.paths import check_writable, input_file, output_file
    path = input_file(args.dataset, "an rlgsim dataset or a recording",
                      missing="no such dataset file")
    if args.programme is not None and os.path.lexists(args.programme):
        input_file(args.programme, "a programme CSV or a scenario .toml")
    out = check_writable(output_file(args.output or
                                     path.with_name(f"{path.stem}_calibration.csv"),
                                     inputs=[path, args.programme or ""]))
    source = path
    if args.programme is not None or _is_recording(path):
        from rlgsim.lab.recordings import calibration_source
        source = calibration_source(path, args.programme)     # recording + programme
    try:
        reader = open_reader(source)
        nominal = reader.nominal()
        probes = reader.probe_names()
        n_windows = len(find_windows(reader.segments()))
        reader.close()
    except CampaignError as exc:
        raise UserInputError(str(exc)) from None
    if args.probe is not None and args.probe not in probes:
        raise UserInputError(f"--probe {args.probe}: no such probe; the dataset's probes are "
                             f"{', '.join(probes) or 'none'}")
    if args.gyro_sf_pulse_per_arcsec or args.accel_sf_pulse_per_s_per_g:
        kg = (args.gyro_sf_pulse_per_arcsec / ARCSEC if args.gyro_sf_pulse_per_arcsec
              else nominal.k_g)
        ka = (args.accel_sf_pulse_per_s_per_g / G0 if args.accel_sf_pulse_per_s_per_g
              else nominal.k_a_pos)
        nominal = SensorModel.nominal(kg, ka)
    options = CampaignSettings(nominal=nominal, arw_deg_per_sqrt_h=args.arw_deg_per_sqrt_h,
                               vrw_ug_per_sqrt_hz=args.vrw_ug_per_sqrt_hz, workers=args.workers)
    bar = None
    if not args.quiet:
        from tqdm import tqdm
        bar = tqdm(total=n_windows, unit="window", desc="rlgsim calibrate", leave=False,
                   dynamic_ncols=True,
                   delay=1.0, file=sys.stderr)
    t0 = time.perf_counter()
    try:
        result = run_campaign(source, options,
                              progress=bar.update if bar is not None else None)
    except CampaignError as exc:
        raise UserInputError(str(exc)) from None
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    table = result.write_csv(out, units_in_names=True)
    wrote_group = False
    if not args.no_dataset and source is path:        # recordings are never modified
        try:
            write_group(path, result)
            wrote_group = True
        except OSError as exc:
            print(f"rlgsim: warning: could not add the calibration group to {path} "
                  f"({exc}); the table is in {table}", file=sys.stderr)
    figures = []
    if args.plot:
        from rlgsim.estimators.calibration_plot import plot_campaign
        figures = plot_campaign(result, table.with_suffix(""), probe=args.probe)
    for r in result.failed:
        print(f"rlgsim: window {r['window']} ({r['label']}, t = {r['t0_s']:.0f}–{r['t1_s']:.0f} "
              f"s) failed: {r['message']}", file=sys.stderr)
    if not args.quiet:
        n = len(result.rows)
        print(f"calibrated {n - len(result.failed)} of {n} windows in {wall:.1f} s "
              f"({wall / max(n, 1):.2f} s per window, {result.meta['workers']} process(es))")
        print(f"table: {table}")
        if wrote_group:
            print(f"dataset group 'calibration' written to {path}")
        for f in figures:
            print(f"figure: {f}")
    return 0


def write_group(path: str | os.PathLike, result) -> None:
    """Add (or replace) the group ``calibration`` of the dataset: written under a temporary
    name, then moved into place (:func:`rlgsim.sim.writer.dataset.add_group`), so an interrupted write
    never leaves a half group named ``calibration``."""
    from rlgsim.estimators.calibration import AXES, PARAMETERS, unit_of
    from rlgsim.ground.dataset_format import CALIBRATION
    from rlgsim.sim.writer.dataset import add_group

    rows = result.rows
    attrs = {"nominal_gyro_sf_pulse_per_arcsec": result.nominal.k_g * np.pi / 180 / 3600,
             "nominal_accel_sf_pulse_per_s_per_g": result.nominal.k_a_pos * G0}
    with add_group(path, CALIBRATION, "turntable Kalman calibration per calibration window "
                                      "(rlgsim calibrate; docs/calibration.md)", attrs) as w:
        w.coordinate("window", np.array([r["window"] for r in rows], dtype=np.int32),
                     units="1", dtype=np.int32, description="calibration window index")
        w.coordinate("probe", result.probes or [""], description="thermometer probe")

        def col(name):
            return np.array([float(r.get(name, np.nan)) if r.get(name) is not None else np.nan
                             for r in rows])
        w.variable("label", ("window",), dtype=str, data=[r["label"] for r in rows],
                   description="window label (timeline)")
        w.variable("status", ("window",), dtype=str, data=[r["status"] for r in rows],
                   description="'ok' or 'failed'")
        w.variable("message", ("window",), dtype=str, data=[r["message"] for r in rows],
                   description="why the window failed (empty when ok)")
        for name, desc in (("t0_s", "window start"), ("t1_s", "window end")):
            w.variable(name[:-2], ("window",), units="s", data=col(name), description=desc)
        w.variable("iterations", ("window",), units="1", data=col("iterations"),
                   description="filter passes with feedback")
        w.variable("residual_rms", ("window",), units="mm s-1", data=col("residual_rms_mm_s"),
                   description="RMS navigated velocity at the measurement epochs, last pass")
        w.variable("nis", ("window",), units="1", data=col("nis"),
                   description="mean normalised innovation squared, last pass (≈ 3 if the "
                               "noise model fits)")
        temps = np.array([[r.get(f"temp_{p}_c", np.nan) for p in result.probes] for r in rows]
                         ) if result.probes else np.full((len(rows), 1), np.nan)
        w.variable("temperature_mean", ("window", "probe"), units="degC", data=temps,
                   description="mean probe reading over the window (NaN if a reading is NaN)")
        has_truth = any(np.isfinite(r.get(f"{PARAMETERS[0].name}_true", np.nan)) for r in rows)
        for p in PARAMETERS:
            u = _UDUNITS[unit_of(p.name)]
            w.variable(p.name, ("window",), units=u, data=col(p.name),
                       description=f"{p.name} estimate ({p.unit}; scale factors as ppm of the "
                                   f"nominal)")
            w.variable(f"{p.name}_sigma", ("window",), units=u, data=col(f"{p.name}_sigma"),
                       description=f"1σ of {p.name} (filter covariance)")
            if has_truth:
                w.variable(f"{p.name}_true", ("window",), units=u, data=col(f"{p.name}_true"),
                           description=f"true {p.name} averaged over the window, in the "
                                       f"accelerometer frame (simulated data)")
                w.variable(f"{p.name}_error", ("window",), units=u, data=col(f"{p.name}_error"),
                           description=f"estimate − truth of {p.name}")
        for a in AXES:
            w.variable(f"gyro_sf_{a}_pulse_per_arcsec", ("window",), units="arcsecond-1",
                       data=col(f"gyro_sf_{a}_pulse_per_arcsec"),
                       description=f"gyro {a} scale factor [pulses/arcsec]")
            for s in ("pos", "neg"):
                w.variable(f"accel_sf_{s}_{a}_pulse_per_s_per_g", ("window",), units="s-1",
                           data=col(f"accel_sf_{s}_{a}_pulse_per_s_per_g"),
                           description=f"accelerometer {a} {s} scale factor [pulses/s at 1 g]")
