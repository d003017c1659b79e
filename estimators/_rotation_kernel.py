"""Compiled rotation algebra shared by the two strapdown loops (numba).

The calibration's strapdown pass (:mod:`rlgsim.estimators._strapdown_kernel`) and the
navigator's (:mod:`rlgsim.estimators.ins._kernel`) make the same three steps per sample on
scalars: the two-sample coning-corrected rotation vector, the quaternion product that applies
it, and the rotation of a body vector by the attitude quaternion. They live here once. Every
helper is ``inline="always"`` and takes and returns scalars in the order the loops used to
write them inline, so the compiled arithmetic (and every result bit) is that of the loops
before the helpers existed. :mod:`rlgsim.ground.frames` holds the numpy (array) forms of the
same algebra for the rest of the project; these are the per-sample scalar forms a numba loop
needs (numba cannot call the numpy forms without allocating per sample).

Quaternions are [w, x, y, z] (Hamilton convention, as :mod:`rlgsim.ground.frames`).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True, inline="always")
def cross(ax: float, ay: float, az: float, bx: float, by: float,
          bz: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """a × b of two 3-vectors given as scalars."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True, nogil=True, inline="always")
def coning_vector(px: float, py: float, pz: float, tx: float, ty: float,
                  tz: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Rotation vector φ = Δθ + (Δθ_prev × Δθ)/12 [rad] of the two-sample coning correction
    (Savage 2007, eq. 7.1.1.1-11) from the previous (p) and this sample's (t) angle
    increments [rad]."""
    return (tx + (py * tz - pz * ty) / 12.0,
            ty + (pz * tx - px * tz) / 12.0,
            tz + (px * ty - py * tx) / 12.0)


@njit(cache=True, nogil=True, inline="always")
def quat_mul(aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float,
             bz: float) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """Hamilton product a ⊗ b of two quaternions [w, x, y, z] (Savage 2007, eq. 3.2.4-9)."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(cache=True, nogil=True, inline="always")
def quat_rotate(qw: float, qx: float, qy: float, qz: float, vx: float, vy: float,
                vz: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """C(q) v for a unit quaternion q [w, x, y, z]: v + w t + u × t with u = (x, y, z) and
    t = 2 u × v (the Euler–Rodrigues form of the rotation, Kuipers 2002 §5.14); same units
    as v."""
    t1 = 2.0 * (qy * vz - qz * vy)
    t2 = 2.0 * (qz * vx - qx * vz)
    t3 = 2.0 * (qx * vy - qy * vx)
    return (vx + qw * t1 + (qy * t3 - qz * t2),
            vy + qw * t2 + (qz * t1 - qx * t3),
            vz + qw * t3 + (qx * t2 - qy * t1))
