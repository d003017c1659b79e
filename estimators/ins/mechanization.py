"""Strapdown inertial navigation on the WGS-84 ellipsoid, from angle and velocity increments.

Works on recorded data (never imports the simulator). Frames (docs/design.md, docs/navigation.md):
navigation frame n = local-level ENU (x East, y North, z Up) at the current position; body frame
b = the IMU's measurement axes; attitude C_b^n (v^n = C_b^n v^b) kept as a Hamilton quaternion
[w, x, y, z]; position geodetic latitude L, longitude λ [rad] and height h [m] above the
ellipsoid. ENU is singular at the poles (the longitude rate has 1/cos L): |L| < 89.9°.

Per sample k of length Δt with increments Δθ_k [rad], Δv_k [m/s] (the integrals of ω_ib^b and
f^b over the sample), the recursion is (Savage, *Strapdown Analytics* 2nd ed. 2007, §7.1–7.3;
Titterton & Weston, *Strapdown Inertial Navigation Technology* 2nd ed. 2004, §11.2–11.3;
Groves 2013 §5.5):

* **Attitude**: body rotation vector with the two-sample coning correction
  φ_k = Δθ_k + (1/12) Δθ_{k−1} × Δθ_k (Savage eq. 7.1.1.1-11, linear-rate model); navigation-
  frame rotation ζ_k = (ω_ie^n + ω_en^n) Δt with the velocity extrapolated to the sample middle;
  q_k = exp(−ζ_k/2) ⊗ q_{k−1} ⊗ exp(φ_k/2), renormalised.
* **Velocity**: ΔV_k = Δv_k + ½ Δθ_k × Δv_k + (1/12)(Δθ_{k−1} × Δv_k + Δv_{k−1} × Δθ_k)
  (rotation + two-sample sculling, Savage eq. 7.2.2.2.2-22 with the linear models);
  Δv_sf^n = (I − ½[ζ_k×]) C_b^n(k−1) ΔV_k;
  v_k = v_{k−1} + Δv_sf^n + (g^n − (2ω_ie^n + ω_en^n) × v_mid) Δt (T&W eq. 3.73) with
  g^n = (0, 0, −γ(L, h)) the WGS-84 normal gravity (:func:`rlgsim.ground.earth.normal_gravity`:
  gravitation + centrifugal, what a static accelerometer senses) and the Earth rate and
  transport rate of :mod:`rlgsim.ground.earth`.
* **Position**: L_k = L_{k−1} + v̄_N Δt/(R_M + h), λ_k = λ_{k−1} + v̄_E Δt/((R_E + h) cos L̄)
  with v̄ the mean of the velocities at both ends of the sample (trapezoid).
* **Vertical channel**: free inertial height is unstable (the gravity gradient feeds height
  errors back with the wrong sign, time constant √(R/2g) ≈ 9.5 min), so as INS practice does the
  navigator *holds the height* at a known value (a fixed site, or a height input per sample):
  h_k = h_ref,k and v_U,k = (h_ref,k − h_{k−1})/Δt. :attr:`InsSolution.vertical` says which;
  ``height=None`` integrates the vertical channel freely (for aided filters).

The sequential loop is compiled with numba (:mod:`rlgsim.estimators.ins._kernel`). Its own
error over 8 h of exact increments is below 1 mm static and a few dm on a turntable
(tests/test_ins.py, docs/navigation.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rlgsim.estimators.ins._kernel import STATE_SIZE, ins_loop
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import dcm_to_quat, quat_to_dcm
from rlgsim.ground.units import DEG

#: highest |latitude| the ENU mechanization accepts [°]
MAX_LATITUDE_DEG = 89.9


@dataclass
class InsState:
    """The navigator's state at the end of a sample (or at the start of a run).

    ``q`` (4,) attitude quaternion body → ENU; ``v`` (3,) ENU velocity [m/s]; ``lat``, ``lon``
    [rad]; ``h`` [m]; plus the previous sample's increments and velocity that the coning,
    sculling and midpoint extrapolation reach back to (``_memory``). Continue a run by passing
    the state returned by :func:`integrate` back in: chunked runs equal one long run exactly.
    """

    q: np.ndarray
    v: np.ndarray
    lat: float
    lon: float
    h: float
    _memory: np.ndarray = field(default_factory=lambda: np.zeros(12), repr=False)

    @classmethod
    def at_rest(cls, c_bn: np.ndarray, latitude_deg: float, longitude_deg: float = 0.0,
                height_m: float = 0.0, v_enu: np.ndarray | None = None) -> "InsState":
        """A start state from an attitude C_b^n (3, 3), a position [°, °, m] and a velocity
        (default 0) [m/s]."""
        c = np.asarray(c_bn, dtype=float)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise UserInputError(f"initial attitude: need a finite 3×3 matrix, got shape {c.shape}")
        for name, val in (("latitude_deg", latitude_deg), ("longitude_deg", longitude_deg),
                          ("height_m", height_m)):
            if not math.isfinite(float(val)):
                raise UserInputError(f"initial position: {name} = {val!r} is not finite")
        if abs(latitude_deg) > MAX_LATITUDE_DEG:
            raise UserInputError(f"initial position: latitude_deg = {latitude_deg!r}; the ENU "
                                 f"navigator needs |latitude| <= {MAX_LATITUDE_DEG}")
        v = np.zeros(3) if v_enu is None else np.asarray(v_enu, dtype=float).reshape(3)
        return cls(dcm_to_quat(c), v.copy(), latitude_deg * DEG, longitude_deg * DEG,
                   float(height_m))

    @property
    def c_bn(self) -> np.ndarray:
        """Attitude C_b^n (3, 3)."""
        return quat_to_dcm(self.q)

    def pack(self) -> np.ndarray:
        """The kernel's state vector (module docstring of ``_kernel``)."""
        s = np.zeros(STATE_SIZE)
        s[0:4], s[4:7] = self.q, self.v
        s[7], s[8], s[9] = self.lat, self.lon, self.h
        s[10:22] = self._memory
        return s

    @classmethod
    def unpack(cls, s: np.ndarray) -> "InsState":
        return cls(s[0:4].copy(), s[4:7].copy(), float(s[7]), float(s[8]), float(s[9]),
                   s[10:22].copy())


@dataclass
class InsSolution:
    """Navigation at the ends of the output samples.

    ``t_s`` (m,) time since the start of the run [s]; ``q`` (m, 4) attitude body → ENU;
    ``v`` (m, 3) ENU velocity [m/s]; ``lat``, ``lon`` (m,) [rad]; ``h`` (m,) [m];
    ``vertical`` "held at the given height" or "free"; ``final`` the state after the last
    sample (to continue).
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vertical: str
    final: InsState

    def attitude(self) -> np.ndarray:
        """C_b^n (m, 3, 3)."""
        return quat_to_dcm(self.q)


def _check_increments(dtheta: np.ndarray, dv: np.ndarray, dt_s: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    if dtheta.ndim != 2 or dtheta.shape[1] != 3 or dv.shape != dtheta.shape:
        raise UserInputError(f"increments: need Δθ and Δv of shape (n, 3), got {dtheta.shape} "
                             f"and {dv.shape}")
    if dtheta.shape[0] == 0:
        raise UserInputError("increments: the span to navigate has 0 samples")
    if not (math.isfinite(dt_s) and dt_s > 0):
        raise UserInputError(f"increments: sample interval dt_s = {dt_s!r}; need a finite "
                             "value > 0")
    for name, a in (("Δθ (gyro)", dtheta), ("Δv (accelerometer)", dv)):
        bad = ~np.isfinite(a)
        if bad.any():
            k, j = map(int, np.argwhere(bad)[0])
            raise UserInputError(f"increments: {name} sample {k}, axis {'xyz'[j]} is {a[k, j]!r};"
                                 " navigation needs finite increments (fill or cut the gap)")
    return dtheta, dv


def integrate(state: InsState, dtheta: np.ndarray, dv: np.ndarray, dt_s: float, *,
              height: float | np.ndarray | None = "initial", output_every: int = 1
              ) -> InsSolution:
    """Navigate from ``state`` over increments Δθ, Δv (n, 3) [rad, m/s] of ``dt_s`` [s] each.

    ``height``: ``"initial"`` (default) holds the vertical channel at the start height; a float
    or an (n,) array [m] holds it at that height (per sample); ``None`` integrates it freely.
    ``output_every``: keep every k-th sample's navigation (the 8 h, 100 Hz run keeps 2.9 M
    samples × 10 values at k = 1; the scores use 1 Hz). See the module docstring for the
    algorithm. Bad input raises :class:`~rlgsim.ground.errors.UserInputError`.
    """
    dtheta, dv = _check_increments(dtheta, dv, dt_s)
    n = dtheta.shape[0]
    every = int(output_every)
    if every < 1:
        raise UserInputError(f"output_every = {output_every!r}; need an integer >= 1")
    if isinstance(height, str):
        if height != "initial":
            raise UserInputError(f"height = {height!r}; allowed: 'initial', a number, an array "
                                 "of n heights, or None (free vertical channel)")
        href, hold, vertical = np.full(n, state.h), 1, f"held at the initial height {state.h:g} m"
    elif height is None:
        href, hold, vertical = np.zeros(1), 0, "free (integrated, unstable beyond minutes)"
    else:
        href = np.broadcast_to(np.asarray(height, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(href)):
            raise UserInputError("height: the height input holds non-finite values")
        hold = 1
        vertical = (f"held at {href[0]:g} m" if np.all(href == href[0])
                    else "held at the given height input")
    s = state.pack()
    q, v, p = ins_loop(dtheta, dv, float(dt_s), s, href, hold, every)
    t = (np.arange(1, q.shape[0] + 1) * every) * float(dt_s)
    return InsSolution(t, q, v, p[:, 0], p[:, 1], p[:, 2], vertical, InsState.unpack(s))


def increments_from_pulses(gyro_pulses: np.ndarray, accel_pulses: np.ndarray,
                           gyro_weight: float | np.ndarray, accel_weight: float | np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Δθ [rad] and Δv [m/s] (n, 3) from pulse counts with the device's nominal pulse weights
    ``gyro_weight`` [rad/pulse] and ``accel_weight`` [(m/s)/pulse] (scalars or per axis)."""
    ng = np.asarray(gyro_pulses, dtype=float)
    na = np.asarray(accel_pulses, dtype=float)
    if ng.ndim != 2 or ng.shape[1] != 3 or na.shape != ng.shape:
        raise UserInputError(f"pulses: need gyro and accelerometer counts of shape (n, 3), got "
                             f"{ng.shape} and {na.shape}")
    return ng * np.asarray(gyro_weight, float), na * np.asarray(accel_weight, float)
