"""The true per-sample increments of a written run, recomputed from its dataset.

A run stores its turntable programme (the ``timeline`` group) and its site (root attributes),
and by default the true increments only summed per thermal step; the per-sample values are a
deterministic function of those, so :func:`true_increments` recomputes them bit for bit (:func:`dataset_motion` gives the kinematics) with the
run's own kinematics (:class:`rlgsim.sim.motion.kinematics.Motion`). The dataset is read with
the one reader, :class:`rlgsim.ground.dataset_format.Dataset` (its :meth:`segments` decodes the
timeline).
"""

from __future__ import annotations

import os

import numpy as np

from rlgsim.ground.dataset_format import Dataset, open_dataset
from rlgsim.sim.motion.kinematics import Motion, TurntableSegment
from rlgsim.sim.motion.site import Site

__all__ = ["dataset_motion", "true_increments"]


def dataset_motion(dataset: Dataset | str | os.PathLike) -> Motion:
    """The run's turntable kinematics rebuilt from a dataset's timeline (turntable track) and
    site. ``dataset``: an open :class:`~rlgsim.ground.dataset_format.Dataset` or a path."""
    if not isinstance(dataset, Dataset):
        with open_dataset(dataset) as ds:
            return dataset_motion(ds)
    segs = [TurntableSegment(s["t0"], s["t1"], "turntable", s["label"], s["attrs"])
            for s in dataset.segments("turntable")]
    site = Site(float(dataset.attrs["latitude_deg"]), float(dataset.attrs["height_m"]))
    return Motion(segs, site)


def true_increments(dataset: Dataset | str | os.PathLike, t0_s: float, n: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample true (Δθ (n, 3) [rad], Δv (n, 3) [m/s]) of ``n`` samples from ``t0_s`` [s],
    recomputed from a dataset's timeline (turntable track) and site — bit for bit what the run
    used. ``dataset``: an open :class:`~rlgsim.ground.dataset_format.Dataset` or a path."""
    if not isinstance(dataset, Dataset):
        with open_dataset(dataset) as ds:
            return true_increments(ds, t0_s, n)
    mb = dataset_motion(dataset).increments(t0_s, n, float(dataset.attrs["sample_rate_hz"]))
    return mb.dtheta_rad, mb.dv_m_per_s
