"""Exact sensor inputs of an IMU on a moving vehicle over the WGS-84 ellipsoid.

Why this file is over 400 lines: one object holds the route's three views that must agree to
the last bit — the increments, the truth states and the standing-still runs — with the NumPy
forms of the formulas the compiled kernel is tested against.

The motion is a sequence of legs (:mod:`rlgsim.sim.motion.legs`: heading, pitch, roll and the
body-frame ground velocity as polynomials of time) from an initial geodetic position. Navigation
frame ENU at the vehicle (the project's convention), body frame right–forward–up.

**States.** Attitude C_b^n and ground velocity v^n = C_b^n v^b are closed forms of the legs;
their rates are

    ω_nb^b = R_y(φ)ᵀ [R_x(θ)ᵀ (0, 0, −ψ̇) + (θ̇, 0, 0)] + (0, φ̇, 0)
    v̇^n   = C_b^n (v̇^b + ω_nb^b × v^b).

The geodetic position (L, λ, h) follows from the velocity (Titterton & Weston 2004 eq. 3.85–3.87,
ENU):

    L̇ = v_N/(R_M + h),   λ̇ = v_E/((R_N + h) cos L),   ḣ = v_U

integrated leg by leg with DOP853 (8th order, rtol 1e-13, atol 1e-15 rad / 1e-9 m, dense
output of order 7): a few nanometres over hours, the only numerical integration here. It is
scipy's method compiled with its right-hand side (sim/motion/_trajectory_route.py: the route's
~1000 steps in ~3 ms instead of ~0.1 s of Python; scipy's ``solve_ivp`` where a leg nears a
pole); its right-hand side the formulas of :meth:`Trajectory._velocity`.

**Sensor inputs** (Groves 2013 eqs. 5.44, 5.54; Titterton & Weston 2004 eq. 3.71, written for ENU):

    ω_ib^b = ω_nb^b + C_n^b (ω_ie^n + ω_en^n)
    f^b    = C_n^b [v̇^n + (2 ω_ie^n + ω_en^n) × v^n − g^n],   g^n = (0, 0, −γ(L, h))

with the Earth rate, the transport rate ω_en^n and WGS-84 normal gravity of
:mod:`rlgsim.ground.earth` — Earth rate, transport rate and Coriolis all in.

**Increments.** Δθ_k = ∫ω_ib^b dt and Δv_k = ∫f^b dt over each sample interval
[k/f, (k+1)/f), split at the leg boundaries (where rates may jump), by composite Gauss–Legendre
quadrature on sub-intervals of at most :data:`MAX_SUBINTERVAL_S`: 4 nodes (exact for
polynomials of degree 7) where the attitude turns, whose error on a sub-interval of length h is
h⁹ (4!)⁴/(9 (8!)³) |F⁽⁸⁾| ≈ 5.6e-10 h⁹ |F⁽⁸⁾| (Abramowitz & Stegun 25.4.30); inside a leg the
integrands are smooth with time scales set by the angular rates w, |F⁽⁸⁾| ≲ |F| w⁸, so at
h = 0.02 s and w = 3 rad/s the relative error is ~2e-20 — far below float64's resolution (1.1e-16)
of the increments. Legs of constant attitude take 3 or 2 nodes (their integrands are
polynomials of the velocity and slow functions of the position), and where they also hold a
velocity that moves the vehicle, the exact means of fitted 10-s chunks (the bounds are in
:mod:`rlgsim.sim.motion._trajectory_block`). Turning and accelerating legs mostly take the
exact mean series of a degree-11 Chebyshev interpolant on chunks of at most 1 s (its bound in
:mod:`rlgsim.sim.motion._trajectory_cheb`); the quadrature above is what those are checked
against. The increments are thus the exact integrals to rounding, as on the turntable.

**Truth.** Position, ground velocity and attitude at each sample's end (:meth:`Trajectory.states`).

A block's increments and truth states are computed by compiled loops over its samples
(:mod:`rlgsim.sim.motion._trajectory_block`); the NumPy forms here (:meth:`Trajectory.rates`,
:meth:`Trajectory.states`) are what the tests compare them with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.integrate import solve_ivp

from rlgsim.ground.earth import (WGS84_A, WGS84_E2, WGS84_F, WGS84_GAMMA_E, WGS84_K,
                                 WGS84_M, earth_rate_enu_rad, normal_gravity_rad,
                                 transport_rate_enu_rad)
from rlgsim.ground.frames import cross_rows, quat_from_rotvec, quat_mul
from rlgsim.ground.units import EARTH_RATE
from rlgsim.sim.motion.kinematics import MotionBlock, _edges
from rlgsim.sim.motion.legs import Leg, rate_leg

#: longest quadrature sub-interval [s] (see the module docstring for the error bound)
MAX_SUBINTERVAL_S = 0.02
#: nodes and weights of the quadrature levels (sim/motion/_trajectory_block.py): 4 points with
#: the Hermite position, 3 and 2 on the legs of constant attitude (padded with zeros)
_QUADS = np.zeros((3, 2, 4))
for _lv, _pts in enumerate((4, 3, 2)):
    _QUADS[_lv, :, :_pts] = np.polynomial.legendre.leggauss(_pts)
#: the fitted chunks of a leg holding its attitude and velocity while moving
#: (sim/motion/_trajectory_block.py): six Chebyshev points on [-1, 1] (row 0) and the inverse of
#: their Vandermonde matrix (rows 1-6: the monomial coefficients from the values)
_FIT = np.vstack([np.polynomial.chebyshev.chebpts1(6)[None, :],
                  np.linalg.inv(np.vander(np.polynomial.chebyshev.chebpts1(6), 6,
                                          increasing=True))])
#: longest fitted chunk [s] and the most of the integrands' time scale one may span (bound in
#: sim/motion/_trajectory_block.py)
_CHUNK_MAX_S = 10.0
_CHUNK_OF_SCALE = 1e-3
#: tolerances of the position integration (rad, rad, m)
_RTOL = 1e-13
_ATOL = (1e-15, 1e-15, 1e-9)
_ATOL_ARRAY = np.array(_ATOL)
_TIME_TOL_S = 1e-6
#: grid points of a leg evaluated at once by :meth:`Trajectory.peak_inputs` (~2 MB of arrays)
_PEAK_SLICE = 4096
#: highest |latitude| a route may reach (the ENU frame is singular at the poles) [rad]
MAX_LATITUDE_RAD = np.radians(89.9)
#: the WGS-84 constants the compiled kernel needs, in its order (a, e², Ω, γ_e, k, f, m)
_EARTH = np.array([WGS84_A, WGS84_E2, EARTH_RATE, WGS84_GAMMA_E, WGS84_K, WGS84_F, WGS84_M])


def _kernel():
    """The compiled block kernels (imported on first use: numba loads in ~0.5 s)."""
    from rlgsim.sim.motion import _trajectory_block
    return _trajectory_block


def _cheb():
    """The Chebyshev chunks of the turning and accelerating legs (their compiled kernels)."""
    from rlgsim.sim.motion import _trajectory_cheb
    return _trajectory_cheb


@dataclass(frozen=True)
class InitialState:
    """Where a trajectory starts: geodetic latitude and longitude [rad], height above the
    ellipsoid [m]; the legs' channels at τ = 0 (heading, pitch, roll [rad], body velocity
    [m/s]) are the first leg's constant terms."""

    lat_rad: float
    lon_rad: float
    height_m: float


@dataclass
class KinematicState:
    """Vehicle states at times ``t_s`` (k,): ``lat``, ``lon`` [rad], ``height`` [m],
    ``c_bn`` (k, 3, 3), ``w_nb_b`` (k, 3) [rad/s], ``v_n`` (k, 3) [m/s], ``vdot_n`` (k, 3)
    [m/s²], ``euler`` (3, k) heading, pitch, roll [rad], ``gnss`` (k,) bool."""

    lat: np.ndarray
    lon: np.ndarray
    height: np.ndarray
    c_bn: np.ndarray
    w_nb_b: np.ndarray
    v_n: np.ndarray
    vdot_n: np.ndarray
    euler: np.ndarray


def _rot_z_neg(psi: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(psi), np.sin(psi), np.zeros_like(psi), np.ones_like(psi)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1),
                     np.stack([z, z, o], -1)], -2)


def _rot_x(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1),
                     np.stack([z, s, c], -1)], -2)


def _rot_y(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                     np.stack([-s, z, c], -1)], -2)


def attitude_from_euler(heading: np.ndarray, pitch: np.ndarray, roll: np.ndarray
                        ) -> np.ndarray:
    """C_b^n = R_z(−ψ) R_x(θ) R_y(φ) (…, 3, 3) for heading, pitch, roll [rad] (body x right,
    y forward, z up; ENU)."""
    return _rot_z_neg(heading) @ _rot_x(pitch) @ _rot_y(roll)


def attitude_rates(x: np.ndarray, xd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """C_b^n (k, 3, 3) and ω_nb^b (k, 3) [rad/s] from legs' channels ``x`` (6, k) and their
    rates ``xd`` (6, k) (the module docstring's ω_nb^b)."""
    rx, ry = _rot_x(x[1]), _rot_y(x[2])
    c = _rot_z_neg(x[0]) @ rx @ ry
    zero = np.zeros(x.shape[1])
    yaw = np.stack([zero, zero, -xd[0]], -1)
    pitch = np.stack([xd[1], zero, zero], -1)
    w = (np.einsum("kji,kj->ki", ry, np.einsum("kji,kj->ki", rx, yaw) + pitch)
         + np.stack([zero, xd[2], zero], -1))
    return c, w


def quaternion_from_euler(heading: np.ndarray, pitch: np.ndarray, roll: np.ndarray
                          ) -> np.ndarray:
    """The Hamilton quaternion [w, x, y, z] (k, 4) of :func:`attitude_from_euler`."""
    z = np.zeros_like(heading)
    qz = quat_from_rotvec(np.stack([z, z, -heading], -1))
    qx = quat_from_rotvec(np.stack([pitch, z, z], -1))
    qy = quat_from_rotvec(np.stack([z, roll, z], -1))
    return quat_mul(quat_mul(qz, qx), qy)


class Trajectory:
    """Exact kinematics of an IMU carried by a vehicle along ``legs`` from ``initial``.

    After the last leg the vehicle keeps its final attitude and body velocity (a rate leg of
    zero rates) up to ``until_s`` (the run's end). The interface is that of
    :class:`rlgsim.sim.motion.kinematics.Motion` (``increments``, ``angles``, ``end_s``), so
    the IMU stage takes either; :meth:`states` gives the truth states.
    """

    kind = "trajectory"

    def __init__(self, legs: Sequence[Leg], initial: InitialState, until_s: float = 0.0
                 ) -> None:
        legs = list(legs)
        if not legs:
            raise ValueError("a trajectory needs at least one leg")
        t = np.concatenate([[0.0], np.cumsum([leg.duration_s for leg in legs])])
        if until_s > t[-1] + _TIME_TOL_S and legs[-1].frame == "geodetic":
            raise ValueError(f"the run ({until_s:g} s) lasts longer than the position table "
                             f"({t[-1]:g} s); shorten the run or extend the table")
        if until_s > t[-1] + _TIME_TOL_S:
            last = legs[-1]
            legs.append(rate_leg(last.end(), np.zeros(6), until_s - t[-1], label="hold (end)",
                                 gnss=last.gnss))
            t = np.append(t, until_s)
        self.legs = legs
        self.initial = initial
        #: the run's end [s] (0: the legs' end); legs starting after it are never sampled
        self._until = float(until_s) if until_s > 0 else float(t[-1])
        self._t0 = t[:-1]
        self._t1 = t[1:]
        self._end_s = float(t[-1])
        self._coef = np.stack([leg.coef for leg in legs])           # (m, 6, 6)
        self._dcoef = np.ascontiguousarray(self._coef[:, :, 1:]
                                           * np.arange(1, self._coef.shape[2]))
        self._d2coef = np.ascontiguousarray(self._dcoef[:, :, 1:]
                                            * np.arange(1, self._dcoef.shape[2]))
        #: 1 where a leg's channels 3-5 are the geodetic position (a table), 0: body velocity
        self._geodetic = np.array([leg.frame == "geodetic" for leg in legs], dtype=np.int64)
        body = self._geodetic == 0
        moves = self._coef[:, :, 1:] != 0                  # (m, 6, 5): a channel's τ terms
        #: legs in which the vehicle stands still (body frame, no rates, no velocity): every
        #: whole sample inside one has the same increments, bit for bit (its channels are
        #: their constant terms exactly and its position the leg's start)
        self._still = (body & ~moves.any(axis=(1, 2))
                       & ~(self._coef[:, 3:, 0] != 0).any(axis=1)).astype(np.int64)
        #: the quadrature of each leg (sim/motion/_trajectory_block.py): 1 constant attitude,
        #: 2 constant attitude and velocity, 0 any other (and a table of positions)
        att_const = body & ~moves[:, :3].any(axis=(1, 2))
        self._level = np.where(att_const, np.where(moves[:, 3:].any(axis=(1, 2)), 1, 2),
                               0).astype(np.int64)
        self._position, self._dense = self._integrate_positions()
        self._legs_i, self._legs_f = _leg_tables(
            self._position, self._geodetic, self._t0, np.array([leg.duration_s for leg in legs]),
            self._level, self._still)
        self._gnss = np.array([leg.gnss for leg in legs], dtype=np.int8)
        self._chunk = _chunk_lengths(self._coef, self._legs_i, self._legs_f, self._dense)

    # ---- the legs ---------------------------------------------------------------------
    @property
    def end_s(self) -> float:
        """End of the last leg [s]."""
        return self._end_s

    @property
    def leg_starts(self) -> np.ndarray:
        return self._t0.copy()

    def leg_of(self, t_s: np.ndarray, side: str = "right") -> np.ndarray:
        """Index of the leg holding each time (``side="left"``: a boundary time belongs to the
        leg ending there)."""
        j = np.searchsorted(self._t0, np.asarray(t_s, dtype=float), side=side) - 1
        return np.clip(j, 0, len(self.legs) - 1)

    def _channels(self, j: int, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Channel values and rates (6, k) of leg ``j`` at leg times ``tau``."""
        x = self._coef[j][:, -1:] * np.ones(tau.size)
        for k in range(self._coef.shape[2] - 2, -1, -1):
            x = x * tau + self._coef[j][:, k:k + 1]
        xd = self._dcoef[j][:, -1:] * np.ones(tau.size)
        for k in range(self._dcoef.shape[2] - 2, -1, -1):
            xd = xd * tau + self._dcoef[j][:, k:k + 1]
        return x, xd

    def _velocity(self, j: int, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                          np.ndarray, np.ndarray]:
        """C_b^n (k, 3, 3), ω_nb^b (k, 3), v^n, v̇^n (k, 3) and the channels (6, k) of leg ``j``."""
        x, xd = self._channels(j, tau)
        if self._geodetic[j]:
            return self._table_velocity(j, tau, x, xd)
        c, w = self._attitude_rates(x, xd)
        vb, vbd = x[3:].T, xd[3:].T
        v_n = np.einsum("kij,kj->ki", c, vb)
        vdot_n = np.einsum("kij,kj->ki", c, vbd + cross_rows(w, vb))
        return c, w, v_n, vdot_n, x

    def _attitude_rates(self, x: np.ndarray, xd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """C_b^n (k, 3, 3) and ω_nb^b (k, 3) from the Euler channels and their rates."""
        return attitude_rates(x, xd)

    def _table_velocity(self, j: int, tau: np.ndarray, x: np.ndarray, xd: np.ndarray):
        """:meth:`_velocity` of a leg whose channels 3-5 are the geodetic position (L, λ, h):
        v^n from its rates and v̇^n by differentiating (Titterton & Weston eqs. 3.85-3.87
        solved for the velocity; R_M, R_N differentiated along L)."""
        c, w = self._attitude_rates(x, xd)
        xdd = self._d2coef[j][:, -1:] * np.ones(tau.size)
        for k in range(self._d2coef.shape[2] - 2, -1, -1):
            xdd = xdd * tau + self._d2coef[j][:, k:k + 1]
        lat, h = x[3], x[5]
        ld, od, hd = xd[3], xd[4], xd[5]
        ldd, odd, hdd = xdd[3], xdd[4], xdd[5]
        sl, cl = np.sin(lat), np.cos(lat)
        wgt = 1.0 - WGS84_E2 * sl * sl
        rn = WGS84_A / np.sqrt(wgt)
        rm = rn * (1.0 - WGS84_E2) / wgt
        drn = rn * WGS84_E2 * sl * cl / wgt                    # dR_N/dL
        drm = 3.0 * rm * WGS84_E2 * sl * cl / wgt              # dR_M/dL
        v_n = np.stack([(rn + h) * cl * od, (rm + h) * ld, hd], -1)
        vdot_n = np.stack([(drn * ld + hd) * cl * od - (rn + h) * sl * ld * od
                           + (rn + h) * cl * odd,
                           (drm * ld + hd) * ld + (rm + h) * ldd, hdd], -1)
        return c, w, v_n, vdot_n, x

    # ---- position ---------------------------------------------------------------------
    def _integrate_positions(self) -> tuple[list, np.ndarray]:
        """Leg by leg: the dense solution of (L, λ, h) on leg time, from the previous leg's
        end (DOP853, compiled: sim/motion/_trajectory_route.py; see the module docstring) →
        (per leg its start and (first row, rows) of the dense table or None, the table (S, 26)
        of the DOP853 steps' interpolants)."""
        from rlgsim.sim.motion import _trajectory_route as R
        y = np.array([self.initial.lat_rad, self.initial.lon_rad, self.initial.height_m])
        out: list = []
        rows = np.empty((max(64, 8 * len(self.legs)), R.ROW))
        n_rows = 0
        for j, leg in enumerate(self.legs):
            if leg.duration_s <= 0.0:
                out.append((y.copy(), None))
                continue
            if leg.frame == "geodetic":                     # the position is the table's
                out.append((None, None))
                y = leg.end()[3:].copy()
                continue
            if self._still[j] or self._t0[j] > self._until:
                # standing: DOP853's steps of a zero rate hold y exactly; after the run's end:
                # never sampled (its position left at its start)
                out.append((y.copy(), None))
                continue
            status, rows, n_new, y_end = R.dop853_leg(
                self._coef, self._dcoef, j, float(leg.duration_s), y, _RTOL, _ATOL_ARRAY,
                _EARTH, MAX_LATITUDE_RAD, R.TAB_A, R.TAB_B, R.TAB_C, R.TAB_E3, R.TAB_E5,
                R.TAB_D, R.CONTROL, rows, n_rows,
                min(float(leg.duration_s), self._until - self._t0[j]))
            if status != 0:                             # the pole, or a step too small
                y_end, leg_rows = self._solve_ivp_leg(j, y)
                n_new = n_rows + len(leg_rows)
                if n_new > rows.shape[0]:
                    rows = np.concatenate([rows[:n_rows], np.empty((n_new, R.ROW))])
                rows[n_rows:n_new] = leg_rows
            out.append((y.copy(), (n_rows, n_new - n_rows)))
            n_rows = n_new
            y = np.array(y_end, dtype=float)
        return out, np.ascontiguousarray(rows[:n_rows])

    def _solve_ivp_leg(self, j: int, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Leg ``j``'s position by scipy's ``solve_ivp`` (DOP853, its polar event): where the
        compiled stepper hands it over — the end state and the dense rows, or the one-line
        error of a path across a pole."""
        from rlgsim.sim.motion._trajectory_kernel import position_rate_at

        def rhs(tau: float, p: np.ndarray) -> tuple[float, float, float]:
            return position_rate_at(self._coef, self._dcoef, j, tau, p[0], p[2], WGS84_E2,
                                    WGS84_A)

        def polar(tau: float, p: np.ndarray) -> float:
            return MAX_LATITUDE_RAD - abs(p[0])
        polar.terminal = True
        leg = self.legs[j]
        sol = solve_ivp(rhs, (0.0, leg.duration_s), y, method="DOP853", rtol=_RTOL,
                        atol=_ATOL, dense_output=True, events=polar)
        if sol.status == 1:
            raise ValueError(f"leg {j} ({leg.label}) reaches latitude "
                             f"{np.degrees(sol.y[0, -1]):+.4g}° at t = "
                             f"{self._t0[j] + sol.t[-1]:.6g} s: the path crosses a pole, "
                             f"where the ENU frame is singular (|latitude| < "
                             f"{np.degrees(MAX_LATITUDE_RAD):g}°)")
        if not sol.success:                             # pragma: no cover - smooth inputs
            raise ValueError(f"leg {j}: position integration failed ({sol.message})")
        leg_rows = np.array([np.concatenate([[f.t_old, f.h], np.ravel(f.F), f.y_old])
                             for f in sol.sol.interpolants], dtype=float)
        return sol.y[:, -1].copy(), leg_rows.reshape(-1, 26)

    def _positions(self, j: int, tau: np.ndarray) -> np.ndarray:
        """(L, λ, h) (3, k) of leg ``j`` at leg times ``tau``."""
        y0, steps = self._position[j]
        if self._geodetic[j]:
            return self._channels(j, np.asarray(tau, dtype=float))[0][3:]
        if steps is None or tau.size == 0:
            return np.repeat(y0[:, None], tau.size, axis=1)
        first, count = steps
        return _dense(self._dense[first:first + count],
                      np.clip(tau, 0.0, self.legs[j].duration_s))

    # ---- evaluations ------------------------------------------------------------------
    def _inputs(self, j: int, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ω_ib^b and f^b (k, 3) of leg ``j`` at leg times ``tau``."""
        c, w, v_n, vdot_n, _ = self._velocity(j, tau)
        lat, _, h = self._positions(j, tau)
        w_ie = earth_rate_enu_rad(lat)
        w_en = transport_rate_enu_rad(lat, h, v_n)
        f_n = vdot_n + cross_rows(2.0 * w_ie + w_en, v_n)
        f_n[:, 2] += normal_gravity_rad(lat, h)
        w_ib = w + np.einsum("kji,kj->ki", c, w_ie + w_en)
        f_b = np.einsum("kji,kj->ki", c, f_n)
        return w_ib, f_b

    def rates(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ω_ib^b [rad/s] and f^b [m/s²] (k, 3) at run times ``t_s`` (a leg boundary belongs to
        the leg starting there) — the integrands of :meth:`increments`."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        w, f = np.empty((t.size, 3)), np.empty((t.size, 3))
        j = self.leg_of(t)
        for leg in np.unique(j):
            sel = j == leg
            w[sel], f[sel] = self._inputs(int(leg), t[sel] - self._t0[leg])
        return w, f

    def states(self, t_s: np.ndarray) -> KinematicState:
        """Position, velocity and attitude at run times ``t_s`` (k,) (a boundary time belongs to
        the leg ending there; the states are continuous across it)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        k = t.size
        out = KinematicState(np.empty(k), np.empty(k), np.empty(k), np.empty((k, 3, 3)),
                             np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)),
                             np.empty((3, k)))
        j = self.leg_of(t, side="left")
        for leg in np.unique(j):
            sel = np.flatnonzero(j == leg)
            tau = t[sel] - self._t0[leg]
            c, w, v_n, vdot_n, x = self._velocity(int(leg), tau)
            lat, lon, h = self._positions(int(leg), tau)
            out.lat[sel], out.lon[sel], out.height[sel] = lat, lon, h
            out.c_bn[sel], out.w_nb_b[sel], out.v_n[sel], out.vdot_n[sel] = c, w, v_n, vdot_n
            out.euler[:, sel] = x[:3]
        return out

    def truth(self, t_s: np.ndarray) -> dict[str, np.ndarray]:
        """The truth at sample end times ``t_s`` (k,) (the dataset's ``trajectory`` rows, in
        SI): ``lat``, ``lon`` [rad], ``height`` [m], ``v_n`` (k, 3) [m/s], ``q_bn`` (k, 4),
        ``euler`` (k, 3) heading, pitch, roll [rad] — :meth:`states`' numbers, the velocity and
        attitude computed by the compiled kernel (the same formulas)."""
        p, v, q, e, _ = self._truth_arrays(t_s, False)
        return {"lat": p[0], "lon": p[1], "height": p[2], "v_n": v, "q_bn": q, "euler": e.T}

    def truth_rows(self, t_s: np.ndarray) -> dict[str, np.ndarray]:
        """The dataset's ``trajectory`` rows at sample end times ``t_s`` — latitude, longitude
        [°], height [m], velocity, attitude q_b^n, heading [°, in [0, 360)], pitch, roll [°],
        gnss_visible (int8) — made by the compiled kernel in one pass: the numbers of
        ``rlgsim.sim.writer.schema.trajectory_rows(self, t_s)``, bit for bit
        (sim/motion/_trajectory_truth.py)."""
        p, v, q, e, g = self._truth_arrays(t_s, True)
        return {"latitude": p[0], "longitude": p[1], "height": p[2], "velocity": v,
                "attitude": q, "heading": e[0], "pitch": e[1], "roll": e[2], "gnss_visible": g}

    def _truth_arrays(self, t_s: np.ndarray, degrees: bool) -> tuple[np.ndarray, ...]:
        """(L, λ, h) (3, k), v^n (k, 3), q_b^n (k, 4), heading/pitch/roll (3, k) and the GNSS
        flags (k,) at ``t_s`` (degrees: the rows' units)."""
        from rlgsim.sim.motion._trajectory_truth import states_at
        t = np.ascontiguousarray(np.atleast_1d(np.asarray(t_s, dtype=float)))
        k = t.size
        p, v, q, e = np.empty((3, k)), np.empty((k, 3)), np.empty((k, 4)), np.empty((3, k))
        g = np.empty(k, dtype=np.int8)
        states_at(t, self._coef, self._dcoef, self._d2coef, self._legs_i, self._legs_f,
                  self._dense, _EARTH, self._gnss, bool(degrees), p, v, q, e, g)
        return p, v, q, e, g

    def gnss_visible(self, t_s: np.ndarray) -> np.ndarray:
        """Whether a GNSS receiver sees the sky at times ``t_s`` (the leg's flag)."""
        flags = np.array([leg.gnss for leg in self.legs])
        return flags[self.leg_of(t_s, side="left")]

    # ---- the Motion interface -----------------------------------------------------------
    def angles(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The turntable's angles: there is none — the IMU is fixed in the vehicle, a static
        mount (0°, 0°, motion 0); the attitude is in :meth:`states`."""
        t = np.asarray(t_s, dtype=float)
        return np.zeros(t.shape), np.zeros(t.shape), np.zeros(t.shape, dtype=np.int64)

    def increments(self, t0_s: float, n: int, rate_hz: float, *, angles: bool = True
                   ) -> MotionBlock:
        """Exact Δθ [rad] and Δv [m/s] (n, 3) of ``n`` samples at ``rate_hz`` from ``t0_s`` (on
        the sample grid): composite Gauss–Legendre over each sample interval split at the leg
        boundaries (module docstring)."""
        if n < 0 or rate_hz <= 0:
            raise ValueError(f"need n >= 0 and rate_hz > 0, got n={n}, rate_hz={rate_hz}")
        k0 = round(t0_s * rate_hz)
        if abs(k0 - t0_s * rate_hz) > 1e-6:
            raise ValueError(f"t0_s = {t0_s!r} s is not on the {rate_hz:g} Hz sample grid")
        # stored axis by axis, (3, n), and handed out as (n, 3) views, as the turntable's:
        # the IMU stage takes each axis's run of samples (its step sums, the pulses) as it is
        # (C-contiguous (3, n) to the kernel: one compiled specialisation whatever n)
        dth_t, dv_t = np.empty((3, n)), np.empty((3, n))
        dth, dv = dth_t.T, dv_t.T
        runs = np.empty((n, 2), dtype=np.int64)
        sub = max(1, int(np.ceil((1.0 / rate_hz) / MAX_SUBINTERVAL_S - 1e-9)))
        r = _kernel().block_increments(k0, n, float(rate_hz), sub, self._coef, self._dcoef,
                                       self._d2coef, self._legs_i, self._legs_f, self._dense,
                                       _QUADS, _EARTH, self._chunk, _FIT, _cheb().DCT, dth_t,
                                       dv_t, runs)
        constant = tuple((int(lo), int(hi)) for lo, hi in runs[:r])
        block = MotionBlock(dth, dv, None, None, None, k0, rate_hz, constant)
        if angles:
            block.outer_deg, block.inner_deg, block.segment = self.angles(block.t_s)
        return block

    # ---- checks -------------------------------------------------------------------------
    def peak_inputs(self, step_s: float = 0.5, below: tuple[float, float] | None = None
                    ) -> tuple[float, float, float]:
        """Largest |ω_ib^b| component [rad/s] and |f^b| component [m/s²] over the run, on a
        grid of ``step_s`` plus the leg ends, and the time of the largest rate — by the
        compiled kernel (sim/motion/_trajectory_kernel.py: the grid of :meth:`peak_inputs_numpy`,
        the integrands' compiled formulas; ~3 ms for 4 h of route instead of ~50 ms).

        ``below`` = (rate, force): the legs that provably stay under both on the whole leg
        (:meth:`_calm_legs`) are left out. Then a peak that exceeds ``rate`` (or ``force``) is
        the full grid's, with its time, for every leg left out is below it; one under it
        only says the run stays under (what the range check asks: the 4-h land route's holds,
        ~3/4 of its grid, cost nothing)."""
        from rlgsim.sim.motion import _trajectory_kernel as K
        out = np.empty(3)
        skip = (self._calm_legs(*below) if below is not None
                else np.zeros(len(self.legs), dtype=np.int64))
        legs_f = self._legs_f
        if self._until < self._end_s:       # the sensors never see the legs after the run
            skip = skip | (self._t0 >= self._until)
            legs_f = legs_f.copy()
            legs_f[:, K.LF_DUR] = np.minimum(legs_f[:, K.LF_DUR],
                                             np.maximum(self._until - self._t0, 0.0))
        K.peak_inputs(self._coef, self._dcoef, self._d2coef, self._legs_i, legs_f,
                      self._dense, _EARTH, float(step_s), skip, out)
        return float(out[0]), float(out[1]), float(out[2])

    def _calm_legs(self, rate: float, force: float) -> np.ndarray:
        """1 for each leg of constant attitude and body velocity (body frame) whose |ω_ib^b|
        and |f^b| components stay under ``rate`` [rad/s] and ``force`` [m/s²] on the whole leg,
        by bounds: there ω_nb^b = 0 and v̇^n = 0, so (ENU; Titterton & Weston 2004 eqs. 3.71,
        3.85–3.87) |ω_ib^b| = |ω_ie^n + ω_en^n| ≤ Ω + |ω_en^n| and |f^b| ≤ (2Ω + |ω_en^n|)|v|
        + γ, with |ω_en^n| ≤ |v|/((R + h) cos L) (R ≥ a(1 − e²) the smaller radius), L the
        largest |latitude| and h the lowest height of the leg (its DOP853 steps' starts, widened
        by |v| times the longest step), γ ≤ normal gravity at the pole at that height (it grows
        with |L| and as h falls); each bound widened by 1e-9 of itself for rounding."""
        from rlgsim.sim.motion import _trajectory_kernel as K
        out = np.zeros(len(self.legs), dtype=np.int64)
        r_min = WGS84_A * (1.0 - WGS84_E2)
        for j, (kind, first, steps, level, _, geo) in enumerate(self._legs_i):
            if level != 2 or geo:
                continue
            speed = float(np.linalg.norm(self._coef[j, 3:, 0]))
            if kind == K.POS_FIXED:
                lat, low = abs(self._legs_f[j, K.LF_Y0]), self._legs_f[j, K.LF_Y0 + 2]
                reach = 0.0
            elif kind == K.POS_DENSE and steps > 0:
                lat, low, reach = _dense_extent(self._dense[first:first + steps], speed)
            else:
                continue
            low -= reach
            radius = r_min + min(low, 0.0)
            if radius <= 0.0:
                continue
            lat += reach / radius
            if lat >= 0.5 * np.pi - 1e-6:
                continue
            w_en = speed / (radius * np.cos(lat))
            gamma = float(normal_gravity_rad(0.5 * np.pi, min(low, 0.0)))
            w_bound = (EARTH_RATE + w_en) * (1.0 + 1e-9)
            f_bound = ((2.0 * EARTH_RATE + w_en) * speed + gamma) * (1.0 + 1e-9)
            out[j] = int(w_bound < rate and f_bound < force)
        return out

    def height_extent(self) -> tuple[float, float, float, float]:
        """Lowest and highest height [m] of the route up to the run's end, at its legs' starts,
        its DOP853 steps' starts and ends (y_old + F_0; a table's: its rows) and the run's end
        (the truth there), with the times [s] they are at."""
        from rlgsim.sim.motion._trajectory_route import ROW
        h, t = [], []
        for j, (y0, steps) in enumerate(self._position):
            if self._t0[j] > self._until:
                break
            y0 = self._coef[j, 3:, 0] if y0 is None else y0     # a table: its start row
            rows = self._dense[steps[0]:steps[0] + steps[1]] if steps else self._dense[:0]
            h += [[y0[2]], rows[:, ROW - 1], rows[:, ROW - 1] + rows[:, 4]]
            t += [[self._t0[j]], self._t0[j] + rows[:, 0], self._t0[j] + (rows[:, 0] + rows[:, 1])]
        hs = np.concatenate(h + [self.truth(np.array([self._until]))["height"]])
        ts = np.concatenate(t + [[self._until]])
        hs[ts > self._until] = np.nan
        lo, hi = int(np.nanargmin(hs)), int(np.nanargmax(hs))
        return float(hs[lo]), float(ts[lo]), float(hs[hi]), float(ts[hi])

    def peak_inputs_numpy(self, step_s: float = 0.5) -> tuple[float, float, float]:
        """:meth:`peak_inputs` by the NumPy formulas (:meth:`_inputs`; what the tests compare
        the kernel with), up to the run's end as it. A leg's grid is ``np.linspace(0, duration,
        m)`` (the duration cut at the run's end), evaluated :data:`_PEAK_SLICE` points at a time
        (``k · duration / (m − 1)``, its last point the duration: linspace's own numbers): the
        memory does not grow with a leg's length (a closing hold lasts as long as the run)."""
        best_w, best_f, at, cut = 0.0, 0.0, 0.0, self._until < self._end_s
        n = int(np.searchsorted(self._t0, self._until)) if cut else len(self.legs)  # t0 < end
        for j, leg in enumerate(self.legs[:n]):
            dur = min(leg.duration_s, self._until - self._t0[j]) if cut else leg.duration_s
            m = max(3, int(np.ceil(dur / step_s)) + 1)
            m += 1 - m % 2                              # odd: the leg's middle on the grid
            step = dur / (m - 1)
            for lo in range(0, m, _PEAK_SLICE):
                tau = np.arange(lo, min(m, lo + _PEAK_SLICE), dtype=float) * step
                if lo + tau.size == m:
                    tau[-1] = dur
                w, f = self._inputs(j, tau)
                iw = int(np.argmax(np.max(np.abs(w), axis=1)))
                if np.max(np.abs(w[iw])) > best_w:
                    best_w, at = float(np.max(np.abs(w[iw]))), float(self._t0[j] + tau[iw])
                best_f = max(best_f, float(np.max(np.abs(f))))
        return best_w, best_f, at


def _dense(rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """(L, λ, h) (3, k) of a leg's DOP853 dense rows (``dense`` of :func:`_leg_tables`) at leg
    times ``tau``: the step the first whose end is ≥ τ (scipy's ``OdeSolution``), its
    interpolant y_old + ((…(F_6 x + F_5)(1 − x) + F_4) x + …) x, x = (τ − t_old)/h (scipy's
    ``Dop853DenseOutput``, the compiled ``_trajectory_kernel._dense_at``) — NumPy, for the
    tests and the truth states."""
    tau = np.asarray(tau, dtype=float).reshape(-1)
    seg = np.clip(np.searchsorted(rows[:, 0], tau, side="left") - 1, 0, len(rows) - 1)
    r = rows[seg]
    x = ((tau - r[:, 0]) / r[:, 1])[:, None]
    y = np.zeros((tau.size, 3))
    for i in range(7):
        c = 2 + 3 * (6 - i)
        y += r[:, c:c + 3]
        y *= x if i % 2 == 0 else 1 - x
    y += r[:, 23:26]
    return y.T


def _leg_tables(position: list, geodetic: np.ndarray, t0: np.ndarray, duration: np.ndarray,
                level: np.ndarray, still: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The legs as the compiled kernels take them (:mod:`rlgsim.sim.motion._trajectory_kernel`:
    ``legs_i``, ``legs_f``; the dense table ``dense`` is :meth:`Trajectory._integrate_positions`'s):
    per leg how its position is found (the DOP853 dense output, its own channels, its start),
    its first dense step and their number, its quadrature level, whether it stands still,
    whether it is a table of positions; its start, duration and start position."""
    from rlgsim.sim.motion import _trajectory_kernel as K
    m = len(position)
    legs_i = np.zeros((m, 6), dtype=np.int64)
    legs_f = np.zeros((m, 5))
    for j, (start, steps) in enumerate(position):
        kind = K.POS_GEODETIC if geodetic[j] else K.POS_FIXED if steps is None else K.POS_DENSE
        first, count = steps if steps is not None else (0, 0)
        legs_i[j] = (kind, first, count, level[j], still[j], geodetic[j])
        legs_f[j, :2] = t0[j], duration[j]
        if start is not None:
            legs_f[j, 2:] = start
    return legs_i, legs_f


def _dense_extent(rows: np.ndarray, speed: float) -> tuple[float, float, float]:
    """A moving leg's extent from its DOP853 dense rows (``ROW`` columns each,
    sim/motion/_trajectory_route.py: column 1 the step's length [s], the last three the
    position (L [rad], λ [rad], h [m]) at its start): the largest |L| [rad] and the lowest h [m]
    at the steps' starts, and the most one step can move the leg at ``speed`` [m/s], in m."""
    from rlgsim.sim.motion._trajectory_route import ROW
    y = ROW - 3
    return (float(np.max(np.abs(rows[:, y]))), float(np.min(rows[:, y + 2])),
            speed * float(np.max(rows[:, 1])))


#: legs whose chunk radii are found at once (each leg's radius is its own: any batch gives
#: the same numbers)
_RADII_BATCH = 4096


def _chunk_lengths(coef: np.ndarray, legs_i: np.ndarray, legs_f: np.ndarray, dense: np.ndarray
                   ) -> np.ndarray:
    """Per leg the length [s] of its fitted chunks (sim/motion/_trajectory_block.py): a leg of
    constant attitude and body velocity that moves (its position the DOP853 dense output) gets
    min(:data:`_CHUNK_MAX_S`, :data:`_CHUNK_OF_SCALE` · τ), τ = (a(1 − e²) + min(h, 0)) cos L_max
    / |v| the time the integrands' nearest singularity in L or h is away at its speed — tan L
    at the pole, 1/(R + h) at the Earth's centre (L_max the largest |L| at its steps' starts and
    end, plus the most one step can add); a turning or accelerating one (body frame, its
    position the dense output) its Chebyshev chunks' min(CHUNK_MAX_S, RHO_FRACTION · ρ)
    (sim/motion/_trajectory_cheb.py: ρ the radius on which its channels move by little); 0 for
    any other leg."""
    from rlgsim.sim.motion import _trajectory_kernel as K
    cheb = _cheb()
    out = np.zeros(len(legs_i))
    turning = np.flatnonzero((legs_i[:, K.LI_LEVEL] != 2) & (legs_i[:, K.LI_STILL] == 0)
                             & (legs_i[:, K.LI_GEO] == 0) & (legs_i[:, K.LI_POS] == K.POS_DENSE)
                             & (legs_i[:, K.LI_NSEG] > 0))
    for lo in range(0, turning.size, _RADII_BATCH):       # memory: ~25 kB a leg at once
        part = turning[lo:lo + _RADII_BATCH]
        out[part] = np.minimum(cheb.CHUNK_MAX_S, cheb.RHO_FRACTION * cheb.chunk_radii(
            coef[part], legs_f[part, K.LF_DUR]))
    for j, (kind, first, steps, level, still, _) in enumerate(legs_i):
        speed = float(np.linalg.norm(coef[j, 3:, 0]))
        if level != 2 or still or kind != K.POS_DENSE or steps == 0 or speed == 0.0:
            continue
        lat, low, reach = _dense_extent(dense[first:first + steps], speed)
        lat_max = lat + reach / (WGS84_A * (1.0 - WGS84_E2))
        radius = WGS84_A * (1.0 - WGS84_E2) + min(low, 0.0)
        if lat_max >= 0.5 * np.pi or radius <= 0.0:       # pragma: no cover - the range check
            continue
        out[j] = min(_CHUNK_MAX_S, _CHUNK_OF_SCALE * radius * np.cos(lat_max) / speed)
    return out
