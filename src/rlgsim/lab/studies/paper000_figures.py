"""The figures of the ``paper000_system`` report: the 15 parameters against temperature with
both models' fits, and the residuals after system-level compensation (5 × 3 panels each)."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.studies.paper000_config import LABEL, probe_for


def _grid_axes(title: str):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(5, 3, figsize=(13, 17), constrained_layout=True)
    fig.suptitle(title)
    return fig, axes


def fit_figure(raw, xs, ys, pred, ok, units):
    from rlgsim.estimators.calibration import PAPER_PARAMETERS
    fig, axes = _grid_axes("paper 000: parameters vs temperature")
    for k, p in enumerate(PAPER_PARAMETERS):
        ax = axes.flat[k]
        x = xs[p]
        order = np.argsort(x)
        sig = raw.column(f"{p}_sigma")[ok]
        ax.errorbar(x, ys[p], yerr=sig, fmt=".", ms=3, lw=0.6, color="0.45",
                    label="estimate ±1σ")
        truth = raw.column(f"{p}_true")[ok]
        if np.all(np.isfinite(truth)):
            ax.plot(x[order], truth[order], "-", color="k", lw=1.0, label="truth")
        ax.plot(x[order], pred[p]["hho_rvr"][order], "-", color="tab:red", lw=1.2,
                label="HHO-RVR")
        ax.plot(x[order], pred[p]["lsm"][order], "--", color="tab:blue", lw=1.2,
                label="cubic LSM")
        _style_panel(ax, p, units[p], first=k == 0)
    return fig


def _style_panel(ax, parameter: str, unit: str, first: bool) -> None:
    """Title, axis labels and (on the first panel) legend of one parameter's panel."""
    ax.set_title(parameter, fontsize=9)
    ax.set_xlabel("probe temperature [°C]", fontsize=8)
    ax.set_ylabel(unit, fontsize=8)
    ax.tick_params(labelsize=7)
    if first:
        ax.legend(fontsize=7)


def residual_figure(comp_tables, resid, units, probes, cfg):
    from rlgsim.estimators.calibration import PAPER_PARAMETERS
    fig, axes = _grid_axes(f"residuals after compensation to {cfg.desired_c:g} °C")
    for k, p in enumerate(PAPER_PARAMETERS):
        ax = axes.flat[k]
        for c, style in (("hho_rvr", "-"), ("lsm", "--")):
            tab = comp_tables[c]
            cok = np.array([r["status"] == "ok" for r in tab.rows])
            x = tab.column(f"temp_{probe_for(p, cfg.temperature)}_c")[cok]
            ax.plot(x, resid[p][c], style, marker=".", ms=3, lw=0.8, label=LABEL[c])
        ax.axhline(0.0, color="k", lw=0.5)
        _style_panel(ax, p, units[p], first=k == 0)
    return fig
