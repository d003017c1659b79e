"""Aided navigation: the strapdown navigator corrected by position fixes and zero-velocity
stops through a loosely coupled error-state Kalman filter.

The navigator is :func:`rlgsim.estimators.ins.mechanization.integrate` (free vertical channel),
run over one update interval at a time (default 1 s) on increments corrected by the filter's
current sensor-bias estimates. Its errors are the filter's 15 states (ENU, Groves 2013 §14.2;
Titterton & Weston 2004 §12.3):

    x = (δp (3) [m], δv (3) [m/s], ψ (3) [rad], δb_g (3) [rad/s], δb_a (3) [m/s²])

with δp, δv the navigator's position and velocity minus the truth, ψ its attitude error
C_est = (I − [ψ×]) C_true (as :func:`rlgsim.estimators.ins.alignment.attitude_error`) and δb
the true sensor biases minus the estimates. The continuous model:

    δṗ = δv
    δv̇ = f^n × ψ + C_b^n δb_a − (2ω_ie^n + ω_en^n) × δv + (0, 0, 2γ/R δp_U)
    ψ̇  = −ω_in^n × ψ + (−δv_N/(R_M + h), δv_E/(R_N + h), δv_E tan L/(R_N + h)) − C_b^n δb_g
    δḃ_g = w_g,   δḃ_a = w_a                                  (random walks, possibly zero)

driven by the gyros' and accelerometers' white noise (ARW, VRW) and discretised over each
interval T as Φ = exp(F T) and Q_d = ½ (Φ Q_c Φᵀ + Q_c) T (trapezoid). Measurements, each a
linear update of :class:`filterpy.kalman.KalmanFilter`:

* a **position fix** (GNSS-like, at its epochs, noise σ_h, σ_u): z = p_nav − p_fix in ENU metres;
* a **zero-velocity stop** (the vehicle known to stand): z = v_nav − v_reported (the stop
  detector's velocity, 0 by default), noise σ_zupt.

After each update the estimate is fed back — position, velocity, attitude (q ← exp(ψ/2) ⊗ q,
C_true = (I + [ψ×]) C_est) and the bias estimates — and the error state reset to zero
(closed-loop, as gnss-ins-sim's ``ins_loose`` peer). The filter's covariance is its claim about
those errors; the NEES over Monte Carlo units checks it (benchmarks/bench_aided_nees.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from filterpy.kalman import KalmanFilter
from threadpoolctl import threadpool_limits

from rlgsim.estimators.ins.mechanization import InsState, integrate
from rlgsim.ground.earth import (earth_rate_enu, normal_gravity, radii_of_curvature,
                                 transport_rate_enu)
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import quat_from_rotvec, quat_mul, quat_to_dcm, skew
from rlgsim.ground.units import DEG

N_STATES = 15


@dataclass(frozen=True)
class AidingModel:
    """What the filter assumes: white noise ``arw`` [rad/√s] and ``vrw`` [(m/s)/√s]; bias
    random walks ``gyro_bias_rw`` [rad/s/√s], ``accel_bias_rw`` [m/s²/√s]; the initial 1σ of
    position [m], velocity [m/s], attitude [rad] (3 each, ENU) and biases [rad/s, m/s²];
    fix noise ``fix_sigma_h_m``, ``fix_sigma_u_m``; zero-velocity noise ``zupt_sigma_m_s``."""

    arw: float
    vrw: float
    gyro_bias_sigma: float
    accel_bias_sigma: float
    position_sigma: tuple[float, float, float] = (3.0, 3.0, 5.0)
    velocity_sigma: tuple[float, float, float] = (0.05, 0.05, 0.05)
    attitude_sigma: tuple[float, float, float] = (1e-4, 1e-4, 1e-3)
    gyro_bias_rw: float = 0.0
    accel_bias_rw: float = 0.0
    fix_sigma_h_m: float = 3.0
    fix_sigma_u_m: float = 5.0
    zupt_sigma_m_s: float = 0.01

    def initial_covariance(self) -> np.ndarray:
        return np.diag(np.r_[np.square(self.position_sigma), np.square(self.velocity_sigma),
                             np.square(self.attitude_sigma), [self.gyro_bias_sigma ** 2] * 3,
                             [self.accel_bias_sigma ** 2] * 3])


@dataclass
class AidedSolution:
    """At the end of every update interval: ``t_s`` (m,), the corrected ``lat``, ``lon`` [rad],
    ``h`` [m], ``v`` (m, 3), ``q`` (m, 4); the bias estimates ``gyro_bias`` [rad/s] and
    ``accel_bias`` [m/s²] (m, 3); the covariance ``P`` (m, 15, 15) after the epoch's updates;
    ``fixed`` (m,) whether a fix was used, ``stopped`` whether a zero-velocity update was."""

    t_s: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v: np.ndarray
    q: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    P: np.ndarray
    fixed: np.ndarray
    stopped: np.ndarray


def error_dynamics(c_bn: np.ndarray, f_n: np.ndarray, lat: float, h: float, v: np.ndarray
                   ) -> np.ndarray:
    """F (15, 15) of the module docstring at attitude ``c_bn``, specific force ``f_n`` (ENU)
    [m/s²], latitude [rad], height [m] and ENU velocity [m/s]."""
    lat_deg = lat / DEG
    w_ie = earth_rate_enu(lat_deg)
    w_en = transport_rate_enu(lat_deg, h, v)
    r_m, r_n = radii_of_curvature(lat_deg)
    gamma = normal_gravity(lat_deg, h)
    f = np.zeros((N_STATES, N_STATES))
    f[0:3, 3:6] = np.eye(3)
    f[3:6, 6:9] = skew(f_n)
    f[3:6, 12:15] = c_bn
    f[3:6, 3:6] = -skew(2.0 * w_ie + w_en)
    f[5, 2] = 2.0 * gamma / (r_m + h)
    f[6:9, 6:9] = -skew(w_ie + w_en)
    f[6, 4] = -1.0 / (r_m + h)
    f[7, 3] = 1.0 / (r_n + h)
    f[8, 3] = math.tan(lat) / (r_n + h)
    f[6:9, 9:12] = -c_bn
    return f


def _enu_offset(lat: float, lon: float, h: float, lat0: float, lon0: float, h0: float
                ) -> np.ndarray:
    r_m, r_n = radii_of_curvature(lat0 / DEG)
    return np.array([(lon - lon0) * (r_n + h0) * math.cos(lat0), (lat - lat0) * (r_m + h0),
                     h - h0])


def aided_navigation(start: InsState, dtheta: np.ndarray, dv: np.ndarray, dt_s: float,
                     model: AidingModel, *, fix_t_s: np.ndarray | None = None,
                     fix_lat: np.ndarray | None = None, fix_lon: np.ndarray | None = None,
                     fix_h: np.ndarray | None = None, stopped: np.ndarray | None = None,
                     stop_velocity: np.ndarray | None = None, update_every: int = 100
                     ) -> AidedSolution:
    """Navigate increments Δθ, Δv (n, 3) of ``dt_s`` from ``start`` with fixes at times
    ``fix_t_s`` [s from the start; used at the end of the update interval they fall in]
    (``fix_lat``, ``fix_lon`` [rad], ``fix_h`` [m]) and zero-velocity flags ``stopped`` (n,)
    (the vehicle stands during the sample; used when the interval's last sample stands) with
    the velocity a stop detector reports ``stop_velocity`` (n, 3) [m/s] (default 0), one
    filter epoch every ``update_every`` samples (module docstring)."""
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    n = dtheta.shape[0]
    if dv.shape != dtheta.shape or dtheta.ndim != 2 or dtheta.shape[1] != 3 or n == 0:
        raise UserInputError(f"aided navigation: need Δθ and Δv of shape (n, 3), got "
                             f"{dtheta.shape} and {dv.shape}")
    step = int(update_every)
    if step < 1:
        raise UserInputError(f"aided navigation: update_every = {update_every!r}; need >= 1")
    fixes = {}
    if fix_t_s is not None:
        k = np.ceil(np.asarray(fix_t_s, dtype=float) / (step * dt_s) - 1e-9).astype(np.int64)
        for i, e in enumerate(k.tolist()):
            fixes.setdefault(e, (fix_lat[i], fix_lon[i], fix_h[i]))
    kf = KalmanFilter(dim_x=N_STATES, dim_z=3)
    kf.P = model.initial_covariance()
    out: dict = {k: [] for k in ("t", "lat", "lon", "h", "v", "q", "bg", "ba", "P", "fix",
                                 "zupt")}
    state = start
    # 15×15 products: a threaded BLAS only adds synchronisation (8× slower on a busy machine)
    with threadpool_limits(1):
        _run_epochs(kf, state, dtheta, dv, dt_s, model, step, n, fixes, stopped, stop_velocity,
                    out)
    return AidedSolution(np.array(out["t"]), np.array(out["lat"]), np.array(out["lon"]),
                         np.array(out["h"]), np.array(out["v"]), np.array(out["q"]),
                         np.array(out["bg"]), np.array(out["ba"]), np.array(out["P"]),
                         np.array(out["fix"]), np.array(out["zupt"]))


def _run_epochs(kf: KalmanFilter, state: InsState, dtheta: np.ndarray, dv: np.ndarray,
                dt_s: float, model: AidingModel, step: int, n: int, fixes: dict,
                stopped: np.ndarray | None, stop_velocity: np.ndarray | None,
                out: dict) -> None:
    """The filter's epochs (:func:`aided_navigation`), appending to ``out``."""
    qc = np.zeros((N_STATES, N_STATES))
    qc[3:6, 3:6] = np.eye(3) * model.vrw ** 2
    qc[6:9, 6:9] = np.eye(3) * model.arw ** 2
    qc[9:12, 9:12] = np.eye(3) * model.gyro_bias_rw ** 2
    qc[12:15, 12:15] = np.eye(3) * model.accel_bias_rw ** 2
    r_fix = np.diag([model.fix_sigma_h_m ** 2] * 2 + [model.fix_sigma_u_m ** 2])
    r_zupt = np.eye(3) * model.zupt_sigma_m_s ** 2
    h_pos = np.hstack([np.eye(3), np.zeros((3, 12))])
    h_vel = np.hstack([np.zeros((3, 3)), np.eye(3), np.zeros((3, 9))])
    bg, ba = np.zeros(3), np.zeros(3)
    for e in range(1, -(-n // step) + 1):
        lo, hi = (e - 1) * step, min(e * step, n)
        T = (hi - lo) * dt_s
        c0 = state.c_bn
        sol = integrate(state, dtheta[lo:hi] - bg * dt_s, dv[lo:hi] - ba * dt_s, dt_s,
                        height=None, output_every=hi - lo)
        state = sol.final
        # error dynamics at the interval's middle attitude and mean specific force
        f_n = 0.5 * (c0 + state.c_bn) @ ((dv[lo:hi] - ba * dt_s).sum(axis=0) / T)
        F = error_dynamics(0.5 * (c0 + state.c_bn), f_n, state.lat, state.h, state.v)
        phi = scipy.linalg.expm(F * T)
        kf.F, kf.Q = phi, 0.5 * (phi @ qc @ phi.T + qc) * T
        kf.x = np.zeros((N_STATES, 1))
        kf.predict()
        used_fix = e in fixes
        if used_fix:
            la, lo_, hh = fixes[e]
            z = _enu_offset(state.lat, state.lon, state.h, la, lo_, hh)
            kf.update(z.reshape(3, 1), R=r_fix, H=h_pos)
        used_zupt = stopped is not None and bool(stopped[hi - 1])
        if used_zupt:                                     # the true velocity is 0
            z = np.asarray(state.v, dtype=float)
            if stop_velocity is not None:
                z = z - stop_velocity[hi - 1]
            kf.update(z.reshape(3, 1), R=r_zupt, H=h_vel)
        state, bg, ba = _feedback(state, kf.x.ravel(), bg, ba)
        out["t"].append(hi * dt_s)
        out["lat"].append(state.lat)
        out["lon"].append(state.lon)
        out["h"].append(state.h)
        out["v"].append(np.array(state.v))
        out["q"].append(np.array(state.q))
        out["bg"].append(bg.copy())
        out["ba"].append(ba.copy())
        out["P"].append(kf.P.copy())
        out["fix"].append(used_fix)
        out["zupt"].append(used_zupt)


def _feedback(state: InsState, x: np.ndarray, bg: np.ndarray, ba: np.ndarray
              ) -> tuple[InsState, np.ndarray, np.ndarray]:
    """The navigator corrected by the estimated errors ``x`` (module docstring)."""
    r_m, r_n = radii_of_curvature(state.lat / DEG)
    lat = state.lat - x[1] / (r_m + state.h)
    lon = state.lon - x[0] / ((r_n + state.h) * math.cos(state.lat))
    q = quat_mul(quat_from_rotvec(x[6:9]), state.q)
    q = q / np.linalg.norm(q)
    new = InsState(q, np.asarray(state.v) - x[3:6], lat, lon, state.h - x[2],
                   state._memory.copy())
    return new, bg + x[9:12], ba + x[12:15]


def nees(error: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared eᵀ P⁻¹ e of errors (…, 15) under covariances
    (…, 15, 15)."""
    sol = np.linalg.solve(P, error[..., None])[..., 0]
    return np.einsum("...i,...i->...", error, sol)


def attitude_of(q: np.ndarray) -> np.ndarray:
    """C_b^n of quaternions (…, 4)."""
    return quat_to_dcm(q)
