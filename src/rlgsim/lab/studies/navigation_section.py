"""The navigation section of a study report (docs/navigation.md, docs/studies.md).

:func:`add_section` puts a navigation run (:func:`rlgsim.lab.navigation.navigate`) into a
:class:`~rlgsim.lab.report.Report`: the conditions, one table of the scores per variant (raw,
the study's compensators, the oracles, the truth floor), one sentence per observed ranking with
its reason (:func:`rlgsim.lab.navigation_report.ranking_reasons`) and the error figure;
:func:`add_env_section` the same for several environments (paper 002: one table, one panel per
environment). The single-gyro studies' IMU of three units is :mod:`rlgsim.lab.studies.imu_axes`.

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


def add_env_section(rep: Report, dss: dict[str, Any], intro: str, *,
                    csv_name: str = "navigation.csv") -> None:
    """The navigation section of a study with several environments (paper 002): one table with
    a row per environment and variant, the ranking reasons per environment, and one figure with
    a panel of horizontal error per environment (``dss``: environment → navigation dataset)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rlgsim.lab.navigation_report import COLUMNS, ranking_reasons, summary_frame
    rep.heading("Navigation: free-inertial position and heading errors", 2)
    a = next(iter(dss.values())).attrs
    rep.paragraph(
        f"{intro} Each environment's IMU is aligned on its first static segment "
        f"({a['align_start_s']:g}–{a['align_end_s']:g} s: coarse levelling and gyrocompassing, "
        f"then a zero-velocity Kalman filter), then navigates free-inertially to "
        f"{a['navigation_end_s']:g} s at latitude {a['latitude_deg']:g}° (docs/navigation.md); "
        f"vertical channel {a['vertical_channel']}. Radial error rate: least-squares slope of "
        "the horizontal error against time. Residual errors: what each variant's increments "
        "differ from the truth's, 100-s means, RMS of the vector.")
    frames = {env: summary_frame(ds) for env, ds in dss.items()}
    df0 = next(iter(frames.values()))
    keys = [(k, h) for k, h, _ in COLUMNS if k in df0]
    rows = [[env, name, *[float(r[k]) for k, _ in keys]]
            for env, df in frames.items() for name, r in df.iterrows()]
    rep.table(Table("Navigation scores per environment and variant",
                    ["environment", "variant", *[h for _, h in keys]], rows, csv_name=csv_name,
                    note="raw: nominal pulse weights; oracle (gyros): the true gyro "
                         "temperature law removed; truth: the exact increments (the "
                         "mechanization's floor)."))
    rep.bullets([f"{env}: {line}" for env, ds in dss.items() for line in ranking_reasons(ds)])
    n = len(dss)
    cols = min(3, n)
    rows_n = -(-n // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(4.0 * cols, 3.2 * rows_n), sharex=True,
                             sharey=True, squeeze=False)
    for ax, (env, ds) in zip(axes.flat, dss.items()):
        t_h = (ds["time"].values - ds.attrs["align_end_s"]) / 3600.0
        for v in ds["variant"].values:
            if str(v) != "truth":            # the floor (< 1 mm) stays in the table
                ax.semilogy(t_h, np.maximum(ds["horizontal_error_m"].sel(variant=v).values,
                                            1.0), label=str(v), lw=1.0)
        ax.set_ylim(bottom=1.0)
        ax.set_title(env, fontsize="medium")
        ax.grid(alpha=0.3)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("horizontal error [m]")
    for ax in axes[-1, :]:
        ax.set_xlabel("time since alignment [h]")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 6), fontsize="small")
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    rep.figure(fig, "navigation", "Free-inertial horizontal position error per variant after "
                                  "the alignment, one panel per environment (the truth floor, "
                                  "under 1 mm, in the table only); the Schuler oscillation "
                                  "(84.4 min) modulates the growth.")
    plt.close(fig)
