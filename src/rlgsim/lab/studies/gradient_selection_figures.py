"""The figures of the ``gradient_selection`` report (paper 003): the Table 3 heat maps, each test
run's bias and compensated error over time, their Allan deviations and the bias against its
most correlated gradient."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.report import Report, slug
from rlgsim.lab.studies.compensators import ORACLE, RAW
from rlgsim.lab.studies.gradient_selection_config import Config, column_name


def short(p: str) -> str:
    """A gradient probe's name without its "g." prefix (the paper's point letter)."""
    return p.split(".", 1)[1] if p.startswith("g.") else p


def figures(rep: Report, config: Config, runs, per_test, predictions, fitted, corr) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if corr is not None:
        pts = [short(p) for p in config.points]
        panels = [("ours (train)", np.abs(corr))]
        if config.published_matrix is not None:
            panels.append(("paper 003 Table 3", np.abs(config.published_matrix)))
        fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4),
                                 squeeze=False)
        for ax, (title, m) in zip(axes[0], panels):
            im = ax.imshow(m, vmin=0, vmax=1, cmap="viridis")
            ax.set_xticks(range(len(pts)), pts)
            ax.set_yticks(range(len(pts)), pts)
            ax.set_title(f"|r(bias, T_row − T_col)|: {title}", fontsize=9)
            for i in range(len(pts)):
                for j in range(len(pts)):
                    if i != j:
                        ax.text(j, i, f"{m[i, j]:.2f}", ha="center", va="center", fontsize=6,
                                color="w" if m[i, j] < 0.6 else "k")
        fig.colorbar(im, ax=axes[0].tolist(), shrink=0.8)
        rep.figure(fig, "correlation_heatmap", "Correlation of the bias with every pairwise "
                                               "gradient of the thermometers (Table 3).")

    names = [f.spec.name for f in fitted]
    for spec in config.test:
        rs = runs[spec.key].series
        preds = predictions[spec.label]
        th = rs.time_s / 3600.0
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
        ax.plot(th, rs.y, color="0.6", lw=0.8, label="measured bias y")
        ax.plot(th, rs.true_bias, color="k", lw=1.0, ls="--", label="true bias b")
        for n in names:
            ax.plot(th, preds[n], lw=0.9, label=f"ŷ: {n}")
        ax.set_ylabel("bias [°/h]")
        ax.legend(fontsize=7)
        ax.set_title(f"Test run {spec.label} ({config.window_s:g} s means)")
        for n in names:
            ax2.plot(th, rs.y - preds[n], lw=0.8, label=f"y − ŷ: {n}")
        ax2.plot(th, rs.y - preds[ORACLE], color="k", lw=0.6, alpha=0.6,
                 label="y − (b − r): oracle")
        ax2.set_xlabel("time [h]")
        ax2.set_ylabel("compensated [°/h]")
        ax2.legend(fontsize=7)
        rep.figure(fig, f"bias_over_time_{slug(spec.label)}",
                   f"Test run {spec.label}: measured and true bias with each model's "
                   "prediction (top); compensated error curves (bottom; paper 003 Figs. 6-8).")

        from rlgsim.lab.studies.sample_rate import allan_curves
        fig, ax = plt.subplots(figsize=(7, 5))
        rate = allan_curves(ax, rs, config.gyro, config.window_s,
                            [(RAW, np.zeros(rs.y.size), dict(color="0.5"))]
                            + [(n, preds[n], {}) for n in names]
                            + [(ORACLE, preds[ORACLE], dict(color="k", ls="--"))], ms=3)
        fast = rate is not None
        ax.set_xlabel("τ [s]")
        ax.set_ylabel("Allan deviation [°/h]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(f"Test run {spec.label}")
        rep.figure(fig, f"allan_deviation_{slug(spec.label)}",
                   "Overlapping Allan deviation before and after compensation (allantools), "
                   + (f"from the {config.window_s:g} s means." if not fast else
                      f"from the sample rate ({rate:g} Hz; ŷ held over each "
                      f"{config.window_s:g} s window)."))

    if corr is not None and len(config.points) >= 2:
        rs = runs[config.test[-1].key].series
        preds = predictions[config.test[-1].label]
        i, j = np.unravel_index(np.argmax(np.abs(corr)), corr.shape)
        a, b = config.points[min(i, j)], config.points[max(i, j)]
        col = column_name(a, b, set(rs.X.names))
        fig, ax = plt.subplots(figsize=(7, 5))
        g = rs.X[col]
        ax.scatter(g, rs.y, s=4, color="0.6", label="measured bias y")
        ax.scatter(g, rs.true_bias - rs.true_random, s=3, color="k",
                   label="true temperature law b − r")
        for n in names:
            ax.scatter(g, preds[n], s=3, label=f"ŷ: {n}")
        ax.set_xlabel(f"gradient {col} [K]")
        ax.set_ylabel("bias [°/h]")
        ax.legend(fontsize=8)
        ax.set_title(f"Test run {config.test[-1].label}")
        rep.figure(fig, "bias_vs_gradient", "Bias against the gradient most correlated with "
                                            "it on the train run, with the fits and the truth.")
