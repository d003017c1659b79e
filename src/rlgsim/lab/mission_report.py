"""The figure of a vehicle mission: the route, the temperature history and each variant's
horizontal error through the aided navigator (:func:`rlgsim.lab.mission.score_mission`).

Three panels (matplotlib, Agg): the route in east/north kilometres from its start with the GNSS
outages drawn in red; the bay's air and the unit's coldest and warmest nodes [°C] against time;
the horizontal error [m] of every variant (log scale) with the outages shaded.
"""

from __future__ import annotations

import pathlib
from typing import Mapping

import numpy as np

from rlgsim.ground.atomic import atomic_file


def mission_figure(dataset: str | pathlib.Path, scores: Mapping[str, dict],
                   path: str | pathlib.Path) -> pathlib.Path:
    """Write the mission's figure for ``scores`` (of ``score_mission(dataset)``) to ``path``
    (PNG); returns the path."""
    import matplotlib.pyplot as plt
    fig = mission_plot(dataset, scores)
    out = pathlib.Path(path)
    with atomic_file(out) as tmp:                       # whole or not at all
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return out


def mission_plot(dataset: str | pathlib.Path, scores: Mapping[str, dict]):
    """The mission's figure (a matplotlib Figure; module docstring)."""
    import h5py
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rlgsim.ground.earth import radii_of_curvature_rad
    with h5py.File(dataset, "r") as f:
        g = f["trajectory"]
        lat = np.radians(g["latitude"][...])
        lon = np.radians(g["longitude"][...])
        vis = np.asarray(g["gnss_visible"][...]).astype(bool)
        rate = float(f.attrs["sample_rate_hz"])
        t_th = np.asarray(f["thermal/time"][...])
        air = np.asarray(f["thermal/chamber_air"][...])
        nodes = np.asarray(f["thermal/node_temperature"][...])
    rm, rn = radii_of_curvature_rad(lat[0])
    east = (lon - lon[0]) * rn * np.cos(lat[0]) / 1e3
    north = (lat - lat[0]) * rm / 1e3
    t = (np.arange(lat.size) + 1) / rate
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    ax[0].plot(east, north, lw=1.0, color="0.3", label="route")
    ax[0].plot(np.where(vis, np.nan, east), np.where(vis, np.nan, north), lw=2.0, color="tab:red",
               label="GNSS outage")
    ax[0].set(xlabel="east [km]", ylabel="north [km]", title="route", aspect="equal")
    ax[0].legend(fontsize=8)
    ax[1].plot(t_th / 60, air, label="bay air")
    ax[1].plot(t_th / 60, nodes.min(axis=1), label="coldest node")
    ax[1].plot(t_th / 60, nodes.max(axis=1), label="warmest node")
    ax[1].set(xlabel="time [min]", ylabel="°C", title="temperature")
    ax[1].legend(fontsize=8)
    for name, s in scores.items():
        ax[2].semilogy(s["t_s"] / 60, np.maximum(s["horizontal_m"], 1e-3), lw=1.0, label=name)
    edges = np.flatnonzero(np.diff(np.r_[0, (~vis).astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2]):
        ax[2].axvspan(t[a] / 60, t[b - 1] / 60, color="tab:red", alpha=0.12)
    ax[2].set(xlabel="time [min]", ylabel="horizontal error [m]",
              title="aided navigation (outages shaded)")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    return fig
