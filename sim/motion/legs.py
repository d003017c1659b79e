"""A vehicle's motion as legs of polynomials: attitude angles and body-frame velocity in time.

A trajectory (:mod:`rlgsim.sim.motion.trajectory`) is a sequence of **legs**. Inside a leg of
duration T every one of six channels is a polynomial of degree ≤ 5 in the leg's own time
τ ∈ [0, T]:

    x(τ) = (ψ, θ, φ, v_x, v_y, v_z)(τ)

heading ψ (from North, clockwise), pitch θ (nose up) and roll φ (right wing down) [rad], and
the ground velocity in body axes v^b [m/s]. Body axes of a vehicle: x right, y forward, z up
(the ENU-paired convention, so body = ENU at zero angles as on the turntable), and

    C_b^n = R_z(−ψ) R_x(θ) R_y(φ)

(heading about Up, then pitch about the new right axis, then roll about the forward axis — the
physical angles of the usual yaw–pitch–roll sequence, written for ENU and right–forward–up;
Titterton & Weston 2004 §3.6.3 for the construction). Every leg starts where the previous one
ended: its constant terms are the previous leg's values at its end (a smooth leg's target, which
its polynomial meets to a few ulps), so the channels, and with them attitude and velocity, are
continuous; their rates may jump between legs (a rate leg after
a hold), as in gnss-ins-sim's type-1 commands, and the kinematics split a sample at such a
boundary.

Two kinds of leg, both closed forms (nothing integrated):

* :func:`rate_leg` — constant channel rates: linear polynomials (hold, constant velocity, a
  turn at a constant rate, a constant acceleration along a body axis, a steady pitch-up);
* :func:`smooth_leg` — from the start values to target values with the quintic "smoothstep"
  s(u) = 10u³ − 15u⁴ + 6u⁵, u = τ/T: rates and rate-of-rates zero at both ends, peak rate
  15/8·Δ/T at u = ½ and peak rate-of-rate (10/√3)·Δ/T² at u = ½ ∓ √3/6 (a minimum-jerk profile;
  Flash & Hogan 1985).

Why by hand: the kinematics need the channel values and their exact derivatives at arbitrary
times, vectorised over legs of different kinds; numpy's polynomial classes evaluate one
polynomial at a time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: channel order of a leg's polynomials
CHANNELS = ("heading", "pitch", "roll", "v_right", "v_forward", "v_up")
N_CHANNELS = 6
DEGREE = 5

#: most legs a route may have (a motion file's commands, a table's rows): building a route
#: peaks at ~3 kB per leg (gnss-ins-sim's sample-by-sample commands at 0.01 s, one hour: 360 000
#: legs, read in 8 s, built in 15 s, 1.1 GB peak), ~3 GB at this count — a 27-h table at 10 Hz
MAX_LEGS = 1_000_000
#: what to do with a route past :data:`MAX_LEGS` (the refusals' advice)
TOO_MANY_LEGS_ADVICE = ("resample a position table to a lower rate, or merge a motion file's "
                        "consecutive commands into longer ones")
#: peak |rate| of a smooth leg = SMOOTH_PEAK_RATE · |Δ| / T
SMOOTH_PEAK_RATE = 15.0 / 8.0
#: peak |rate of rate| of a smooth leg = SMOOTH_PEAK_ACCEL · |Δ| / T²
SMOOTH_PEAK_ACCEL = 10.0 / math.sqrt(3.0)


@dataclass(frozen=True)
class Leg:
    """One leg: ``duration_s`` T [s], ``coef`` (6, DEGREE + 1) ascending powers of τ [rad or
    m/s per s^k], ``kind`` ("rate", "smooth" or "table"), ``label``, ``gnss`` whether a GNSS
    receiver sees the sky during the leg (gnss-ins-sim's visibility column; true by default),
    ``frame`` what the last three channels hold."""

    duration_s: float
    coef: np.ndarray
    kind: str
    label: str = ""
    gnss: bool = True
    #: what channels 3-5 hold: "body" the body-frame ground velocity [m/s], "geodetic" the
    #: position itself — latitude, longitude [rad], height [m] (a table of positions,
    #: :mod:`rlgsim.sim.motion.position_table`)
    frame: str = "body"
    #: the values the next leg starts from (a smooth leg: its target exactly, which its
    #: polynomial meets to a few ulps); None: the polynomial's values at T
    target: np.ndarray | None = None

    def values(self, tau: np.ndarray) -> np.ndarray:
        """Channel values x(τ) (6, k) at leg times ``tau`` (k,) [s] (Horner)."""
        return _horner(self.coef, tau)

    def rates(self, tau: np.ndarray) -> np.ndarray:
        """Channel rates dx/dτ (6, k)."""
        return _horner(self.coef[:, 1:] * np.arange(1, DEGREE + 1), tau)

    def end(self) -> np.ndarray:
        """Channel values at τ = T, (6,) (a smooth leg: its target, so a stop is a speed of
        exactly 0 and the next leg stands still bit for bit)."""
        if self.target is not None:
            return self.target.copy()
        return self.values(np.array([self.duration_s]))[:, 0]

    def peak_rates(self) -> np.ndarray:
        """Largest |rate| of each channel over the leg (6,): at the ends for a rate leg, at
        the middle for a smooth one (both exact for these polynomials)."""
        tau = np.array([0.0, 0.5 * self.duration_s, self.duration_s])
        return np.max(np.abs(self.rates(tau)), axis=1)


def _horner(coef: np.ndarray, tau: np.ndarray) -> np.ndarray:
    tau = np.asarray(tau, dtype=float)
    out = np.broadcast_to(coef[:, -1:], (coef.shape[0], tau.size)).copy()
    for k in range(coef.shape[1] - 2, -1, -1):
        out *= tau
        out += coef[:, k:k + 1]
    return out


def rate_leg(start: np.ndarray, rates: np.ndarray, duration_s: float, *, label: str = "",
             gnss: bool = True) -> Leg:
    """Constant channel ``rates`` (6,) [rad/s, m/s²] from ``start`` (6,) for ``duration_s``."""
    coef = np.zeros((N_CHANNELS, DEGREE + 1))
    coef[:, 0] = start
    coef[:, 1] = rates
    return Leg(float(duration_s), coef, "rate", label, gnss)


def smooth_leg(start: np.ndarray, target: np.ndarray, duration_s: float, *, label: str = "",
               gnss: bool = True) -> Leg:
    """From ``start`` to ``target`` (6,) over ``duration_s`` > 0 along the quintic smoothstep
    (rates zero at both ends)."""
    t = float(duration_s)
    d = np.asarray(target, dtype=float) - np.asarray(start, dtype=float)
    coef = np.zeros((N_CHANNELS, DEGREE + 1))
    coef[:, 0] = start
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        # absurd inputs overflow here; the route's checks refuse them in one line
        coef[:, 3] = 10.0 * d / t ** 3
        coef[:, 4] = -15.0 * d / t ** 4
        coef[:, 5] = 6.0 * d / t ** 5
    return Leg(t, coef, "smooth", label, gnss, target=np.array(target, dtype=float))


def smooth_time(delta: np.ndarray, max_rate: np.ndarray, max_accel: np.ndarray) -> float:
    """Shortest T of a smooth leg whose channel changes ``delta`` keep their peak rates within
    ``max_rate`` and their peak rates of rate within ``max_accel`` (per channel; inf or 0 ⇒
    no limit), 0 when nothing changes."""
    d = np.abs(np.asarray(delta, dtype=float))
    t = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        by_rate = np.where((d > 0) & (max_rate > 0), SMOOTH_PEAK_RATE * d / max_rate, 0.0)
        by_acc = np.where((d > 0) & (max_accel > 0), np.sqrt(SMOOTH_PEAK_ACCEL * d / max_accel),
                          0.0)
    t = max(t, float(np.max(by_rate)), float(np.max(by_acc)))
    return t
