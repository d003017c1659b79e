"""The figures of the ``bias_compensation`` report: per test run, the bias and each model's
prediction over time, the compensated errors, their Allan deviations and the bias against the
inputs."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.report import Report, slug
from rlgsim.lab.studies.bias_compensation_config import Config
from rlgsim.lab.studies.compensators import ORACLE
from rlgsim.lab.studies.fitting import Fitted
from rlgsim.lab.studies.runs import RunSeries
from rlgsim.lab.studies.scoring import has_truth


def run_figures(rep: Report, config: Config, fitted: list[Fitted], rs: RunSeries,
                preds: dict[str, np.ndarray], sc: dict, ytr: np.ndarray, label: str,
                multi: bool) -> None:
    """The figures of one test run: bias over time (measured, true, predicted; compensated),
    bias against temperature with the truth, Allan deviation before and after."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tag = f"_{slug(label)}" if multi else ""
    where = f"Test run {label}. " if multi else ""
    best = _best_per_kind(fitted, sc)
    th = rs.time_s / 3600.0
    top = min(fitted, key=lambda f: sc[f.spec.name]["stability_after"]).spec.name if fitted \
        else None
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax.plot(th, rs.y, color="0.6", lw=0.8, label="measured bias y")
    ax.plot(th, rs.true_bias, color="k", lw=1.0, ls="--", label="true bias b")
    if top is not None:
        ax.plot(th, preds[top], color="C3", lw=1.0, label=f"prediction ŷ: {top}")
    ax.set_ylabel("bias [°/h]")
    ax.legend(fontsize=7)
    ax.set_title(f"Test run {label} ({config.window_s:g} s means)")
    ax2.plot(th, rs.y - np.mean(ytr), color="0.6", lw=0.8, label="raw (y − train mean)")
    for name in best:
        ax2.plot(th, rs.y - preds[name], lw=0.9, label=f"y − ŷ: {name}")
    ax2.set_xlabel("time [h]")
    ax2.set_ylabel("compensated [°/h]")
    ax2.legend(fontsize=7, ncol=2)
    rep.figure(fig, f"bias_over_time{tag}",
               f"{where}Top: measured and true bias with the prediction of the model with the "
               "best bias stability. Bottom: the raw and compensated series of the best model "
               "of each kind.")

    if "T" in rs.X:
        fig, ax = plt.subplots(figsize=(7, 5))
        T = rs.X["T"]
        ax.scatter(T, rs.y, s=4, color="0.6", label="measured bias y")
        ax.scatter(T, rs.true_bias, s=4, color="k", label="true bias b")
        ax.scatter(T, rs.true_bias - rs.true_random, s=3, color="C3",
                   label="true temperature law b − r")
        if top is not None:
            ax.scatter(T, preds[top], s=3, color="C0", label=f"prediction: {top}")
        ax.set_xlabel(f"T (probe {config.temperature}) [°C]")
        ax.set_ylabel("bias [°/h]")
        ax.legend(fontsize=8)
        rep.figure(fig, f"bias_vs_temperature{tag}", f"{where}Bias against the probe "
                                                     "temperature, with the truth.")

    from rlgsim.lab.studies.sample_rate import allan_curves
    fig, ax = plt.subplots(figsize=(7, 5))
    fast = allan_curves(ax, rs, config.gyro, config.window_s,
                        [("raw", np.zeros(rs.y.size), dict(color="0.5"))]
                        + [(n, preds[n], {}) for n in best]
                        + ([(ORACLE, preds[ORACLE], dict(color="k", ls="--"))]
                           if has_truth(rs) else []), ms=3)
    rate = 1.0 / config.window_s if fast is None else fast
    resolution = "window" if fast is None else "sample"
    ax.set_xlabel("τ [s]")
    ax.set_ylabel("Allan deviation [°/h]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    rep.figure(fig, f"allan_deviation{tag}",
               f"{where}Overlapping Allan deviation before and after compensation "
               f"(allantools), from the {resolution} rate"
               + (f" ({rate:g} Hz: pulse quantisation, slope −1, and angle random walk, "
                  f"slope −½, at short τ; ŷ held over each {config.window_s:g} s window)"
                  if fast is not None else
                  f" ({config.window_s:g} s means)") + ".")


def _best_per_kind(fitted: list[Fitted], sc: dict) -> dict[str, str]:
    best: dict[str, str] = {}
    for f in fitted:
        cur = best.get(f.spec.kind)
        if cur is None or sc[f.spec.name]["stability_after"] < sc[cur]["stability_after"]:
            best[f.spec.kind] = f.spec.name
    return {name: kind for kind, name in best.items()}
