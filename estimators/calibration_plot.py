"""Figures of a calibration campaign: every parameter against temperature, with ±1σ and truth.

One PNG per sensor group (matplotlib, Agg backend): gyro bias and scale factor; accelerometer
bias and positive/negative scale factors (the 15 temperature-related parameters of paper 000,
cf. its Figure 2); the nine misalignments. x is the window-mean temperature of one probe
(default: the first probe of the dataset); the estimate is drawn with its ±1σ error bar, the
window-averaged truth (simulated data) as a line. Failed windows are left out.
"""

from __future__ import annotations

import pathlib

import numpy as np

from rlgsim.ground.atomic import atomic_file
from rlgsim.estimators.calibration import AXES, PARAMETERS, CampaignResult

_UNITS = {"deg/h": "°/h", "ppm": "ppm", "arcsec": "arcsec", "ug": "µg"}

FIGURES = {
    "gyro": ["gyro_bias", "gyro_sf"],
    "accel": ["accel_bias", "accel_sf_pos", "accel_sf_neg"],
    "misalignment": ["gyro_mis", "accel_mis"],
}


def plot_campaign(result: CampaignResult, prefix: str | pathlib.Path,
                  probe: str | None = None) -> list[pathlib.Path]:
    """Write ``<prefix>_gyro.png``, ``<prefix>_accel.png``, ``<prefix>_misalignment.png``;
    return their paths. ``probe`` names the temperature on the x axis."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if probe is None:
        probe = result.probes[0] if result.probes else None
    elif probe not in result.probes:
        raise ValueError(f"no probe {probe!r}; the dataset's probes are "
                         f"{', '.join(result.probes) or 'none'}")
    ok = np.array([r["status"] == "ok" for r in result.rows], dtype=bool)
    if probe is not None:
        x = result.column(f"temp_{probe}_c")
        xlabel = f"probe {probe} mean temperature over the window [°C]"
    else:
        x = result.column("t0_s") / 3600.0
        xlabel = "window start [h]"
    prefix = pathlib.Path(prefix)
    out = []
    for fig_name, stems in FIGURES.items():
        params = [p for p in PARAMETERS if any(p.name.startswith(s + "_") and
                                               p.name[len(s) + 1:] in _suffixes(s)
                                               for s in stems)]
        ncol = 3
        nrow = int(np.ceil(len(params) / ncol))
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 2.8 * nrow), squeeze=False,
                                 constrained_layout=True)
        for ax, p in zip(axes.ravel(), params):
            y = result.column(p.name)
            s = result.column(f"{p.name}_sigma")
            t = result.column(f"{p.name}_true")
            ax.errorbar(x[ok], y[ok], yerr=s[ok], fmt="o", ms=2.5, lw=0.8, capsize=0,
                        label="estimate ±1σ")
            if np.any(np.isfinite(t[ok])):
                order = np.argsort(x[ok])
                ax.plot(x[ok][order], t[ok][order], "-", color="C3", lw=1.0,
                        label="truth (window mean)")
            ax.set_title(p.name, fontsize=9)
            ax.set_ylabel(_UNITS.get(p.unit, p.unit), fontsize=8)
            ax.tick_params(labelsize=7)
            ax.set_xlabel(xlabel, fontsize=7)
        for ax in axes.ravel()[len(params):]:
            ax.set_visible(False)
        axes.ravel()[0].legend(fontsize=7)
        fig.suptitle(f"calibration parameters vs temperature ({int(ok.sum())} of "
                     f"{len(ok)} windows ok)", fontsize=10)
        path = prefix.with_name(f"{prefix.name}_{fig_name}.png")
        with atomic_file(path) as tmp:             # whole or not at all
            fig.savefig(tmp, dpi=110, format="png")
        plt.close(fig)
        out.append(path)
    return out


def _suffixes(stem: str) -> set[str]:
    if stem.endswith("_mis"):
        return {a + b for a in AXES for b in AXES if a != b}
    return set(AXES)
