"""Recordings as the runs of a study (docs/recordings.md, docs/studies.md).

A study's ``train``/``test`` list may name a recording — a table file with its sidecar, or the
sidecar, relative to the study file — instead of a scenario::

    train = ["my_gyro_run1.csv"]
    test = [{scenario = "my_gyro_run2.parquet", skip_h = 1}]

Such a run is not simulated (:func:`rlgsim.lab.recordings.recording_path` recognises it):
:func:`recording_series` builds the same window series as
:func:`rlgsim.lab.studies.runs.read_run` builds from a dataset — the measured bias is the
window's mean rate (pulses over the sidecar's nominal scale factor, or the rate columns) minus
the Earth rate on the gyro axis (site latitude and ``[orientation]``, a static mount); the
inputs are the window means and least-squares slopes of the probe readings and the UHFO — and
the truth series are NaN: a recording has none, so the truth-based scores are absent and the
report says so. Windows holding a dropout, or not powered throughout (``power_on``), are
dropped.

The recipes that take recordings (bias_compensation, gradient_selection, environments) describe
them in their reports with :func:`run_origin` and :func:`recordings_paragraph`.
"""

from __future__ import annotations

import pathlib

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.gyro_axis import choose_gyro
from rlgsim.ground.recording import Recording, load_recording
from rlgsim.lab.windows import recording_windows, uhfo_column

__all__ = ["check_recording_run", "recorded_labels", "recording_series", "recordings_paragraph",
           "run_origin"]


def _axis(rec: Recording, gyro: str | None, where: str) -> str:
    return choose_gyro(rec.gyro_axes, gyro, where=where, name=rec.path.name,
                       unknown="{where}: data.gyro: value {gyro!r} not allowed; recording "
                               "{name} has gyro axes {axes}",
                       several="{where}: data.gyro: missing: recording {name} has {n} gyros "
                               "({axes}); say which one")


def _rates(rec: Recording) -> tuple[float, float]:
    f = rec.sample_rate_hz
    return f, rec.sidecar.temperature_rate_hz or f


def check_recording_run(study, path: pathlib.Path, spec) -> Recording:
    """Load and validate a recording for the study's features (window length, probes, gyro
    axis, UHFO), before anything is fitted; one-line errors naming the study and the file."""
    from rlgsim.estimators.features import samples_per_window
    rec = load_recording(path)
    where = str(study.source)
    for rate in _rates(rec):
        try:
            samples_per_window(rate, spec.window_s)
        except ValueError as exc:
            raise UserInputError(f"{where}: data.window_s: {exc} (recording {path.name})"
                                 ) from None
    _axis(rec, spec.gyro, where)
    names = rec.probe_names
    for key, wanted in (("temperature", (spec.temperature,) if spec.temperature else ()),
                        ("probes", spec.probes), ("gradients", spec.gradients)):
        for n in wanted:
            if n not in names:
                raise UserInputError(f"{where}: features.{key}: unknown probe {n!r}; recording "
                                     f"{path.name} has {', '.join(names) or 'no probes'}")
    if spec.uhfo and not any(k == "uhfo" for k, _, _ in rec.kinds.values()):
        raise UserInputError(f"{where}: features.uhfo: recording {path.name} logs no UHFO "
                             f"(uhfo_v or uhfo_<axis>_v)")
    if rec.gyro_axes and rec.kinds[rec._column_of("gyro", rec.gyro_axes[0])[0]][1] == "pulses" \
            and rec.sidecar.gyro_sf_pulse_per_arcsec is None:
        raise UserInputError(f"{rec.sidecar.path}: gyro.scale_factor_pulses_per_arcsec missing; "
                             f"the study needs it to turn pulses into rates")
    return rec


def recording_series(path: pathlib.Path, config, label: str, ctx, skip_s: float = 0.0
                     ) -> dict:
    """The fields of the :class:`~rlgsim.lab.studies.runs.RunSeries` of a recording (module
    docstring; the windows: :func:`rlgsim.lab.windows.recording_windows`); runs.py builds the
    series (this module imports nothing from it)."""
    from rlgsim.estimators.columns import Columns
    rec = load_recording(path)
    W = config.window_s
    axis = _axis(rec, config.gyro, str(ctx.source))
    uhfo = None
    if config.uhfo:
        uhfo = uhfo_column(rec, axis)
        if uhfo is None:
            raise UserInputError(f"{ctx.source}: features.uhfo: recording {path.name} has no "
                                 f"UHFO column for gyro {axis}")
    means = tuple(dict.fromkeys(((config.temperature,) if config.temperature else ())
                                + tuple(config.probes) + tuple(config.gradients)))
    w = recording_windows(rec, axis, W, means,
                          (config.temperature,) if config.temperature else (), uhfo)
    n_win = w["n_win"]
    if n_win == 0:
        raise UserInputError(f"{ctx.source}: data.window_s: recording {path.name} is shorter "
                             f"than one {W:g} s window")
    y, earth = w["y"], w["earth"]
    cols = config.columns(w)
    keep = ~w["dropout"]
    if "power" in w:
        keep &= w["power"] >= 1.0
    keep &= np.isfinite(y) & np.all([np.isfinite(v) for v in cols.values()], axis=0) \
        if cols else np.isfinite(y)
    keep &= np.arange(n_win) * W >= skip_s - 1e-9
    nan = np.full(int(keep.sum()), np.nan)
    return dict(label=label, path=path, seed=0, device_seed=0,
                time_s=((np.arange(n_win) + 1) * W)[keep], y=y[keep], true_bias=nan,
                true_random=nan.copy(), X=Columns({k: v[keep] for k, v in cols.items()}),
                earth_deg_per_h=earth, coefficients={})


# ------------------------------------------------------------------------------ report text
def run_origin(run) -> str:
    """Where a run's data come from (``run`` a :class:`~rlgsim.lab.studies.runs.LoadedRun`):
    its scenario, seeds and dataset, or its recording."""
    if run.scenario is None:
        return f"recording {run.series.path.name} (no truth)"
    return (f"scenario {run.scenario.name}, seed {run.series.seed}, device_seed "
            f"{run.series.device_seed}, dataset {run.series.path.name} "
            f"({'reused' if run.reused else 'simulated'})")


def recorded_labels(runs: dict, specs) -> list[str]:
    """Labels of the runs among ``specs`` (RunSpecs, each once) that are recordings."""
    return [s.label for s in dict.fromkeys(specs) if runs[s.key].scenario is None]


def recordings_paragraph(labels: list[str], truth: bool) -> str:
    """The report's paragraph on recorded runs: what is absent and why. ``truth``: whether
    every test run still carries the truth (only train runs are recordings)."""
    return (f"Recorded runs (docs/recordings.md): {', '.join(labels)}. A recording has no "
            f"ground truth, so "
            + ("the truth-based scores (rmse_true, mae_true, r2_true, resid_std_true, "
               "law_resid_std, the oracle) are absent (—) and the rankings are judged by the "
               "paper's score only; every paper-style table is computed as for a simulated "
               "run." if not truth else
               "only the simulated test runs are scored against the truth."))
