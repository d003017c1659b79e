"""The body frame of a recording's fixed mount for the navigation
(:mod:`rlgsim.lab.navigation_source`): the three body axes picked by name from the gyro and
accelerometer columns, and C_n^b from the sidecar's ``[orientation]`` direction cosines
(docs/recordings.md). The nearest rotation is numpy's SVD.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rlgsim.ground.errors import UserInputError

__all__ = ["ORTHO_TOL", "body_axes", "body_frame"]


#: How far from orthogonal [cosine] a sidecar's body axes may be before ``body_frame`` refuses
#: them: 4-decimal direction cosines are off by ≤ ~2e-4; a wrong axis by ≳ 0.1.
ORTHO_TOL = 1e-3


def body_frame(orientation: dict, axes: list[str], where: Any) -> np.ndarray:
    """C_n^b (rows: the body ``axes``' unit vectors in ENU, from a sidecar's ``orientation``;
    x, y, z east, north, up by default), or one line if they are not a right-handed
    orthonormal triad to :data:`ORTHO_TOL`.

    Direction cosines are written to a few decimals (a 45° mount as [0.7071, 0.7071, 0]: each
    row a unit to ~1e-4 — the sidecar normalises it — and orthogonal to ~1e-4 only), so the
    triad is refused only for a gross error (a repeated, swapped or mistyped axis: off by
    ~0.1 to 1; a left-handed set: det < 0) and otherwise replaced by the nearest rotation
    (orthogonal Procrustes: C = U Vᵀ of the SVD C = U S Vᵀ, which minimises the Frobenius
    distance; Higham, "Computing the polar decomposition", SIAM J. Sci. Stat. Comput. 7, 1986).
    A triad orthonormal to rounding (1e-12) is kept as given."""
    default = {"x": [1.0, 0, 0], "y": [0, 1.0, 0], "z": [0, 0, 1.0]}
    rows = [orientation.get(ax, default.get(ax)) for ax in axes]
    c_nb = np.array([r if r is not None else [np.nan] * 3 for r in rows], dtype=float)
    gram = c_nb @ c_nb.T
    if not (np.allclose(gram, np.eye(3), rtol=0.0, atol=ORTHO_TOL)
            and np.linalg.det(c_nb) > 0):
        raise UserInputError(f"{where}: [orientation] of axes {', '.join(axes)} is not a "
                             f"right-handed orthonormal triad (got {c_nb.tolist()}; each pair "
                             f"orthogonal to {ORTHO_TOL:g}); navigation needs the body frame "
                             "(give each axis its unit vector [east, north, up])")
    if np.allclose(gram, np.eye(3), rtol=0.0, atol=1e-12):
        return c_nb
    u, _, vt = np.linalg.svd(c_nb)
    return u @ vt


def body_axes(gyro_axes: list[str], accel_axes: list[str], where: Any) -> list[str]:
    """The three body axes navigated, in the order x, y, z (axes of the user's own names: in
    their gyro columns' order, the only order they have — sorting them could turn a
    right-handed mount left-handed): picked by name, so a table may list its columns in any
    order; each accelerometer is paired with the gyro of the same axis name (one line if the
    names differ)."""
    axes = ["x", "y", "z"] if {"x", "y", "z"} <= set(gyro_axes) else list(gyro_axes[:3])
    missing = [a for a in axes if a not in accel_axes]
    if missing:
        raise UserInputError(f"{where}: no accelerometer on gyro axis {', '.join(missing)} "
                             f"(gyro axes {', '.join(gyro_axes)}; accelerometer axes "
                             f"{', '.join(accel_axes)}); navigation pairs each gyro with the "
                             f"accelerometer of the same axis name")
    return axes
