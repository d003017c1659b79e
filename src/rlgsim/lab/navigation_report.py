"""Tables, figure, ranking reasons and files of a navigation run (:mod:`rlgsim.lab.navigation`).

The ranking text states, for every pair of neighbours in the order of the radial error rate,
the reason visible in the data: the residual gyro and accelerometer error each variant leaves
against the truth over the navigation span (100-s means, RMS of the vector: bias, and on a
turning table also scale factor and misalignment times the rate). Where the order of the
residual errors and the order of the position errors disagree it says so: a free INS integrates
the errors through the Schuler and Earth-rate loops, so an error that changes sign or sits along
the vertical costs less position than a smaller constant horizontal one.
"""

from __future__ import annotations

import math
import pathlib
from typing import Any

import numpy as np

from rlgsim.ground.atomic import atomic_file
from rlgsim.lab.report import write_atomic

COLUMNS = [("error_1h_m", "error at 1 h [m]", "{:.4g}"),
           ("error_end_m", "error at end [m]", "{:.4g}"),
           ("radial_error_rate_nmi_per_h", "radial rate [nmi/h]", "{:.3g}"),
           ("velocity_error_rms_m_s", "velocity RMS [m/s]", "{:.3g}"),
           ("heading_error_align_arcmin", "heading after alignment [′]", "{:.3g}"),
           ("heading_bound_arcmin", "bound ε_E/(Ω cos L) [′]", "{:.3g}"),
           ("heading_error_end_arcmin", "heading at end [′]", "{:.3g}"),
           ("residual_gyro_error_deg_h", "residual gyro error [°/h]", "{:.3g}"),
           ("residual_accel_error_ug", "residual accel error [µg]", "{:.3g}")]


def summary_frame(ds):
    """The per-variant scores as a :class:`pandas.DataFrame` (index: variant)."""
    import pandas as pd
    cols = {key: ds[key].values for key, _, _ in COLUMNS if key in ds}
    return pd.DataFrame(cols, index=pd.Index([str(v) for v in ds["variant"].values],
                                             name="variant"))


def markdown_table(ds) -> str:
    """The scores as a Markdown table (units in the header)."""
    df = summary_frame(ds)
    keys = [(k, h, f) for k, h, f in COLUMNS if k in df]
    lines = ["| variant | " + " | ".join(h for _, h, _ in keys) + " |",
             "|---|" + "---:|" * len(keys)]
    for name, row in df.iterrows():
        cells = ["—" if not math.isfinite(row[k]) else f.format(row[k]) for k, _, f in keys]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ranking_reasons(ds) -> list[str]:
    """One sentence per neighbouring pair in the order of the radial error rate."""
    df = summary_frame(ds).sort_values("radial_error_rate_nmi_per_h")
    if "residual_gyro_error_deg_h" not in df:
        return ["No truth in the source: the ranking cannot be explained by residual biases "
                "(a recording's errors are against a site at rest)."]
    out = []
    names = list(df.index)
    for a, b in zip(names[:-1], names[1:]):
        ra, rb = df.loc[a], df.loc[b]
        ga, gb = ra["residual_gyro_error_deg_h"], rb["residual_gyro_error_deg_h"]
        aa, ab = ra["residual_accel_error_ug"], rb["residual_accel_error_ug"]
        why = (f"{a} ({ra['radial_error_rate_nmi_per_h']:.3g} nmi/h) ranks before {b} "
               f"({rb['radial_error_rate_nmi_per_h']:.3g} nmi/h): residual gyro error "
               f"{ga:.3g} vs {gb:.3g} °/h, accelerometer {aa:.3g} vs {ab:.3g} µg")
        if a == "truth":
            why += " — the exact increments: what is left is the mechanization's own error"
        elif ga <= gb and aa <= ab:
            why += " — it leaves no more of either"
        elif ga <= gb:
            why += (" — less gyro error; the gyro error drives the error growth (the "
                    "accelerometer's is Schuler-bounded)")
        elif aa < ab:
            why += (" — more gyro error but less accelerometer error; over this span the "
                    "accelerometer's share dominates")
        else:
            why += (" — although it leaves more of both: the position error integrates the "
                    "errors' time history and direction through the Schuler and Earth-rate "
                    "loops (an error that changes sign, or lies along the vertical, costs "
                    "less position), which one RMS figure does not hold")
        out.append(why + ".")
    return out


def figure(ds, path: pathlib.Path) -> pathlib.Path:
    """Horizontal position error, North velocity error and heading error against time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t_h = (ds["time"].values - ds.attrs["align_end_s"]) / 3600.0
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for v in ds["variant"].values:
        sel = ds.sel(variant=v)
        axes[0].semilogy(t_h, np.maximum(sel["horizontal_error_m"].values, 1e-6), label=str(v))
        axes[1].plot(t_h, sel["velocity_error_north_m_s"].values, label=str(v))
        axes[2].plot(t_h, sel["heading_error_arcmin"].values, label=str(v))
    axes[0].set_ylabel("horizontal error [m]")
    axes[1].set_ylabel("North velocity error [m/s]")
    axes[2].set_ylabel("heading error [′]")
    axes[2].set_xlabel("time since alignment [h]  (Schuler period 84.4 min, Earth rate 24 h)")
    axes[0].legend(fontsize="small")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"free-inertial navigation, {ds.attrs['source']}")
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path


def report_text(ds, figure_name: str | None = "navigation.png") -> str:
    """The Markdown section: conditions, table, ranking reasons, figure."""
    a = ds.attrs
    lines = [f"Aligned on {a['align_start_s']:g}–{a['align_end_s']:g} s (coarse levelling + "
             f"gyrocompassing, then a zero-velocity Kalman filter), free-inertial navigation "
             f"to {a['navigation_end_s']:g} s at latitude {a['latitude_deg']:g}°; vertical "
             f"channel {a['vertical_channel']}. Variants: raw (nominal pulse weights), the "
             f"compensators ({a['compensation']}), the oracles and the truth increments "
             "(the floor).", "", markdown_table(ds), ""]
    lines += [f"- {r}" for r in ranking_reasons(ds)]
    if figure_name:
        lines += ["", f"![navigation errors]({figure_name})"]
    return "\n".join(lines)


def write(ds, out_dir: str | pathlib.Path, fmt: str = "csv") -> dict[str, Any]:
    """solution.csv|parquet (every variant's error series), summary.csv, navigation.png and
    report.md into ``out_dir``; returns the paths."""
    out = pathlib.Path(out_dir)
    if fmt == "parquet":
        from rlgsim.ground.recording_columns import need_pyarrow
        need_pyarrow(out / "solution.parquet", "writing")   # optional: one line, before work
    out.mkdir(parents=True, exist_ok=True)
    series = ds.drop_vars([k for k in ds.data_vars if ds[k].dims == ("variant",)])
    df = series.to_dataframe().reset_index()
    df = df.rename(columns={"time": "time_s"})
    sol = out / f"solution.{fmt}"
    with atomic_file(sol) as tmp:          # each file whole or not at all
        if fmt == "parquet":
            df.to_parquet(tmp, index=False)
        else:
            df.to_csv(tmp, index=False)
    summ = out / "summary.csv"
    with atomic_file(summ) as tmp:
        summary_frame(ds).to_csv(tmp)
    fig = figure(ds, out / "navigation.png")
    rep = out / "report.md"
    write_atomic(rep, f"# Navigation: {ds.attrs['source']}\n\n{report_text(ds)}\n")
    return {"solution": sol, "summary": summ, "figure": fig, "report": rep}
