"""Systematic-calibration Kalman filter for one turntable window (paper 000 §4.1).

The IMU stands at the centre of the turntable; a strapdown navigation
(:mod:`rlgsim.estimators.strapdown`) integrates its compensated pulses; its velocity — whose true
value is zero — is the measurement during the static dwells. A Kalman filter estimates the
sensor errors from it; the estimates are fed back into the pulse model and the whole window is
navigated again, until the corrections stop changing (iterated, feedback calibration:
Cai Q. et al., "Systematic calibration for ultra-high accuracy inertial measurement units",
Sensors 16(6):940, 2016).

Why the filter step is not filterpy's ``KalmanFilter``: its predict and update are the
textbook dense ones (F P Fᵀ with the full 51×51 F, a dense Joseph form) and keep nothing for
later. Here only the 6 navigation-error rows of F change per step (and 18 bias-wander rows
are not identity rows), and H = [0 I 0] selects δv, so :func:`run_filter` writes the same
equations (filterpy's update in Joseph form, same order) on those rows — a test pins the
estimates to those of the filterpy version to 1e-5 σ — and records the gains. A pass whose
linearisation point is within ``FilterSettings.reuse_tol`` (relative change of the Jacobian,
:func:`linearisation_distance`) of the window's earlier full pass — the later passes of a
window — reuses those gains. Gains are never carried from one window to the next: a window's
estimates depend on its own pulses only, never on what the process calibrated before, so a
campaign gives the same bytes for any number of worker processes and any window order
(:func:`rerun_filter`: a fixed-gain, chord-Newton pass). The step loops of both passes run
compiled (numba, :mod:`rlgsim.estimators._kalman_kernel`: the same algebra without ~20 array
calls per step, the zero columns of F skipped); a full pass of a 40-min window takes ~25 ms
instead of ~100 ms, a fixed-gain pass ~2 ms. The
navigation and the convergence test are unchanged, so the iteration still ends at the
nonlinear fixed point to within the gains' mismatch: a few 1e-3 σ at the default 1e-3, σ within
0.2 % (test_window_estimates_equal_their_values_before_the_speed_up).

State vector (33; 51 with the slow bias noise below), in the filter's scaled units
(docs/calibration.md)
------------------------------------------------------------------------------------
====== ========== ==========================================================================
index  unit       state
====== ========== ==========================================================================
0–2    arcsec     φ attitude error (ENU), computed C̃_b^n = (I − [φ×]) C_b^n
3–5    mm/s       δv velocity error (ENU) = navigated velocity (the truth is zero)
6–8    °/h        b_g gyro bias error, ω̂ − ω ∋ b_g
9–11   ppm        s_g gyro scale-factor error, true K_g = K̂_g (1 + s_g)
12–17  arcsec     Γ_g gyro misalignment error Γ_xy, Γ_xz, Γ_yx, Γ_yz, Γ_zx, Γ_zy (E_g − Ê_g)
18–20  µg         b_a accelerometer bias error
21–23  ppm        s_a⁺ positive-input scale-factor error, true K_a⁺ = K̂_a⁺ (1 + s_a⁺)
24–26  ppm        s_a⁻ negative-input scale-factor error
27–29  arcsec     Γ_a accelerometer misalignment error Γ_yx, Γ_zx, Γ_zy (lower triangle)
30–32  arcsec     φ₀ attitude error at the window start (a constant copy, for feedback)
====== ========== ==========================================================================

The body frame is defined by the accelerometers (x along accelerometer x, y in the plane of
accelerometers x and y), so only the three lower-triangular accelerometer misalignments are
estimated; with zero velocity as the only measurement a common rotation of both sensor triads
is indistinguishable from an initial-attitude error (it would make three misalignments
unobservable).

Error model (continuous; Titterton & Weston 2004 §12.3, ψ/φ-angle form, fixed site):

    φ̇  = −ω_ie^n × φ − C_b^n δω,    δω = b_g + s_g∘ω^b + Γ_g ω^b
    δv̇ = f^n × φ + C_b^n δf,        δf = b_a + s_a⁺∘f⁺ + s_a⁻∘f⁻ + Γ_a f^b

with f^n = (0, 0, γ) exactly (no lever arm), f⁺ = max(f^b, 0), f⁻ = min(f^b, 0) per axis, and
no Coriolis term (consistently left out of the navigation: the true velocity is zero). With
ξ = (φ, δv) this is ξ̇ = M ξ + B(t) p + G w, M = [[−ω_ie×, 0], [f^n×, 0]] constant, and
B(t) = [[−C[I | diag ω | Γ-map(ω)], 0], [0, C[I | diag f⁺ | diag f⁻ | L-map(f)]]].

Discretisation at the KF step T (default 1 s: the KF runs decimated; the navigation runs at the
sample rate): Φ_ξξ = expm(M T) (constant), Φ_ξp = Σ_j expm(M (T − τ_j)) ∫_j B dt over m
sub-steps (default 5 per step) with ∫_j B dt built from the sub-step's accumulated increments
(Σ Δθ, Σ Δv⁺, Σ Δv⁻) and the navigated attitude at the sub-step middle; parameters are
constant within a window (Φ_pp = I, optional random walk). Process noise G w: gyro angle
random walk w_g (PSD ARW² per axis) into φ through −C, accelerometer velocity random walk w_a
(PSD VRW²) into δv through C; Q_ξ = ∫₀ᵀ e^{Ms} G Q_c Gᵀ e^{Mᵀs} ds in closed form with
Ω_ie neglected inside the step (relative error ~Ω T ≈ 7e-5):

    Q_φφ = Q_g T,   Q_vφ = F Q_g T²/2,   Q_vv = Q_a T + F Q_g Fᵀ T³/3,
    Q_g = C diag(ARW²) Cᵀ,  Q_a = C diag(VRW²) Cᵀ,  F = [f^n×]

Slow bias noise: with bias instability or rate random walk in the settings, 18 more states
carry the bias wander per axis — a fast and a slow Gauss–Markov process standing for the flicker
decades (Keshner 1982) plus the random walk, and their running mean over the window — and the
reported biases are window means (docs/calibration.md, "Slow bias noise").

Thermal drift in a window (``FilterSettings.accel_drift``; docs/calibration.md): 9 more
constant states δ, the change over the window of b_a, s_a⁺, s_a⁻, enter F through their
parameters' columns of Φ_ξp times (t_k/T_w − 1/2) at the step middle; not fed back, so the
reported p̄ is the mid-window value, the window mean of a linear drift during a ramp.

Measurement: z = v̂(t_k) at KF step ends that lie inside a static dwell (minus a margin after
and before the table moves), H = [0 I 0], R = σ_v² I.

Observability (which motion shows which state; docs/calibration.md): the dwells in 19
orientations separate gyro and accelerometer biases and the tilts; each ±90° turn about a
horizontal axis turns a gyro scale-factor error (and the misalignment of the other two gyros
onto the turned axis) into a tilt, which the following dwell shows as a growing velocity; each
accelerometer pointing Up and Down separates K_a⁺, K_a⁻ and bias; horizontal axes under g
expose the accelerometer misalignments.

Why this file is long: the filter's state layout (indices, names, units and scales), its
settings and the filter that uses them are one model; split apart, every index would be defined
in one file and read in another. The sequential loop is compiled in
:mod:`rlgsim.estimators._kalman_kernel`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.linalg import expm

from rlgsim.estimators._kalman_kernel import filter_loop, input_transition, rerun_loop
from rlgsim.estimators.strapdown import (ARCSEC, DEG, NavSolution, SensorModel, coarse_level,
                                  earth_rate_enu, navigate, normal_gravity, rotation_matrix,
                                  skew, table_attitude)
from rlgsim.ground.units import G0                # standard gravity for µg [m/s²]

DEG_PER_H = DEG / 3600.0          # rad/s per °/h
UG = 1e-6 * G0                    # m/s² per µg

N_STATES = 33
PHI, DV, BG, SG, MG, BA, SAP, SAN, MA, PHI0 = (slice(0, 3), slice(3, 6), slice(6, 9),
                                               slice(9, 12), slice(12, 18), slice(18, 21),
                                               slice(21, 24), slice(24, 27), slice(27, 30),
                                               slice(30, 33))
PARAMS = slice(6, 30)
#: Optional slow-bias-noise states (when the settings give bias instability or rate random
#: walk), per gyro [°/h] and accelerometer [µg] axis: a fast Gauss–Markov process f (the
#: flicker decades below a minute, stationary), a slow one s (the decades up to the window
#: length plus the random walk, starting at 0: its start value is the constant bias b), and the
#: running mean η = (1/T_w)∫(f + s) dt; the reported bias is b + η(T_w), the window mean.
FG, FA, SLG, SLA, ETA_G, ETA_A = (slice(33, 36), slice(36, 39), slice(39, 42), slice(42, 45),
                                  slice(45, 48), slice(48, 51))
N_STATES_WANDER = 51
#: Optional drift states: the change over the window δ of b_a, s_a⁺, s_a⁻ (µg, ppm).
DRIFT_OF = np.r_[18:27]
N_DRIFT = 9
SCALE_WANDER = np.array(([DEG_PER_H] * 3 + [UG] * 3) * 3)
#: Gyro misalignment states (row, column) of E_g, and accelerometer ones of E_a.
GYRO_MIS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
ACCEL_MIS = ((1, 0), (2, 0), (2, 1))
_GYRO_MIS_IDX = np.array(GYRO_MIS, dtype=np.intp)
_ACCEL_MIS_IDX = np.array(ACCEL_MIS, dtype=np.intp)

STATE_NAMES = (["phi_e", "phi_n", "phi_u", "dv_e", "dv_n", "dv_u"]
               + [f"gyro_bias_{a}" for a in "xyz"] + [f"gyro_sf_{a}" for a in "xyz"]
               + [f"gyro_mis_{'xyz'[i]}{'xyz'[j]}" for i, j in GYRO_MIS]
               + [f"accel_bias_{a}" for a in "xyz"] + [f"accel_sf_pos_{a}" for a in "xyz"]
               + [f"accel_sf_neg_{a}" for a in "xyz"]
               + [f"accel_mis_{'xyz'[i]}{'xyz'[j]}" for i, j in ACCEL_MIS]
               + ["phi0_e", "phi0_n", "phi0_u"])
STATE_UNITS = (["arcsec"] * 3 + ["mm/s"] * 3 + ["deg/h"] * 3 + ["ppm"] * 3 + ["arcsec"] * 6
               + ["ug"] * 3 + ["ppm"] * 6 + ["arcsec"] * 3 + ["arcsec"] * 3)
#: SI value of one scaled unit, per state.
SCALE = np.array([ARCSEC] * 3 + [1e-3] * 3 + [DEG_PER_H] * 3 + [1e-6] * 3 + [ARCSEC] * 6
                 + [UG] * 3 + [1e-6] * 6 + [ARCSEC] * 3 + [ARCSEC] * 3)


@dataclass(frozen=True)
class CommandedMotion:
    """One commanded turntable motion, times relative to the window start [s]."""

    t0_s: float
    t1_s: float
    kind: str                       # 'static' | 'rotate'
    axis: str | None = None
    rate_deg_s: float = 0.0
    outer_deg: float = 0.0          # at t0_s
    inner_deg: float = 0.0
    position: int | None = None
    label: str = ""


@dataclass
class FilterSettings:
    """Tuning of the calibration filter (SI unless the name says otherwise).

    ``arw_rad_per_sqrt_s`` (3,) gyro angle random walk; ``vrw_m_per_s_per_sqrt_s`` (3,)
    accelerometer velocity random walk; ``velocity_sigma_m_per_s`` measurement noise of the
    navigated velocity (accelerometer pulse quantisation and readout); ``kf_step_s`` KF step;
    ``substeps`` per KF step for the transition matrix; ``margin_s`` no measurement this close
    to a turn; ``align_s`` levelling time at the start of the first dwell; prior 1σ of the
    states in the filter's units (``prior``: dict name → σ for φ, b_g, s_g, Γ_g, b_a, s_a, Γ_a);
    ``param_random_walk`` (24,) optional random walk of the parameters [unit/√s];
    ``gyro_bias_instability_rad_per_s``, ``gyro_rrw_rad_per_s_per_sqrt_s``,
    ``accel_bias_instability_m_per_s2``, ``accel_rrw_m_per_s2_per_sqrt_s``: the slow bias
    noise (flicker, random walk), one value or one per axis (3,); when any is > 0 the filter
    carries the bias wander and its running mean (18 more states) and reports the window-mean
    biases; ``accel_drift``: 9 more states, the change δ over the window of each
    accelerometer bias and ± scale factor (linear drift, p(t) = p̄ + δ (t/T_w − 1/2)), so that
    p̄ — the reported value — is the window mean during a temperature ramp, with prior 1σ
    ``accel_drift_prior`` (µg, ppm; as wide as the parameters' own priors);
    ``max_iterations``; convergence when every parameter correction is below
    ``tol_sigma`` × its σ or ``tol_abs`` (filter units); ``reuse_tol``: a pass reuses the gains
    of the last full pass in this process (same window shape, motions and settings) when its
    linearisation point is within this relative Jacobian change of that pass's
    (:func:`linearisation_distance`); 0 runs every pass in full.
    """

    arw_rad_per_sqrt_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vrw_m_per_s_per_sqrt_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity_sigma_m_per_s: float | None = None
    kf_step_s: float = 1.0
    substeps: int = 5
    margin_s: float = 1.0
    align_s: float = 60.0
    prior: dict = field(default_factory=lambda: dict(
        phi_arcsec=300.0, dv_mm_s=1e-3, gyro_bias_deg_h=0.5, gyro_sf_ppm=1000.0,
        gyro_mis_arcsec=300.0, accel_bias_ug=1000.0, accel_sf_ppm=1000.0,
        accel_mis_arcsec=300.0))
    param_random_walk: np.ndarray | None = None
    gyro_bias_instability_rad_per_s: float | np.ndarray = 0.0
    gyro_rrw_rad_per_s_per_sqrt_s: float | np.ndarray = 0.0
    accel_bias_instability_m_per_s2: float | np.ndarray = 0.0
    accel_rrw_m_per_s2_per_sqrt_s: float | np.ndarray = 0.0
    accel_drift: bool = False
    accel_drift_prior: tuple[float, float] = (1000.0, 1000.0)
    max_iterations: int = 10
    tol_sigma: float = 1e-2
    tol_abs: float = 1e-4
    reuse_tol: float = 1e-3

    def __post_init__(self) -> None:
        self.arw_rad_per_sqrt_s = np.broadcast_to(
            np.asarray(self.arw_rad_per_sqrt_s, float), (3,)).copy()
        self.vrw_m_per_s_per_sqrt_s = np.broadcast_to(
            np.asarray(self.vrw_m_per_s_per_sqrt_s, float), (3,)).copy()
        if not self.kf_step_s > 0 or self.substeps < 1 or (
                self.velocity_sigma_m_per_s is not None and not self.velocity_sigma_m_per_s > 0):
            raise ValueError("kf_step_s, substeps and velocity_sigma_m_per_s must be positive")

    flicker_fast_tau_s: float = 20.0
    flicker_fast_decades: float = 2.0
    flicker_slow_tau_s: float = 2000.0
    flicker_slow_decades: float = 2.0

    def slow_noise(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per sensor group ('gyro', 'accel'): (σ_f² of the fast process, drive PSD q_s² of
        the slow one) per axis (3,) in SI² and SI²/s (the levels may be given per axis).

        Flicker of bias instability B is a continuum of Gauss–Markov processes with variance
        B²·ln10/π per decade of correlation time (Keshner 1982; sim/sensors/noise.py builds it the same
        way). The fast process (τ_f = 20 s) stands for the two decades 2–200 s
        (σ_f² = 2·B²·ln10/π), the slow one (τ_s = 2000 s) for the two decades 200 s–20 000 s,
        which inside a window grow from their start value (part of the bias b) like a random
        walk of intensity 2σ_s²/τ_s; the rate random walk K adds K². Slower decades are
        constant within a window. Checked against the simulator's flicker bank (many seeds:
        NEES inside the χ² band, tests/test_calibration.py)."""
        c = math.log(10.0) / math.pi
        out = {}
        for name, b, k in (("gyro", self.gyro_bias_instability_rad_per_s,
                            self.gyro_rrw_rad_per_s_per_sqrt_s),
                           ("accel", self.accel_bias_instability_m_per_s2,
                            self.accel_rrw_m_per_s2_per_sqrt_s)):
            b = np.broadcast_to(np.asarray(b, dtype=float), (3,))
            k = np.broadcast_to(np.asarray(k, dtype=float), (3,))
            out[name] = (self.flicker_fast_decades * c * b * b,
                         2.0 * (self.flicker_slow_decades * c * b * b) / self.flicker_slow_tau_s
                         + k * k)
        return out

    def velocity_sigma(self, nominal: SensorModel) -> float:
        """σ of the navigated-velocity measurement [m/s]: the given value, else the
        accelerometer pulse quantum's readout error 1/(K_a√12) (largest axis), at least 1e-6."""
        if self.velocity_sigma_m_per_s is not None:
            return float(self.velocity_sigma_m_per_s)
        k = float(np.min(np.concatenate([nominal.k_a_pos, nominal.k_a_neg])))
        return max(1.0 / (k * math.sqrt(12.0)), 1e-6)

    def prior_sigma(self) -> np.ndarray:
        """Prior 1σ of the 33 states in filter units."""
        p = self.prior
        return np.array([p["phi_arcsec"]] * 3 + [p["dv_mm_s"]] * 3 + [p["gyro_bias_deg_h"]] * 3
                        + [p["gyro_sf_ppm"]] * 3 + [p["gyro_mis_arcsec"]] * 6
                        + [p["accel_bias_ug"]] * 3 + [p["accel_sf_ppm"]] * 6
                        + [p["accel_mis_arcsec"]] * 3 + [p["phi_arcsec"]] * 3, dtype=float)


@dataclass
class WindowResult:
    """Outcome of one window: the calibrated ``model``, the 1σ of the 33 states after the last
    pass (filter units; the parameter part is the 1σ of the calibrated parameters), ``c0`` the
    calibrated initial attitude, ``iterations`` run, ``converged``, the parameter corrections of
    every pass (filter units),
    ``n_measurements`` per pass, ``nis`` mean normalised innovation squared of the last pass
    (≈ 3 when the noise model fits), ``residual_rms_m_per_s`` RMS of the navigated velocity at
    the measurement epochs of the last pass (the velocity error left by the model of that
    pass)."""

    model: SensorModel
    sigma: np.ndarray
    covariance: np.ndarray
    c0: np.ndarray
    iterations: int
    converged: bool
    corrections: list
    residual_rms_m_per_s: float
    n_measurements: int
    nis: float


# ----------------------------------------------------------------------------- model pieces

def apply_correction(model: SensorModel, x: np.ndarray) -> SensorModel:
    """Feed the estimated errors (filter units, 33 states) back into the pulse model."""
    si = x * SCALE
    e_g = model.e_g.copy()
    for (i, j), val in zip(GYRO_MIS, si[MG]):
        e_g[i, j] += val
    e_a = model.e_a.copy()
    for (i, j), val in zip(ACCEL_MIS, si[MA]):
        e_a[i, j] += val
    return SensorModel(k_g=model.k_g * (1 + si[SG]), d_g=model.d_g + si[BG], e_g=e_g,
                       k_a_pos=model.k_a_pos * (1 + si[SAP]),
                       k_a_neg=model.k_a_neg * (1 + si[SAN]), d_a=model.d_a + si[BA], e_a=e_a)


def model_difference(target: SensorModel, model: SensorModel) -> np.ndarray:
    """The parameter states (24, filter units) that :func:`apply_correction` would need to move
    ``model`` to ``target`` (to first order; exact for biases and misalignments)."""
    d = np.zeros(N_STATES)
    d[BG] = target.d_g - model.d_g
    d[SG] = target.k_g / model.k_g - 1
    d[MG] = [target.e_g[i, j] - model.e_g[i, j] for i, j in GYRO_MIS]
    d[BA] = target.d_a - model.d_a
    d[SAP] = target.k_a_pos / model.k_a_pos - 1
    d[SAN] = target.k_a_neg / model.k_a_neg - 1
    d[MA] = [target.e_a[i, j] - model.e_a[i, j] for i, j in ACCEL_MIS]
    return (d / SCALE)[PARAMS]


def _transition_pieces(nav: NavSolution, dtheta: np.ndarray, dv: np.ndarray, per_step: int,
                       per_sub: int, dt_s: float, g: float, w_ie: np.ndarray,
                       settings: FilterSettings):
    """Φ_ξξ (6, 6), Φ_ξp (K, 6, 24) and Q_ξ (K, 6, 6) for K KF steps (SI units)."""
    n_steps = dtheta.shape[0] // per_step
    m = per_step // per_sub
    n_sub = n_steps * m
    used = n_sub * per_sub
    T = per_step * dt_s
    h = per_sub * dt_s
    f_n = np.array([0.0, 0.0, g])
    F = skew(f_n)
    M = np.zeros((6, 6))
    M[0:3, 0:3] = -skew(w_ie)
    M[3:6, 0:3] = F
    phi_xx, e_j = _exponentials(M.tobytes(), T, m)
    mid = np.arange(n_sub) * per_sub + max(per_sub // 2 - 1, 0)     # sample ending mid-sub-step
    c = nav.attitude(mid)
    # Σ_j expm(M (T − τ_j)) ∫_j B dt with the sub-step sums of the increments, compiled
    # (estimators/_kalman_kernel.py; numpy's version built a (K·m, 6, 24) array first)
    phi_xp = input_transition(e_j, np.ascontiguousarray(c), np.ascontiguousarray(dtheta[:used]),
                              np.ascontiguousarray(dv[:used]), per_sub, h, _GYRO_MIS_IDX,
                              _ACCEL_MIS_IDX)
    # process noise, closed form with C at the step middle
    c_step = c.reshape(n_steps, m, 3, 3)[:, m // 2]
    qg = np.einsum("kij,j,klj->kil", c_step, settings.arw_rad_per_sqrt_s ** 2, c_step)
    qa = np.einsum("kij,j,klj->kil", c_step, settings.vrw_m_per_s_per_sqrt_s ** 2, c_step)
    q = np.zeros((n_steps, 6, 6))
    q[:, 0:3, 0:3] = qg * T
    q[:, 3:6, 0:3] = F @ qg * (T ** 2 / 2)
    q[:, 0:3, 3:6] = np.swapaxes(q[:, 3:6, 0:3], 1, 2)
    q[:, 3:6, 3:6] = qa * T + F @ qg @ F.T * (T ** 3 / 3)
    return phi_xx, phi_xp, q


@functools.lru_cache(maxsize=32)
def _exponentials(m_bytes: bytes, T: float, m: int) -> tuple[np.ndarray, np.ndarray]:
    """expm(M T) and expm(M (T − τ_j)) at the sub-step middles τ_j (cached per window shape)."""
    M = np.frombuffer(m_bytes).reshape(6, 6)
    h = T / m
    tau = (np.arange(m) + 0.5) * h
    return expm(M * T), np.stack([expm(M * (T - tj)) for tj in tau])


def measurement_mask(motions: Sequence[CommandedMotion], t_end: np.ndarray, margin_s: float
                     ) -> np.ndarray:
    """True where a KF step end time lies inside a static dwell, ``margin_s`` away from turns."""
    mask = np.zeros(t_end.shape, dtype=bool)
    for mo in motions:
        if mo.kind == "static":
            mask |= (t_end >= mo.t0_s + margin_s) & (t_end <= mo.t1_s - margin_s)
    return mask


def motion_breaks(motions: Sequence[CommandedMotion], rate_hz: float, n: int) -> np.ndarray:
    """Sample indices at which the commanded table rate steps (motion boundaries)."""
    idx = np.array([round(mo.t0_s * rate_hz) for mo in motions], dtype=np.intp)
    return idx[(idx > 0) & (idx < n)]


def initial_attitude(motions: Sequence[CommandedMotion], dv: np.ndarray, rate_hz: float,
                     align_s: float) -> np.ndarray:
    """Commanded attitude at the window start, levelled with the mean specific force over the
    first ``align_s`` seconds of the first dwell (which must start the window)."""
    first = motions[0]
    c_cmd = table_attitude(first.outer_deg, first.inner_deg)
    if first.kind != "static":
        return c_cmd
    n = int(min(align_s, first.t1_s - first.t0_s) * rate_hz)
    k0 = int(round(first.t0_s * rate_hz))
    if n < 1:
        return c_cmd
    return coarse_level(c_cmd, dv[k0:k0 + n].sum(0))


# ------------------------------------------------------------------------------ the filter

@dataclass(frozen=True)
class Linearisation:
    """What a filter pass depends on besides its measurements: the per-step transition rows,
    the gains, the innovation covariances and the final covariance, with the point (model,
    attitude fed back) they were computed at. The filter's estimate is linear in the
    measurements for fixed gains, so a later pass near that point re-runs only the cheap
    fixed-gain recursion (:func:`rerun_filter`)."""

    order: np.ndarray          # internal state order (dynamic states first) → filter index
    n_dyn: int                 # rows of F that are not identity rows
    f_dyn: np.ndarray          # (n_steps, n_dyn, n_x) those rows per step (internal order)
    mask: np.ndarray           # (n_steps,) measurement at the step end
    gains: np.ndarray          # (n_meas, n_x, 3) Kalman gains (internal order)
    s_inv: np.ndarray          # (n_meas, 3, 3) inverse innovation covariances
    P: np.ndarray              # (n_x, n_x) covariance after the last step (filter order)
    per_step: int
    key: tuple                 # what the gains depend on besides the linearisation point
    nz: tuple                  # _nonzero_columns(f_dyn), kept for the reruns
    model: SensorModel | None = None
    phi_fed: np.ndarray | None = None


def _filter_setup(rate_hz, settings):
    dt = 1.0 / rate_hz
    per_step = int(round(settings.kf_step_s * rate_hz))
    if per_step < 1 or abs(per_step * dt - settings.kf_step_s) > 1e-9:
        raise ValueError(f"kf_step_s = {settings.kf_step_s} s is not a whole number of "
                         f"samples at {rate_hz:g} Hz")
    subs = settings.substeps
    while per_step % subs:
        subs -= 1
    return dt, per_step, per_step // subs


def _prior(settings: FilterSettings, slow: dict, wander: bool
           ) -> tuple[np.ndarray, np.ndarray, int]:
    """The filter's state scale (SI per filter unit), prior covariance P0 (filter units) and
    the index where the drift states start (= the state count without them): the 33 states,
    the 18 bias-wander states when ``wander`` (the fast processes stationary from the start,
    the slow ones and the running means at 0), the 9 drift states with
    ``settings.accel_drift``."""
    n_x = N_STATES_WANDER if wander else N_STATES
    scale = np.concatenate([SCALE, SCALE_WANDER]) if wander else SCALE
    sig0 = np.concatenate([settings.prior_sigma(), np.zeros(n_x - N_STATES)])
    if wander:
        sig0[FG] = np.sqrt(slow["gyro"][0]) / DEG_PER_H
        sig0[FA] = np.sqrt(slow["accel"][0]) / UG
    if settings.accel_drift:                # linear drift of b_a, s_a⁺, s_a⁻ over the window
        scale = np.concatenate([scale, SCALE[DRIFT_OF]])
        b, s_ = settings.accel_drift_prior
        sig0 = np.concatenate([sig0, [b] * 3 + [s_] * 6])
    P0 = np.diag(sig0 ** 2)
    P0[PHI, PHI0] = P0[PHI0, PHI] = np.diag(sig0[PHI] ** 2)          # φ(0) = φ₀
    return scale, P0, n_x


def run_filter(nav: NavSolution, dtheta: np.ndarray, dv: np.ndarray, rate_hz: float,
               motions: Sequence[CommandedMotion], g: float, w_ie: np.ndarray,
               settings: FilterSettings, velocity_sigma: float,
               x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """One forward pass of the Kalman filter over the window; returns the final state x (33,
    or 51 with the slow bias noise), covariance P in filter units, and diagnostics (with the
    pass's :class:`Linearisation` under ``"linearisation"``). ``x0`` is the prior mean
    relative to the current linearisation point (filter units; default 0).

    The predict and update are the textbook ones (filterpy's ``KalmanFilter.predict`` and
    ``update``, Joseph form; ``test_structured_filter_equals_filterpy`` checks them against
    filterpy step by step) written for this filter's structure: only the 6 navigation-error
    rows of F (and the 18 bias-wander rows) differ from identity rows, so F P Fᵀ is two
    (6|24)×n×n products instead of two n³ ones, and H = [0 I 0] is a selection, so the update
    is rank-3 algebra. filterpy's generic dense step costs 2.5× as much and keeps no gains;
    the gains are what later passes reuse."""
    dt, per_step, per_sub = _filter_setup(rate_hz, settings)
    phi_xx, phi_xp, q = _transition_pieces(nav, dtheta, dv, per_step, per_sub, dt, g, w_ie,
                                           settings)
    n_steps = phi_xp.shape[0]
    t_end = (np.arange(n_steps) + 1) * per_step * dt
    mask = measurement_mask(motions, t_end, settings.margin_s)
    v_meas = nav.v[(np.arange(n_steps) + 1) * per_step - 1]

    T = per_step * dt
    window_s = n_steps * T
    slow = settings.slow_noise()
    wander = any(np.any(v > 0) for pair in slow.values() for v in pair)
    scale, P0, n_base = _prior(settings, slow, wander)
    n_x = scale.size
    inv = 1.0 / scale
    x_init = np.zeros(n_x)
    if x0 is not None:
        x_init[:N_STATES] = x0
    r2 = (velocity_sigma / 1e-3) ** 2
    F = np.eye(n_x)
    F[0:6, 0:6] = inv[0:6, None] * phi_xx * scale[None, 0:6]
    Q = np.zeros((n_x, n_x))
    if settings.param_random_walk is not None:
        Q[PARAMS, PARAMS] = np.diag(np.asarray(settings.param_random_walk) ** 2 * T)
    if wander:
        # Gauss–Markov f and s per axis (exact discretisation at the KF step; s has τ_s and
        # drive q_s²), running mean η += (T/T_w)(f + s) with the step-start values
        I3 = np.eye(3)
        af = math.exp(-T / settings.flicker_fast_tau_s)
        as_ = math.exp(-T / settings.flicker_slow_tau_s)
        for fs, ss, eta, name, sc in ((FG, SLG, ETA_G, "gyro", DEG_PER_H),
                                      (FA, SLA, ETA_A, "accel", UG)):
            var_f, q_s = slow[name]
            F[fs, fs] = I3 * af
            F[ss, ss] = I3 * as_
            F[eta, fs] = F[eta, ss] = I3 * (T / window_s)
            Q[fs, fs] = np.diag(var_f * (1 - af * af) / sc ** 2)
            Q[ss, ss] = np.diag(q_s * settings.flicker_slow_tau_s / 2 * (1 - as_ * as_)
                                / sc ** 2)
    # the rows of F that change per step (navigation errors) or are not identity rows (the
    # bias wander) come first in the internal order: F = [[F_d], [0 I]] there
    dyn = np.arange(6) if not wander else np.r_[0:6, N_STATES:N_STATES_WANDER]
    order = np.r_[dyn, np.setdiff1d(np.arange(n_x), dyn)]
    nd = dyn.size
    pos = np.argsort(order)                 # filter index → internal index
    f_dyn = np.empty((n_steps, nd, n_x))
    f_dyn[:] = F[np.ix_(dyn, order)]
    f_dyn[:, 0:6, pos[PARAMS]] = phi_xp * (inv[0:6, None] * scale[None, PARAMS])
    if wander:                              # the wander enters like the bias it adds to
        for w_cols, b_cols in ((FG, BG), (SLG, BG), (FA, BA), (SLA, BA)):
            f_dyn[:, 0:6, pos[w_cols]] = f_dyn[:, 0:6, pos[b_cols]]
    if settings.accel_drift:                # p(t) = p̄ + δ (t/T_w − 1/2), step middles
        tau = (np.arange(n_steps) + 0.5) * T / window_s - 0.5
        f_dyn[:, 0:6, pos[n_base:]] = (f_dyn[:, 0:6, pos[DRIFT_OF]]
                                       * tau[:, None, None])
    qs = q * (inv[0:6, None] * inv[None, 0:6])
    Q = Q[np.ix_(order, order)]
    full_q = settings.param_random_walk is not None
    q_dd = Q[:nd, :nd].copy()
    P = P0[np.ix_(order, order)]
    x = x_init[order]
    n_meas = int(mask.sum())
    gains = np.empty((n_meas, n_x, 3))
    s_inv = np.empty((n_meas, 3, 3))
    z_all = np.ascontiguousarray(v_meas / 1e-3)
    nis = np.empty(n_meas)
    nz_idx, nz_cnt = _nonzero_columns(f_dyn)
    P = np.ascontiguousarray(P)
    filter_loop(f_dyn, nz_idx, nz_cnt, np.ascontiguousarray(qs), q_dd, np.ascontiguousarray(Q),
                full_q, mask, z_all, float(r2), P, x, gains, s_inv, nis)
    x_out = x[pos]
    P_out = P[np.ix_(pos, pos)]
    z = v_meas[mask]
    lin = Linearisation(order=order, n_dyn=nd, f_dyn=f_dyn, mask=mask, gains=gains,
                        s_inv=s_inv, P=P_out, per_step=per_step, key=(), nz=(nz_idx, nz_cnt))
    diag = dict(n_measurements=n_meas, nis=float(np.mean(nis)) if n_meas else float("nan"),
                residual_rms=float(np.sqrt(np.mean(z ** 2))) if z.size else float("nan"),
                n_steps=n_steps, linearisation=lin)
    return x_out, P_out, diag


def _nonzero_columns(f_dyn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The non-zero columns (over all steps) of each moving row of F, as a padded index array
    and counts: the compiled loops skip the rest."""
    nz = np.any(f_dyn != 0.0, axis=0)
    nz_cnt = nz.sum(axis=1).astype(np.intp)
    nz_idx = np.zeros((nz.shape[0], max(int(nz_cnt.max()), 1)), dtype=np.intp)
    for r in range(nz.shape[0]):
        nz_idx[r, :nz_cnt[r]] = np.flatnonzero(nz[r])
    return nz_idx, nz_cnt


def rerun_filter(lin: Linearisation, nav: NavSolution, x0: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, dict]:
    """The filter pass of :func:`run_filter` with the gains of ``lin`` (a pass near the same
    linearisation point): x_k = F_k x_{k−1} + K_k (z_k − H F_k x_{k−1}). Returns x, the
    covariance of ``lin`` and the diagnostics (NIS with ``lin``'s innovation covariances)."""
    n_x = lin.order.size
    n_steps = lin.f_dyn.shape[0]
    x_init = np.zeros(n_x)
    if x0 is not None:
        x_init[:N_STATES] = x0
    x = x_init[lin.order]
    z_all = np.ascontiguousarray(nav.v[(np.arange(n_steps) + 1) * lin.per_step - 1] / 1e-3)
    mask = lin.mask
    ys = np.empty((lin.gains.shape[0], 3))
    nz_idx, nz_cnt = lin.nz
    j = rerun_loop(lin.f_dyn, nz_idx, nz_cnt, lin.gains, mask, z_all, x, ys)
    z = z_all[mask] * 1e-3
    nis = np.einsum("ki,kij,kj->k", ys, lin.s_inv, ys)
    diag = dict(n_measurements=int(j), nis=float(np.mean(nis)) if j else float("nan"),
                residual_rms=float(np.sqrt(np.mean(z ** 2))) if z.size else float("nan"),
                n_steps=n_steps, linearisation=lin)
    return x[np.argsort(lin.order)], lin.P, diag


def linearisation_distance(a: SensorModel, b: SensorModel, phi_a: np.ndarray,
                           phi_b: np.ndarray, window_s: float, g: float) -> float:
    """How far apart two linearisation points are, as the relative change they make to the
    filter's Jacobian: scale-factor ratios, misalignments and fed-back attitude [rad], the
    attitude a gyro-bias difference integrates to over the window [rad] and an accelerometer
    bias difference relative to g. The Jacobian (attitude along the window, sub-step
    increments) moves by about this fraction, and so does a pass's correction computed with
    the other point's gains."""
    d = [np.abs(a.k_g / b.k_g - 1), np.abs(a.k_a_pos / b.k_a_pos - 1),
         np.abs(a.k_a_neg / b.k_a_neg - 1), np.abs(a.e_g - b.e_g), np.abs(a.e_a - b.e_a),
         np.abs(a.d_g - b.d_g) * window_s, np.abs(a.d_a - b.d_a) / g,
         np.abs(np.asarray(phi_a) - np.asarray(phi_b)) * ARCSEC]
    return float(max(np.max(v) for v in d))


def _linearisation_key(motions, rate_hz, n, settings, sigma_v, g, nominal) -> tuple:
    """Everything the gains depend on besides the linearisation point."""
    return (tuple(motions), float(rate_hz), int(n), repr(settings), float(sigma_v), float(g),
            repr(nominal))


def calibrate_window(gyro_pulses: np.ndarray, accel_pulses: np.ndarray, rate_hz: float,
                     motions: Sequence[CommandedMotion], nominal: SensorModel,
                     latitude_deg: float, height_m: float = 0.0,
                     settings: FilterSettings | None = None,
                     start: SensorModel | None = None) -> WindowResult:
    """Calibrate the pulse model from one window of pulses (n, 3) at ``rate_hz`` with the
    commanded ``motions`` (times relative to the first sample's start).

    Starts from ``start`` (default ``nominal``), navigates, filters, feeds back, and repeats
    until the parameter corrections stop changing (``settings.tol_*``) or
    ``settings.max_iterations``.
    """
    # the work is tall-and-thin vectors and 33×33 matrices: BLAS threads only add overhead
    # (and oversubscribe the campaign's worker processes)
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1, user_api="blas"):
        return _calibrate_window(gyro_pulses, accel_pulses, rate_hz, motions, nominal,
                                 latitude_deg, height_m, settings or FilterSettings(), start)


def _calibrate_window(gyro_pulses, accel_pulses, rate_hz, motions, nominal, latitude_deg,
                      height_m, settings, start) -> WindowResult:
    dt = 1.0 / rate_hz
    g = normal_gravity(latitude_deg, height_m)
    w_ie = earth_rate_enu(latitude_deg)
    gp = np.asarray(gyro_pulses, dtype=float)
    ap = np.asarray(accel_pulses, dtype=float)
    n = gp.shape[0]
    breaks = motion_breaks(motions, rate_hz, n)
    sigma_v = settings.velocity_sigma(nominal)
    model = start if start is not None else nominal
    c0 = None
    phi_fed = np.zeros(3)          # attitude fed back so far [arcsec]
    corrections = []
    converged = False
    x = P = diag = None
    it = 0
    key = _linearisation_key(motions, rate_hz, n, settings, sigma_v, g, nominal)
    window_s = n * dt
    lin = None                     # this window's last full pass (gains reused by later passes)
    for it in range(1, settings.max_iterations + 1):
        dtheta, dv = model.compensate(gp, ap, dt)
        if c0 is None:
            c0 = initial_attitude(motions, dv, rate_hz, settings.align_s)
        nav = navigate(dtheta, dv, dt, c0, latitude_deg, height_m, breaks=breaks, gravity=g)
        # the prior stays centred on the nominal model and the levelled attitude (iterated
        # filter: the passes only move the linearisation point, so the fixed point is the
        # posterior mode and convergence is quadratic rather than slowed by the prior)
        x0 = np.zeros(N_STATES)
        x0[PARAMS] = model_difference(nominal, model)
        x0[PHI] = x0[PHI0] = -phi_fed
        if (lin is not None and lin.key == key and settings.reuse_tol > 0
                and linearisation_distance(model, lin.model, phi_fed, lin.phi_fed, window_s, g)
                <= settings.reuse_tol):
            x, P, diag = rerun_filter(lin, nav, x0)
        else:
            x, P, diag = run_filter(nav, dtheta, dv, rate_hz, motions, g, w_ie, settings,
                                    sigma_v, x0)
            lin = dataclasses.replace(diag["linearisation"], key=key, model=model,
                                      phi_fed=phi_fed.copy())
        model = apply_correction(model, x[:N_STATES])
        c0 = rotation_matrix(x[PHI0] * ARCSEC) @ c0
        phi_fed = phi_fed + x[PHI0]
        corr = x[PARAMS]
        corrections.append(corr.copy())
        sig = np.sqrt(np.diag(P))[PARAMS]
        if np.all(np.abs(corr) <= np.maximum(settings.tol_sigma * sig, settings.tol_abs)):
            converged = True
            break
    if x.size - (N_DRIFT if settings.accel_drift else 0) > N_STATES:
        # report the window-mean biases b + η(T_w) and their covariance
        M = np.eye(x.size)
        M[BG, ETA_G] = np.eye(3)
        M[BA, ETA_A] = np.eye(3)
        P = (M @ P @ M.T)[:N_STATES, :N_STATES]
        model = model.with_(d_g=model.d_g + x[ETA_G] * DEG_PER_H,
                            d_a=model.d_a + x[ETA_A] * UG)
    P = P[:N_STATES, :N_STATES]             # the drift states are not reported
    return WindowResult(model=model, sigma=np.sqrt(np.diag(P)), covariance=P, c0=c0,
                        iterations=it, converged=converged, corrections=corrections,
                        residual_rms_m_per_s=diag["residual_rms"],
                        n_measurements=diag["n_measurements"], nis=diag["nis"])
