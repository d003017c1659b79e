"""Monte Carlo units of the aided navigator on a simulated route: the filter's consistency
(NEES) and its coasting error through GNSS outages (benchmarks/bench_aided_nees.py, tests).

A unit draws, from its own seed, exactly the errors the filter models
(:class:`rlgsim.estimators.ins.aided.AidingModel`): constant gyro and accelerometer biases
(1σ as the model's initial bias σ), white angle and velocity noise on every increment (ARW,
VRW), an initial position, velocity and attitude error from the initial covariance, and fixes
with white ENU noise once a second where the route's sky is visible, and the velocity a stop
detector reports at the vehicle's stops with white noise σ_zupt. The increments themselves
are the route's exact ones (:mod:`rlgsim.sim.motion.trajectory`); the vehicle's stops
(speed 0) are the zero-velocity flags. So the errors the filter reports should be inside its
covariance at the rate it claims: NEES eᵀP⁻¹e ~ χ²(15), and its mean over N units inside the
χ² band [χ²_{0.025}(15N)/N, χ²_{0.975}(15N)/N] at ~95 % of the epochs (Bar-Shalom, Li &
Kirubarajan 2001, §5.4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from rlgsim.estimators.ins.aided import (N_STATES, AidedSolution, AidingModel, aided_navigation,
                                         nees)
from rlgsim.estimators.ins.alignment import attitude_error
from rlgsim.estimators.ins.mechanization import InsState
from rlgsim.ground.earth import radii_of_curvature_rad
from rlgsim.ground.frames import dcm_to_quat, quat_from_rotvec, quat_mul, quat_to_dcm
from rlgsim.ground.units import DEG

#: a navigation-grade RLG IMU (the filter's model and the drawn errors): ARW 0.002 °/√h,
#: VRW 20 µg/√Hz, gyro bias 0.005 °/h, accelerometer bias 50 µg
NAV_GRADE = AidingModel(arw=0.002 * DEG / 60.0, vrw=20e-6 * 9.80665,
                        gyro_bias_sigma=0.005 * DEG / 3600.0, accel_bias_sigma=50e-6 * 9.80665)


@dataclass
class Route:
    """A route sampled for the units: exact increments (n, 3) at ``rate_hz``, the truth at the
    filter epochs (every ``update_every`` samples) and per-sample stop flags and sky."""

    dtheta: np.ndarray
    dv: np.ndarray
    rate_hz: float
    update_every: int
    epoch_t: np.ndarray
    truth: object                      # the KinematicState at the epochs
    start: object                      # the KinematicState at 0
    stopped: np.ndarray
    visible_at: np.ndarray             # sky visible at each epoch (fix available)
    fix_truth: object                  # KinematicState at the fix epochs


def sample_route(trajectory, duration_s: float, rate_hz: float = 50.0,
                 update_every: int = 50, start_s: float = 0.0) -> Route:
    """The exact increments and truths of ``trajectory`` over ``duration_s`` from ``start_s``
    (on the sample grid; the route's times count from ``start_s``)."""
    n = int(round(duration_s * rate_hz))
    k_start = int(round(start_s * rate_hz))
    per = int(round(600 * rate_hz))
    parts = [trajectory.increments((k_start + k) / rate_hz, min(per, n - k), rate_hz,
                                   angles=False) for k in range(0, n, per)]
    t_end = (k_start + np.arange(n) + 1) / rate_hz
    speed = np.linalg.norm(trajectory.truth(t_end)["v_n"], axis=1)
    epoch_t = t_end[update_every - 1::update_every]
    truth = trajectory.states(epoch_t)
    visible = trajectory.gnss_visible(epoch_t)
    return Route(np.concatenate([p.dtheta_rad for p in parts]),
                 np.concatenate([p.dv_m_per_s for p in parts]), rate_hz, update_every,
                 epoch_t - k_start / rate_hz, truth,
                 trajectory.states(np.array([k_start / rate_hz])), speed == 0.0, visible, truth)


def run_unit(route: Route, seed: int, model: AidingModel = NAV_GRADE,
             filter_model: AidingModel | None = None) -> tuple[AidedSolution, np.ndarray]:
    """One unit: the aided solution and its true errors (m, 15) at the epochs (module
    docstring; the error convention of :mod:`rlgsim.estimators.ins.aided`). The errors are
    drawn from ``model``; the filter assumes ``filter_model`` (default: the same)."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / route.rate_hz
    n = route.dtheta.shape[0]
    bg = rng.normal(0.0, model.gyro_bias_sigma, 3)
    ba = rng.normal(0.0, model.accel_bias_sigma, 3)
    dth = route.dtheta + bg * dt + rng.normal(0.0, model.arw * np.sqrt(dt), (n, 3))
    dv = route.dv + ba * dt + rng.normal(0.0, model.vrw * np.sqrt(dt), (n, 3))
    s0 = route.start
    dp = rng.normal(0.0, model.position_sigma)
    dvel = rng.normal(0.0, model.velocity_sigma)
    psi = rng.normal(0.0, model.attitude_sigma)
    rm, rn = radii_of_curvature_rad(s0.lat[0])
    q_true = dcm_to_quat(s0.c_bn[0])
    q0 = quat_mul(quat_from_rotvec(-psi), q_true)          # C_est = (I − [ψ×]) C_true
    start = InsState(q0 / np.linalg.norm(q0), s0.v_n[0] + dvel,
                     s0.lat[0] + dp[1] / (rm + s0.height[0]),
                     s0.lon[0] + dp[0] / ((rn + s0.height[0]) * np.cos(s0.lat[0])),
                     s0.height[0] + dp[2])
    tr = route.truth
    fix = route.visible_at
    m_rm, m_rn = radii_of_curvature_rad(tr.lat)
    noise = rng.normal(0.0, [model.fix_sigma_h_m, model.fix_sigma_h_m, model.fix_sigma_u_m],
                       (tr.lat.size, 3))
    sol = aided_navigation(
        start, dth, dv, dt, filter_model or model, fix_t_s=route.epoch_t[fix],
        fix_lat=(tr.lat + noise[:, 1] / (m_rm + tr.height))[fix],
        fix_lon=(tr.lon + noise[:, 0] / ((m_rn + tr.height) * np.cos(tr.lat)))[fix],
        fix_h=(tr.height + noise[:, 2])[fix], stopped=route.stopped,
        stop_velocity=rng.normal(0.0, model.zupt_sigma_m_s, (n, 3)),
        update_every=route.update_every)
    err = np.empty((sol.t_s.size, N_STATES))
    err[:, 0] = (sol.lon - tr.lon) * (m_rn + tr.height) * np.cos(tr.lat)
    err[:, 1] = (sol.lat - tr.lat) * (m_rm + tr.height)
    err[:, 2] = sol.h - tr.height
    err[:, 3:6] = sol.v - tr.v_n
    err[:, 6:9] = attitude_error(quat_to_dcm(sol.q), tr.c_bn)
    err[:, 9:12] = bg - sol.gyro_bias
    err[:, 12:15] = ba - sol.accel_bias
    return sol, err


def nees_band(units: int, dof: int = N_STATES, level: float = 0.95) -> tuple[float, float]:
    """The two-sided χ² band of the mean NEES over ``units`` units."""
    a = (1.0 - level) / 2.0
    return (chi2.ppf(a, dof * units) / units, chi2.ppf(1.0 - a, dof * units) / units)


def monte_carlo(route: Route, units: int, seed0: int = 0, model: AidingModel = NAV_GRADE
                ) -> dict[str, np.ndarray]:
    """``units`` units: the mean NEES per epoch, the horizontal errors (units, m) and the true
    errors (units, m, 15)."""
    errs, ness = [], []
    for u in range(units):
        sol, err = run_unit(route, seed0 + u, model)
        errs.append(err)
        ness.append(nees(err, sol.P))
    errs = np.array(errs)
    return {"mean_nees": np.mean(ness, axis=0), "errors": errs,
            "horizontal": np.hypot(errs[:, :, 0], errs[:, :, 1])}
