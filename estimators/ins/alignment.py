"""Alignment of a strapdown IMU at rest: coarse (levelling + gyrocompassing) and fine
(zero-velocity Kalman filter), giving the initial attitude C_b^n and its covariance.

**Coarse** (analytic, Titterton & Weston 2004 §10.3.1; Groves 2013 §5.6.2): over a static
segment the mean specific force points Up and the mean angular rate is the Earth rate
ω_ie^n = Ω (0, cos L, sin L) (ENU). In body axes

    u^b = f̄ / |f̄|,   e^b = (ω̄ × u^b) / |ω̄ × u^b|,   n^b = u^b × e^b,   C_b^n = [e^b; n^b; u^b]

(the rows of C_b^n are the navigation axes in body components). A gyro bias with an East
component ε_E turns e^b about Up by ψ ≈ ε_E / (Ω cos L) — the gyrocompassing limit that no
alignment at rest beats (the bias is not separable from the Earth rate); an accelerometer bias
b tilts the level by b/γ. :func:`heading_error_bound` gives the former.

**Fine** (T&W §10.3.2; Groves §14.3): the navigator runs from the coarse attitude with the
height held; its horizontal velocity, which should be zero, feeds a Kalman filter
(filterpy) on the error state x = (ψ_E, ψ_N, ψ_U, δv_E, δv_N) of the linearised ψ-angle model at
rest (T&W eqs. 12.6–12.13; C̃_b^n = (I − [ψ×]) C_b^n):

    ψ̇  = −ω_ie^n × ψ + (−δv_N/R_M, δv_E/R_E, δv_E tan L/R_E)
    δv̇ = (f^n × ψ − 2 ω_ie^n × δv)_{E,N},    f^n = (0, 0, γ)

discretised once by the matrix exponential (scipy.linalg.expm) at the filter step. Process
noise from the angle and velocity random walks, measurement noise ``velocity_sigma``. The
estimated ψ corrects the attitude at the segment end: C_b^n = exp([ψ̂×]) C̃_b^n.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from filterpy.kalman import KalmanFilter

from rlgsim.estimators.ins.mechanization import InsState, _check_increments, integrate
from rlgsim.ground.earth import earth_rate_enu, normal_gravity, radii_of_curvature
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import rotation_matrix
from rlgsim.ground.units import DEG, EARTH_RATE, HOUR, MICRO_G


def heading_error_bound(east_gyro_bias_rad_s: float, latitude_deg: float) -> float:
    """The gyrocompassing heading error ψ ≈ ε_E / (Ω_ie cos L) [rad] of an East gyro bias
    ε_E [rad/s] at latitude L [°] (T&W §10.3.1)."""
    return east_gyro_bias_rad_s / (EARTH_RATE * math.cos(latitude_deg * DEG))


def attitude_error(c_est: np.ndarray, c_true: np.ndarray) -> np.ndarray:
    """Small-angle attitude error ψ (…, 3) [rad] in ENU with C_est = (I − [ψ×]) C_true:
    ψ_U > 0 is the estimate turned clockwise seen from above (heading too large)."""
    d = np.asarray(c_true) @ np.swapaxes(np.asarray(c_est), -1, -2)   # ≈ I + [ψ×]
    a = 0.5 * (d - np.swapaxes(d, -1, -2))
    return np.stack([a[..., 2, 1], a[..., 0, 2], a[..., 1, 0]], axis=-1)


def coarse_align(dtheta: np.ndarray, dv: np.ndarray, dt_s: float) -> np.ndarray:
    """C_b^n (3, 3) from increments (n, 3) [rad, m/s] of a static segment (module docstring)."""
    dtheta, dv = _check_increments(dtheta, dv, dt_s)
    f = dv.sum(axis=0)
    w = dtheta.sum(axis=0)
    if np.linalg.norm(f) == 0.0:
        raise UserInputError("coarse alignment: the mean specific force is zero (no "
                             "accelerometer signal in the alignment segment)")
    u = f / np.linalg.norm(f)
    e = np.cross(w, u)
    ne = np.linalg.norm(e)
    if ne <= 1e-12 * np.linalg.norm(w) or ne == 0.0:
        raise UserInputError("coarse alignment: the mean rate is parallel to the specific force"
                             " (gyrocompassing needs |latitude| < 90° and working gyros)")
    e = e / ne
    return np.stack([e, np.cross(u, e), u])


@dataclass
class Alignment:
    """Result of :func:`align`: ``c_bn`` (3, 3) attitude at the end of the segment, ``cov``
    (3, 3) covariance of ψ = (ψ_E, ψ_N, ψ_U) [rad²], ``coarse`` the coarse attitude at the
    segment start, ``psi_history`` (m, 3) the filter's correction along the segment,
    ``state`` the navigator's start state (at rest, at the segment end)."""

    c_bn: np.ndarray
    cov: np.ndarray
    coarse: np.ndarray
    psi_history: np.ndarray
    state: InsState

    @property
    def heading_sigma_rad(self) -> float:
        return float(math.sqrt(self.cov[2, 2]))


def error_model_matrix(latitude_deg: float, height_m: float = 0.0) -> np.ndarray:
    """F (5, 5) of the fine-alignment error state (ψ_E, ψ_N, ψ_U, δv_E, δv_N) at rest."""
    w = earth_rate_enu(latitude_deg)
    g = normal_gravity(latitude_deg, height_m)
    r_m, r_e = radii_of_curvature(latitude_deg)
    r_m, r_e = r_m + height_m, r_e + height_m
    tl = math.tan(latitude_deg * DEG)
    f = np.zeros((5, 5))
    wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    f[0:3, 0:3] = -wx
    f[0, 4] = -1.0 / r_m
    f[1, 3] = 1.0 / r_e
    f[2, 3] = tl / r_e
    f[3, 1] = -g                     # (f × ψ)_E = −γ ψ_N
    f[4, 0] = g                      # (f × ψ)_N = +γ ψ_E
    f[3, 4] = 2.0 * w[2]             # −2 (ω × δv)_E = 2 Ω sinL δv_N
    f[4, 3] = -2.0 * w[2]
    return f


@functools.lru_cache(maxsize=32)
def _transition(latitude_deg: float, height_m: float, step_s: float) -> np.ndarray:
    """exp(F Δt) of :func:`error_model_matrix` (cached: a study aligns many variants at one
    site)."""
    phi = scipy.linalg.expm(error_model_matrix(latitude_deg, height_m) * step_s)
    phi.setflags(write=False)
    return phi


def align(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, latitude_deg: float,
          longitude_deg: float = 0.0, height_m: float = 0.0, *, step_s: float = 1.0,
          arw_deg_rt_h: float = 0.003, vrw_ug_rt_hz: float = 30.0,
          velocity_sigma: float = 1e-3, tilt_sigma_rad: float = 1e-3,
          heading_sigma_rad: float = 0.05) -> Alignment:
    """Coarse then fine alignment over a static segment (increments (n, 3), module docstring).

    ``step_s`` the filter's measurement interval [s] (a multiple of ``dt_s``);
    ``arw_deg_rt_h`` [°/√h] and ``vrw_ug_rt_hz`` [µg/√Hz] set the process noise;
    ``velocity_sigma`` [m/s] the zero-velocity measurement noise; the two sigmas [rad] the
    prior of the coarse attitude. The coarse attitude uses the first half of the segment.
    """
    dtheta, dv = _check_increments(dtheta, dv, dt_s)
    every = max(1, int(round(step_s / dt_s)))
    n = dtheta.shape[0]
    if n < 4 * every:
        raise UserInputError(f"alignment: the static segment has {n} samples; need at least "
                             f"{4 * every} ({4 * every * dt_s:g} s)")
    c0 = coarse_align(dtheta[: n // 2], dv[: n // 2], dt_s)
    start = InsState.at_rest(c0, latitude_deg, longitude_deg, height_m)
    sol = integrate(start, dtheta, dv, dt_s, output_every=every)
    h_kf = every * dt_s
    kf = KalmanFilter(dim_x=5, dim_z=2)
    kf.F = _transition(float(latitude_deg), float(height_m), float(h_kf))
    kf.H = np.array([[0, 0, 0, 1.0, 0], [0, 0, 0, 0, 1.0]])
    arw = arw_deg_rt_h * DEG / math.sqrt(HOUR)
    vrw = vrw_ug_rt_hz * MICRO_G
    kf.Q = np.diag([arw ** 2] * 3 + [vrw ** 2] * 2) * h_kf
    kf.R = np.eye(2) * velocity_sigma ** 2
    kf.P = np.diag([tilt_sigma_rad ** 2] * 2 + [heading_sigma_rad ** 2] + [velocity_sigma ** 2] * 2)
    kf.x = np.zeros(5)
    hist = np.empty((sol.v.shape[0], 3))
    for k in range(sol.v.shape[0]):
        kf.predict()
        kf.update(sol.v[k, :2])
        hist[k] = kf.x[:3]
    psi = kf.x[:3].copy()
    c_end = rotation_matrix(psi) @ sol.attitude()[-1]
    state = InsState.at_rest(c_end, sol.lat[-1] / DEG, sol.lon[-1] / DEG, height_m)
    state.lat, state.lon = float(sol.lat[-1]), float(sol.lon[-1])
    return Alignment(c_end, kf.P[:3, :3].copy(), c0, hist, state)
