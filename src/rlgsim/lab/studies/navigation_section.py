"""The navigation section of a study report (docs/navigation.md, docs/studies.md).

:func:`add_section` puts a navigation run (:func:`rlgsim.lab.navigation.navigate`) into a
:class:`~rlgsim.lab.report.Report`: the conditions, one table of the scores per variant (raw,
the study's compensators, the oracles, the truth floor), one sentence per observed ranking with
its reason (:func:`rlgsim.lab.navigation_report.ranking_reasons`) and the error figure.

:func:`paper000_navigation` is paper 000's: its IMU navigates as it is, on the test run, after
the alignment on the lead-in; the compensators' variants are the system-level compensated
datasets (pulses mapped to the desired temperature by eqs. 24–29) with the models' biases at
that temperature removed as constants (the navigator's nominal pulse weights stay: the models'
scale factors at the desired temperature are not applied, for no variant).
"""

from __future__ import annotations

import pathlib
from typing import Any

import numpy as np

from rlgsim.ground.units import DEG, HOUR, MICRO_G
from rlgsim.lab.report import Report, Table

#: hours navigated after the alignment in the studies (or the rest of the run, if shorter)
STUDY_SPAN_H = 8.0


def add_section(rep: Report, ds, intro: str, *, csv_name: str = "navigation.csv") -> None:
    """Heading, conditions, scores table, ranking reasons and figure of navigation ``ds``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rlgsim.lab.navigation_report import COLUMNS, ranking_reasons, summary_frame
    rep.heading("Navigation: free-inertial position and heading errors", 2)
    a = ds.attrs
    rep.paragraph(
        f"{intro} Aligned on {a['align_start_s']:g}–{a['align_end_s']:g} s (coarse levelling "
        f"and gyrocompassing, then a zero-velocity Kalman filter), then free-inertial "
        f"navigation to {a['navigation_end_s']:g} s at latitude {a['latitude_deg']:g}° "
        f"(docs/navigation.md); vertical channel {a['vertical_channel']}. Radial error rate: "
        "least-squares slope of the horizontal error against time. Residual errors: what "
        "each variant's increments differ from the truth's, 100-s means, RMS of the vector.")
    df = summary_frame(ds)
    keys = [(k, h) for k, h, _ in COLUMNS if k in df]
    rows = [[name, *[float(r[k]) for k, _ in keys]] for name, r in df.iterrows()]
    rep.table(Table("Navigation scores per variant", ["variant", *[h for _, h in keys]], rows,
                    csv_name=csv_name,
                    note="raw: nominal pulse weights; oracle (gyros): the true gyro "
                         "temperature law removed; oracle: gyro and accelerometer laws "
                         "removed; truth: the exact increments (the mechanization's floor)."))
    rep.bullets(ranking_reasons(ds))
    t_h = (ds["time"].values - a["align_end_s"]) / 3600.0
    fig, axes = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    for v in ds["variant"].values:
        sel = ds.sel(variant=v)
        axes[0].semilogy(t_h, np.maximum(sel["horizontal_error_m"].values, 1e-6), label=str(v))
        axes[1].plot(t_h, sel["heading_error_arcmin"].values, label=str(v))
    axes[0].set_ylabel("horizontal error [m]")
    axes[1].set_ylabel("heading error [′]")
    axes[1].set_xlabel("time since alignment [h] (Schuler 84.4 min, Earth rate 24 h)")
    axes[0].legend(fontsize="small")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    rep.figure(fig, "navigation", "Free-inertial navigation errors per variant after the "
                                  "alignment; the Schuler oscillation (84.4 min) modulates "
                                  "the growth.")
    plt.close(fig)


def paper000_navigation(data_path: pathlib.Path, desired: dict[str, dict], desired_c: float,
                        compensators: dict[str, str]) -> tuple[Any, str]:
    """Paper 000's navigation run and its introduction (module docstring). ``desired``:
    parameter → model → value at ``desired_c`` (°/h, µg); ``compensators``: model key →
    label."""
    from rlgsim.lab.navigation import navigate
    from rlgsim.lab.navigation_source import open_source
    src = open_source(data_path)
    try:
        rest_h = (src.n - src.start) / src.rate_hz / HOUR
    finally:
        src.close()
    others: dict[str, Any] = {}
    for key, label in compensators.items():
        path = data_path.parent / f"{data_path.stem}_compensated_{key}.h5"
        if not path.exists():
            continue
        others[f"{label} (to {desired_c:g} °C)"] = {
            "path": path,
            "gyro_bias": np.array([desired[f"gyro_bias_{a}"][key] for a in "xyz"]) * DEG / HOUR,
            "accel_bias": np.array([desired[f"accel_bias_{a}"][key] for a in "xyz"]) * MICRO_G}
    span_h = min(STUDY_SPAN_H, rest_h - 0.25)          # the alignment takes at most 600 s
    ds = navigate(data_path, others=others, span_s=span_h * HOUR)
    return ds, (f"Paper 000's IMU navigates as it is, on the campaign run ({span_h:g} h "
                         "after the alignment; the turntable keeps running its calibration "
                         "sequence, so scale-factor and misalignment errors times the table "
                         f"rate add to the biases). The compensated variants use the pulses "
                         f"compensated to {desired_c:g} °C (eqs. 24–29) with the models' biases "
                         f"at {desired_c:g} °C removed; no variant applies a scale-factor "
                         "model (nominal pulse weights throughout).")


def _window_predictor(ends: np.ndarray, pred_deg_h: np.ndarray, window_s: float, mount: int):
    """f(t) → (m, 3) [rad/s]: the prediction of the window holding t on axis ``mount``
    (0 outside the windows)."""
    ends = np.asarray(ends, float)
    vals = np.asarray(pred_deg_h, float) * DEG / HOUR

    def f(t: np.ndarray) -> np.ndarray:
        j = np.searchsorted(ends, t, side="left")
        jj = np.minimum(j, ends.size - 1)
        ok = (j < ends.size) & (t > ends[jj] - window_s) & np.isfinite(vals[jj])
        out = np.zeros((t.size, 3))
        out[:, mount] = np.where(ok, vals[jj], 0.0)
        return out
    return f


def single_gyro_navigation(data_path: pathlib.Path, gyro: str | None, ends: np.ndarray,
                           predictions: dict[str, np.ndarray], window_s: float,
                           mount: int = 1, note: str = "") -> tuple[Any, str]:
    """The navigation section of a single-gyro study: the test run's gyro as the North axis
    (``mount``) of an otherwise ideal IMU (:func:`rlgsim.lab.navigation_source.
    single_gyro_source`), each compensator's window prediction [°/h] subtracted."""
    from rlgsim.lab.navigation import navigate_source
    from rlgsim.lab.navigation_source import single_gyro_source
    src = single_gyro_source(data_path, gyro, mount)
    try:
        rest_h = (src.n - src.start) / src.rate_hz / HOUR
        span_h = min(STUDY_SPAN_H, rest_h - 0.25)
        models = {name: _window_predictor(ends, p, window_s, mount)
                  for name, p in predictions.items()}
        ds = navigate_source(src, models=models, span_s=span_h * HOUR)
    finally:
        src.close()
    ds.attrs["compensation"] = "the compensators' window predictions subtracted from the gyro"
    return ds, (f"The device has one gyro, so it navigates as the {'xyz'[mount]} "
                         f"(North) axis of an otherwise ideal IMU: the exact increments of the "
                         f"run's motion on every axis, plus this gyro's own error (its pulses "
                         f"through the nominal weight minus the true increment) on the North "
                         f"axis, where a gyro error costs the most position (North gyro error → "
                         f"East tilt → East velocity). Ideal accelerometers, so no "
                         f"accelerometer oracle. Not done: the three-unit IMU (units drawn from "
                         f"the preset, compensated per axis) that would show the units' spread. "
                         f"{span_h:g} h after the alignment. {note}".rstrip())

