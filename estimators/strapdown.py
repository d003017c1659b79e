"""Strapdown navigation of an IMU standing on a turntable at a fixed site, from pulse counts.

Everything here works on recorded data (pulses, sample interval, commanded table angles): it
never imports ``sim``. The site model and the turntable's gimbal convention are therefore
restated here (they are the conventions of the dataset, docs/dataset.md); they are tiny and
a library for them would be a heavier dependency than the ten lines.

Frames: navigation frame ENU at the site (x East, y North, z Up); body frame = the IMU
measurement frame; i0 = the inertial frame that coincides with ENU at the start of the window.

Pulse model (paper 000 eqs. 17 and 20; DESIGN.md), per sample of length Δt:

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
(NIMA TR8350.2 3rd ed. eqs. 4-1, 4-3), the same model :mod:`rlgsim.sim.earth` uses for the simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

#: Earth rotation rate [rad/s] (WGS-84).
EARTH_RATE = 7.292115e-5
DEG = math.pi / 180.0
ARCSEC = DEG / 3600.0

_WGS84_A, _WGS84_F = 6378137.0, 1.0 / 298.257223563
_WGS84_GAMMA_E, _WGS84_K = 9.7803253359, 0.00193185265241
_WGS84_E2, _WGS84_M = 0.00669437999013, 0.00344978650684


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity γ [m/s²] at geodetic latitude [°] and ellipsoidal height [m]
    (Somigliana + second-order free-air term, NIMA TR8350.2 eqs. 4-1, 4-3)."""
    s2 = math.sin(latitude_deg * DEG) ** 2
    g0 = _WGS84_GAMMA_E * (1 + _WGS84_K * s2) / math.sqrt(1 - _WGS84_E2 * s2)
    return g0 * (1 - 2 / _WGS84_A * (1 + _WGS84_F + _WGS84_M - 2 * _WGS84_F * s2) * height_m
                 + 3 * height_m ** 2 / _WGS84_A ** 2)


def earth_rate_enu(latitude_deg: float) -> np.ndarray:
    """ω_ie^n = (0, Ω cos L, Ω sin L) [rad/s]."""
    lat = latitude_deg * DEG
    return np.array([0.0, EARTH_RATE * math.cos(lat), EARTH_RATE * math.sin(lat)])


def table_attitude(outer_deg, inner_deg) -> np.ndarray:
    """Body-to-ENU attitude C_b^n = R_x(outer) R_z(inner) of the two-axis table (outer axis
    horizontal along East, inner axis = body z, body = ENU at zero angles; docs/dataset.md).
    Broadcasts, (…, 3, 3)."""
    o = np.asarray(outer_deg, dtype=float) * DEG
    i = np.asarray(inner_deg, dtype=float) * DEG
    co, so, ci, si = np.cos(o), np.sin(o), np.cos(i), np.sin(i)
    z = np.zeros_like(co * ci)
    return np.stack([np.stack([ci + z, -si + z, z], -1),
                     np.stack([co * si, co * ci, -so + z], -1),
                     np.stack([so * si, so * ci, co + z], -1)], -2)


# ------------------------------------------------------------------------------ rotations

def skew(v: np.ndarray) -> np.ndarray:
    """[v×] for v (…, 3) → (…, 3, 3)."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: exp([r×]) for rotation vectors r (…, 3) → (…, 3, 3)."""
    r = np.asarray(rotvec, dtype=float)
    a = np.linalg.norm(r, axis=-1)[..., None, None]
    k = skew(r)
    s = np.sinc(a / np.pi)                                  # sin a / a
    c = 0.5 * np.sinc(a / (2 * np.pi)) ** 2                 # (1 − cos a)/a²
    return np.eye(3) + s * k + c * (k @ k)


def quat_from_rotvec(r: np.ndarray) -> np.ndarray:
    """exp(r/2) as quaternions [w, x, y, z] (…, 4); exact for small angles (sinc form)."""
    a = np.linalg.norm(r, axis=-1)
    return np.concatenate([np.cos(0.5 * a)[..., None],
                           (0.5 * np.sinc(a / (2 * np.pi)))[..., None] * r], axis=-1)


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q, broadcasting over leading axes."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of unit quaternions (…, 4) → (…, 3, 3) (v^i = C v^b)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def dcm_to_quat(c: np.ndarray) -> np.ndarray:
    """Unit quaternion of one rotation matrix (Shepperd's method)."""
    c = np.asarray(c, dtype=float)
    tr = np.trace(c)
    k = int(np.argmax([tr, c[0, 0], c[1, 1], c[2, 2]]))
    if k == 0:
        w = 0.5 * math.sqrt(1 + tr)
        q = [w, (c[2, 1] - c[1, 2]) / (4 * w), (c[0, 2] - c[2, 0]) / (4 * w),
             (c[1, 0] - c[0, 1]) / (4 * w)]
    elif k == 1:
        x = 0.5 * math.sqrt(1 + 2 * c[0, 0] - tr)
        q = [(c[2, 1] - c[1, 2]) / (4 * x), x, (c[0, 1] + c[1, 0]) / (4 * x),
             (c[0, 2] + c[2, 0]) / (4 * x)]
    elif k == 2:
        y = 0.5 * math.sqrt(1 + 2 * c[1, 1] - tr)
        q = [(c[0, 2] - c[2, 0]) / (4 * y), (c[0, 1] + c[1, 0]) / (4 * y), y,
             (c[1, 2] + c[2, 1]) / (4 * y)]
    else:
        z = 0.5 * math.sqrt(1 + 2 * c[2, 2] - tr)
        q = [(c[1, 0] - c[0, 1]) / (4 * z), (c[0, 2] + c[2, 0]) / (4 * z),
             (c[1, 2] + c[2, 1]) / (4 * z), z]
    q = np.array(q)
    return q / np.linalg.norm(q)


def quat_cumprod(q: np.ndarray) -> np.ndarray:
    """Prefix products P_k = q_0 ⊗ q_1 ⊗ … ⊗ q_k of quaternions q (n, 4).

    Blocked scan: the sequence is cut into ~√n blocks, the products inside all blocks advance
    together (one vectorised multiply per position in a block), the block totals are prefixed
    recursively, and one vectorised multiply joins them. Same multiplications as the
    sequential loop up to association, so rounding stays at the eps·√n level.
    """
    q = np.asarray(q, dtype=float)
    n = q.shape[0]
    if n <= 64:
        out = np.empty_like(q)
        acc = q[0]
        out[0] = acc
        for k in range(1, n):
            acc = quat_mul(acc, q[k])
            out[k] = acc
        return out
    b = int(math.ceil(math.sqrt(n)))
    nb = -(-n // b)
    pad = np.zeros((nb * b, 4))
    pad[:, 0] = 1.0
    pad[:n] = q
    blocks = pad.reshape(nb, b, 4)
    local = np.empty_like(blocks)
    acc = blocks[:, 0]
    local[:, 0] = acc
    for j in range(1, b):
        acc = quat_mul(acc, blocks[:, j])
        local[:, j] = acc
    totals = quat_cumprod(local[:, -1])                     # inclusive prefix of block totals
    prefix = np.concatenate([[[1.0, 0.0, 0.0, 0.0]], totals[:-1]])
    out = quat_mul(prefix[:, None, :], local).reshape(nb * b, 4)[:n]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


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
        ng = np.asarray(gyro_pulses, dtype=float)
        na = np.asarray(accel_pulses, dtype=float)
        y_g = ng * (1.0 / self.k_g) - self.d_g * dt_s
        # einsum, not y @ Mᵀ: a tall (n, 3) × (3, 3) product through BLAS is 10× slower
        dtheta = np.einsum("nj,ij->ni", y_g, np.linalg.inv(self.e_g))
        inv_k = np.where(na >= 0, 1.0 / self.k_a_pos, 1.0 / self.k_a_neg)
        y_a = na * inv_k - self.d_a * dt_s
        dv = np.einsum("nj,ij->ni", y_a, np.linalg.inv(self.e_a))
        return dtheta, dv

    def pulses(self, dtheta: np.ndarray, dv: np.ndarray, dt_s: float
               ) -> tuple[np.ndarray, np.ndarray]:
        """The forward model without noise or quantisation (real-valued pulses) — for tests and
        for synthesising ideal data; the sign of the accelerometer input picks K_a^±."""
        y_g = self.d_g * dt_s + np.einsum("nj,ij->ni", np.asarray(dtheta, float), self.e_g)
        y_a = self.d_a * dt_s + np.einsum("nj,ij->ni", np.asarray(dv, float), self.e_a)
        return self.k_g * y_g, np.where(y_a >= 0, self.k_a_pos, self.k_a_neg) * y_a


# ------------------------------------------------------------------------------ navigation

def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (faster than np.cross for tall arrays)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """q ⊗ v ⊗ q* for unit quaternions (n, 4) and vectors (n, 3)."""
    u = q[..., 1:]
    t = 2.0 * _cross(u, v)
    return v + q[..., :1] * t + _cross(u, t)


def rotate_about(axis_angle_rate: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (n, 3) by the rotation vector ``axis_angle_rate`` × t (n,) (a fixed
    axis, Rodrigues on vectors)."""
    w = np.asarray(axis_angle_rate, float)
    rate = float(np.linalg.norm(w))
    if rate == 0.0:
        return np.array(v, dtype=float)
    k = w / rate
    a = (rate * np.asarray(t, float))[:, None]
    kv = np.einsum("nj,j->n", v, k)
    return v * np.cos(a) + _cross(np.broadcast_to(k, v.shape), v) * np.sin(a) \
        + np.outer(kv, k) * (1.0 - np.cos(a))


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
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    n = dtheta.shape[0]
    w_ie = earth_rate_enu(latitude_deg)
    g = normal_gravity(latitude_deg, height_m) if gravity is None else float(gravity)
    # two-sample coning (Savage 2007 eq. 7.1.1.1-11 with the linear-rate model), no reach-back
    # across the commanded rate steps
    prev_th = np.empty_like(dtheta)
    prev_th[0] = dtheta[0]
    prev_th[1:] = dtheta[:-1]
    if breaks is not None and len(breaks):
        b = np.asarray(breaks, dtype=np.intp)
        b = b[(b > 0) & (b < n)]
        prev_th[b] = dtheta[b]
    phi = dtheta + _cross(prev_th, dtheta) / 12.0
    q = quat_from_rotvec(phi)
    q[0] = quat_mul(dcm_to_quat(c0), q[0])
    q_bi = quat_cumprod(q)                                   # body → i0 at sample ends
    t = (np.arange(n) + 1.0) * dt_s
    # velocity: rotation correction exact for a constant rate over the sample (the inverse
    # SO(3) Jacobian, ΔV = Δv + ½α×Δv + (1/12)α×(α×Δv)), into i0 with the attitude at the
    # sample start, then into ENU at the sample middle
    a_dv = _cross(dtheta, dv)
    dV = dv + 0.5 * a_dv + _cross(dtheta, a_dv) / 12.0
    q_start = np.empty_like(q_bi)
    q_start[0] = dcm_to_quat(c0)
    q_start[1:] = q_bi[:-1]
    dv_i = quat_rotate(q_start, dV)
    dv_n = rotate_about(-w_ie, t - 0.5 * dt_s, dv_i)
    dv_n[:, 2] -= g * dt_s
    v = np.cumsum(dv_n, axis=0)
    if v0 is not None:
        v += np.asarray(v0, float)
    return NavSolution(t, q_bi, v, np.asarray(c0, float), w_ie)
