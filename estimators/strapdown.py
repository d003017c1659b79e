"""Strapdown navigation of an IMU standing on a turntable at a fixed site, from pulse counts.

Everything here works on recorded data (pulses, sample interval, commanded table angles): it
never imports ``sim``. The site model (normal gravity, Earth rate), the turntable's gimbal
convention and the rotation algebra are the conventions of the dataset (docs/dataset.md) and
come from the ground package both sides share (:mod:`rlgsim.ground.earth`,
:mod:`rlgsim.ground.frames`).

Frames: navigation frame ENU at the site (x East, y North, z Up); body frame = the IMU
measurement frame; i0 = the inertial frame that coincides with ENU at the start of the window.

Pulse model (paper 000 eqs. 17 and 20; docs/design.md), per sample of length Δt:

    N_g = K_g (D_g Δt + E_g Δθ)            K_g [pulse/rad] diagonal, D_g [rad/s], E_g unit-diagonal
    N_a = K_a^± (D_a Δt + E_a Δv)          K_a^± [pulse/(m/s)] chosen per axis by the sign of the
                                           pulse count, D_a [m/s²], E_a unit-diagonal

:meth:`SensorModel.compensate` inverts it: Δθ = E_g⁻¹(N_g/K_g − D_g Δt), Δv = E_a⁻¹(N_a/K_a^± − D_a Δt).

Attitude (Savage, *Strapdown Analytics* 2nd ed. 2007, §7.1; Titterton & Weston 2004 §11.2):
the two-sample coning-corrected rotation vector φ_k = Δθ_k + (1/12) Δθ_{k−1} × Δθ_k updates the
body-to-i0 quaternion q_k = q_{k−1} ⊗ exp(φ_k/2); the navigation frame turns with the Earth, so
C_b^n(t) = R(ω_ie^n, −t) C_b^{i0}(t) exactly (ω_ie^n is constant at a fixed site). The sequential
quaternion product is evaluated as a blocked prefix product (√n vectorised steps), not a
per-sample Python loop.

Velocity (Savage §7.2): ΔV_k = Δv_k + ½ Δθ_k × Δv_k + (1/12)(Δθ_{k−1} × Δv_k + Δv_{k−1} × Δθ_k)
(rotation + two-sample sculling), ΔV^n_k = R(ω_ie^n, −t_{k−½}) C_b^{i0}(t_{k−1}) ΔV_k, and

    v^n_k = v^n_0 + Σ_j (ΔV^n_j + g^n Δt),        g^n = (0, 0, −γ)

The true velocity on the turntable is zero, and the IMU sits at the table centre, so the
Coriolis term −2 ω_ie × v (which only keeps a *moving* vehicle's velocity right) is left out of
the navigation and — consistently — out of the error model (:mod:`rlgsim.estimators.kalman_calibration`):
the navigated velocity is the velocity error itself.

Normal gravity γ: Somigliana's closed formula with WGS-84 constants and the free-air correction
(NIMA TR8350.2 3rd ed. eqs. 4-1, 4-3), :func:`rlgsim.ground.earth.normal_gravity` — the same
function the simulation's site uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from rlgsim.ground.earth import earth_rate_enu, normal_gravity
from rlgsim.estimators._strapdown_kernel import compensate_loop, strapdown_loop
from rlgsim.ground.frames import dcm_to_quat, quat_to_dcm, rotation_matrix
# also imported from here by rlgsim.estimators.kalman_calibration
from rlgsim.ground.frames import body_to_enu as table_attitude  # noqa: F401
from rlgsim.ground.frames import skew  # noqa: F401
from rlgsim.ground.units import ARCSEC, DEG  # noqa: F401


# --------------------------------------------------------------------------- sensor model

@dataclass(frozen=True)
class SensorModel:
    """Pulse-model parameters (paper 000 eqs. 17, 20) of the three gyros and accelerometers.

    ``k_g`` (3,) gyro scale factors [pulse/rad]; ``d_g`` (3,) gyro biases [rad/s]; ``e_g`` (3, 3)
    gyro installation matrix (unit diagonal, off-diagonal misalignments [rad]); ``k_a_pos`` /
    ``k_a_neg`` (3,) accelerometer scale factors for positive / negative input [pulse/(m/s)];
    ``d_a`` (3,) accelerometer biases [m/s²]; ``e_a`` (3, 3) accelerometer installation matrix.
    """

    k_g: np.ndarray
    k_a_pos: np.ndarray
    k_a_neg: np.ndarray
    d_g: np.ndarray = field(default_factory=lambda: np.zeros(3))
    e_g: np.ndarray = field(default_factory=lambda: np.eye(3))
    d_a: np.ndarray = field(default_factory=lambda: np.zeros(3))
    e_a: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self) -> None:
        for name in ("k_g", "k_a_pos", "k_a_neg", "d_g", "d_a"):
            v = np.array(getattr(self, name), dtype=float).reshape(3)
            object.__setattr__(self, name, v)
        for name in ("e_g", "e_a"):
            object.__setattr__(self, name, np.array(getattr(self, name), dtype=float).reshape(3, 3))
        for name in ("k_g", "k_a_pos", "k_a_neg"):
            if not np.all(np.isfinite(getattr(self, name))) or np.any(getattr(self, name) <= 0):
                raise ValueError(f"{name} must be finite and > 0, got {getattr(self, name)}")

    @classmethod
    def nominal(cls, k_g: float | np.ndarray, k_a: float | np.ndarray) -> "SensorModel":
        """Nominal scale factors, no bias, no misalignment, K_a⁺ = K_a⁻."""
        k_g = np.broadcast_to(np.asarray(k_g, float), (3,)).copy()
        k_a = np.broadcast_to(np.asarray(k_a, float), (3,)).copy()
        return cls(k_g=k_g, k_a_pos=k_a, k_a_neg=k_a.copy())

    def with_(self, **changes) -> "SensorModel":
        return replace(self, **changes)

    def compensate(self, gyro_pulses: np.ndarray, accel_pulses: np.ndarray, dt_s: float
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Invert the pulse model: angle increments Δθ [rad] and velocity increments Δv [m/s]
        (n, 3) from pulse counts (n, 3) over samples of ``dt_s`` seconds."""
        ng = np.ascontiguousarray(gyro_pulses, dtype=float)
        na = np.ascontiguousarray(accel_pulses, dtype=float)
        # one compiled pass (estimators/_strapdown_kernel.py): numpy's version makes five
        # (n, 3) temporaries, ~11 ms per 40-min window at 100 Hz, twice per calibration window
        dtheta, dv = compensate_loop(ng, na, 1.0 / self.k_g, self.d_g, np.linalg.inv(self.e_g),
                                     1.0 / self.k_a_pos, 1.0 / self.k_a_neg, self.d_a,
                                     np.linalg.inv(self.e_a), float(dt_s))
        return dtheta, dv

    def pulses(self, dtheta: np.ndarray, dv: np.ndarray, dt_s: float
               ) -> tuple[np.ndarray, np.ndarray]:
        """The forward model without noise or quantisation (real-valued pulses) — for tests and
        for synthesising ideal data; the sign of the accelerometer input picks K_a^±."""
        y_g = self.d_g * dt_s + np.einsum("nj,ij->ni", np.asarray(dtheta, float), self.e_g)
        y_a = self.d_a * dt_s + np.einsum("nj,ij->ni", np.asarray(dv, float), self.e_a)
        return self.k_g * y_g, np.where(y_a >= 0, self.k_a_pos, self.k_a_neg) * y_a


# ------------------------------------------------------------------------------ navigation

@dataclass
class NavSolution:
    """Navigation at the end of each sample: ``t_s`` (n,) time since the start [s],
    ``q_bi`` (n, 4) body → i0 quaternions, ``v`` (n, 3) ENU velocity [m/s] (the velocity error,
    the truth being zero), ``c0`` the initial attitude, ``w_ie`` ω_ie^n [rad/s]."""

    t_s: np.ndarray
    q_bi: np.ndarray
    v: np.ndarray
    c0: np.ndarray
    w_ie: np.ndarray

    def attitude(self, index: np.ndarray | slice | None = None) -> np.ndarray:
        """C_b^n (body → ENU) at the ends of the selected samples, (m, 3, 3)."""
        sel = slice(None) if index is None else index
        c_bi = quat_to_dcm(self.q_bi[sel])
        t = np.atleast_1d(self.t_s[sel])
        c_in = rotation_matrix(-np.outer(t, self.w_ie))
        return c_in @ c_bi


def coarse_level(c_cmd: np.ndarray, dv_mean: np.ndarray) -> np.ndarray:
    """Static levelling: the attitude closest to the commanded ``c_cmd`` (body → ENU) whose
    measured mean specific force ``dv_mean`` (body, any scale) points Up.

    Heading is kept from the commanded table angles (gyrocompassing over a short dwell would
    be far less accurate than the table); the tilt comes from the accelerometers.
    """
    f_n = c_cmd @ (dv_mean / np.linalg.norm(dv_mean))
    up = np.array([0.0, 0.0, 1.0])
    axis = np.cross(f_n, up)
    s = np.linalg.norm(axis)
    if s < 1e-15:
        return np.array(c_cmd, dtype=float)
    angle = math.atan2(s, float(f_n @ up))
    return rotation_matrix(axis / s * angle) @ c_cmd


def navigate(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, c0: np.ndarray,
             latitude_deg: float, height_m: float = 0.0, v0: np.ndarray | None = None,
             gravity: float | None = None, breaks: np.ndarray | None = None) -> NavSolution:
    """Strapdown navigation at a fixed site from angle/velocity increments (n, 3) [rad, m/s].

    ``c0`` initial attitude body → ENU at the start of sample 0; ``latitude_deg`` [°] and
    ``height_m`` [m] fix Earth rate and normal gravity (``gravity`` [m/s²] overrides γ);
    ``v0`` initial velocity [m/s] (default 0); ``breaks`` sample indices at which the table
    rate steps (the commanded motion boundaries): the two-sample coning term does not reach
    back across them (its linear-rate model does not hold over a rate step).
    See the module docstring for the algorithms.
    """
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    n = dtheta.shape[0]
    w_ie = earth_rate_enu(latitude_deg)
    g = normal_gravity(latitude_deg, height_m) if gravity is None else float(gravity)
    # two-sample coning (Savage 2007 eq. 7.1.1.1-11 with the linear-rate model), no reach-back
    # across the commanded rate steps; quaternion recursion; velocity: rotation correction
    # exact for a constant rate over the sample (the inverse SO(3) Jacobian, ΔV = Δv + ½α×Δv +
    # (1/12)α×(α×Δv)), into i0 with the attitude at the sample start, then into ENU at the
    # sample middle — one compiled pass over the samples (estimators/_strapdown_kernel.py)
    is_break = np.zeros(n, dtype=np.bool_)
    if breaks is not None and len(breaks):
        b = np.asarray(breaks, dtype=np.intp)
        is_break[b[(b > 0) & (b < n)]] = True
    w = -w_ie
    rate = float(np.linalg.norm(w))
    k_axis = w / rate if rate > 0 else np.zeros(3)
    q_bi, v = strapdown_loop(dtheta, dv, float(dt_s), dcm_to_quat(c0), is_break, k_axis, rate,
                             float(g))
    t = (np.arange(n) + 1.0) * dt_s
    if v0 is not None:
        v += np.asarray(v0, float)
    return NavSolution(t, q_bi, v, np.asarray(c0, float), w_ie)
