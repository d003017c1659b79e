"""The figures of the ``environments`` report (paper 002): bias and compensated bias over
time, against temperature, and their Allan deviations, per environment."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.report import Report
from rlgsim.lab.studies.compensators import ORACLE, RAW
from rlgsim.lab.studies.environment_fits import EnvResult
from rlgsim.lab.studies.environment_tables import Config
from rlgsim.lab.studies.environments_report_tables import grid


#: Figure panels limit the bias axis to this many raw σ around the measured bias, so that a
#: model's spikes do not hide everything else (the tables hold the full numbers).
CLIP_SIGMAS = 6.0


def _limit(ax, reference: np.ndarray, plotted: list[np.ndarray]) -> bool:
    """Limit the y axis to CLIP_SIGMAS std of ``reference`` around its mean when anything
    plotted lies beyond; returns whether it did."""
    mid, sd = float(np.mean(reference)), float(np.std(reference))
    lo, hi = mid - CLIP_SIGMAS * sd, mid + CLIP_SIGMAS * sd
    if sd > 0 and any(np.any((x < lo) | (x > hi)) for x in plotted):
        ax.set_ylim(lo, hi)
        ax.text(0.02, 0.02, "axis cut", transform=ax.transAxes, fontsize=7, color="C3")
        return True
    return False


def figures(rep: Report, results: list[EnvResult], config: Config) -> None:
    """Bias over time, bias against temperature and Allan deviation, one panel per
    environment (its first test run)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [c.name for c in config.compensators]
    colour = {n: f"C{i}" for i, n in enumerate(names)}
    cut = (f" Panels marked 'axis cut' show ±{CLIP_SIGMAS:g} raw σ only: a model's spikes "
           "go beyond (full numbers in the tables).")
    _time_figure(rep, results, config, names, colour, plt, cut)
    if config.temperature:
        _temperature_figure(rep, results, config, names, colour, plt, cut)
    _allan_figure(rep, results, config, names, colour, plt)


def _time_figure(rep: Report, results: list[EnvResult], config: Config, names: list[str],
                 colour: dict[str, str], plt, cut: str) -> None:
    """Raw and compensated bias of each test run over time."""
    fig, axes = grid(len(results), plt)
    for ax, r in zip(axes, results):
        rs, p = r.tests[0], r.predictions[r.tests[0].label]
        th = rs.time_s / 3600.0
        ax.plot(th, rs.y - p[RAW], color="0.6", lw=0.8, label="raw (y − train mean)")
        for n in names:
            ax.plot(th, rs.y - p[n], color=colour[n], lw=0.7, label=f"y − ŷ: {n}")
        _limit(ax, rs.y - p[RAW], [rs.y - p[n] for n in names])
        ax.plot(th, rs.y - p[ORACLE] - np.mean(rs.y - p[ORACLE]), color="k", lw=0.7, ls="--",
                label="y − true law (floor)")
        ax.set_title(r.env.name, fontsize=9)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("time [h]", fontsize=8)
        ax.set_ylabel("bias [°/h]", fontsize=8)
    axes[0].legend(fontsize=6)
    fig.tight_layout()
    rep.figure(fig, "bias_over_time", f"Raw and compensated bias ({config.window_s:g} s means) "
                                      "of each environment's test run." + cut)


def _temperature_figure(rep: Report, results: list[EnvResult], config: Config,
                        names: list[str], colour: dict[str, str], plt, cut: str) -> None:
    """Bias against the probe temperature: measured, true law and predictions."""
    fig, axes = grid(len(results), plt)
    for ax, r in zip(axes, results):
        rs, p = r.tests[0], r.predictions[r.tests[0].label]
        T = rs.X["T"]
        ax.scatter(T, rs.y, s=3, color="0.7", label="measured bias y")
        ax.scatter(T, p[ORACLE], s=3, color="k", label="true law b − r")
        for n in names:
            ax.scatter(T, p[n], s=2, color=colour[n], label=f"ŷ: {n}")
        _limit(ax, rs.y, [p[n] for n in names])
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.set_title(r.env.name, fontsize=9)
        ax.tick_params(labelsize=7)
        ax.set_xlabel(f"T (probe {config.temperature}) [°C]", fontsize=8)
        ax.set_ylabel("bias [°/h]", fontsize=8)
    axes[0].legend(fontsize=6, markerscale=3)
    fig.tight_layout()
    rep.figure(fig, "bias_vs_temperature", "Bias against the probe temperature on each test "
                                           "run: measured, the true temperature law and the "
                                           "fitted models' predictions." + cut)


def _allan_figure(rep: Report, results: list[EnvResult], config: Config, names: list[str],
                  colour: dict[str, str], plt) -> None:
    """Overlapping Allan deviation before and after compensation (allantools)."""
    from rlgsim.lab.studies.sample_rate import allan_curves
    fig, axes = grid(len(results), plt)
    rates = set()
    for ax, r in zip(axes, results):
        rs, p = r.tests[0], r.predictions[r.tests[0].label]
        rates.add(allan_curves(ax, rs, config.gyro, config.window_s,
                               [("raw", np.zeros(rs.y.size), {"color": "0.5"})]
                               + [(n, p[n], {"color": colour[n]}) for n in names]
                               + [(ORACLE, p[ORACLE], {"color": "k", "ls": "--"})],
                               ms=2, lw=0.8))
        ax.set_title(r.env.name, fontsize=9)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("τ [s]", fontsize=8)
        ax.set_ylabel("Allan deviation [°/h]", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=6)
    fig.tight_layout()
    start = ("from the sample rate (ŷ held over each window)" if None not in rates
             else f"from the {config.window_s:g} s means")
    rep.figure(fig, "allan_deviation", "Overlapping Allan deviation (allantools) of each test "
                                       f"run before and after compensation, {start}.")
