"""The navigator (rlgsim.estimators.ins) against independent references.

* exact increments of a static IMU and of the paper-000 turntable programme (the simulator's
  closed-form kinematics, rlgsim.sim.motion) → the mechanization's own position error;
* constant gyro and accelerometer biases → the error time series against the linearised
  ψ-angle error model (Titterton & Weston 2004 eqs. 12.6–12.13), written out here on its own and
  integrated with scipy.integrate.solve_ivp;
* the Schuler period against the eigenvalues of that model (and the textbook 2π√(R/g));
* gyrocompassing heading error against the bound ε_E/(Ω cos L).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rlgsim.estimators.ins import (InsState, align, attitude_error, coarse_align,
                                   heading_error_bound, integrate)
from rlgsim.ground.earth import earth_rate_enu, normal_gravity, radii_of_curvature
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import rotation_matrix
from rlgsim.ground.units import DEG, EARTH_RATE, HOUR, MICRO_G
from rlgsim.sim.motion.kinematics import Motion, segments_from_program
from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.turntable import TurntableProgram

LAT = 34.0


def static_increments(c_bn, lat, n, dt, gyro_bias=(0, 0, 0), accel_bias=(0, 0, 0)):
    """Exact increments of an IMU at rest with attitude c_bn, plus constant body biases."""
    w_b = c_bn.T @ earth_rate_enu(lat) + np.asarray(gyro_bias, float)
    f_b = c_bn.T @ np.array([0, 0, normal_gravity(lat)]) + np.asarray(accel_bias, float)
    return np.tile(w_b * dt, (n, 1)), np.tile(f_b * dt, (n, 1))


def horizontal_error(sol, lat_deg, lon_deg=0.0):
    """(north, east) position errors [m] of a solution against a fixed site."""
    r_m, r_e = radii_of_curvature(lat_deg)
    return ((sol.lat - lat_deg * DEG) * (r_m + sol.h),
            (sol.lon - lon_deg * DEG) * (r_e + sol.h) * math.cos(lat_deg * DEG))


def test_static_truth_8h_stays_put():
    dt, n = 0.01, 8 * 3600 * 100
    c = rotation_matrix(np.array([0.01, -0.02, 0.7]))
    dth, dv = static_increments(c, LAT, n, dt)
    sol = integrate(InsState.at_rest(c, LAT, 10.0, 120.0), dth, dv, dt, output_every=100)
    north, east = horizontal_error(sol, LAT, 10.0)
    assert np.hypot(north, east).max() < 0.5                     # acceptance: < 0.5 m
    assert np.hypot(north, east).max() < 0.01                    # what it really does
    assert sol.vertical.startswith("held") and np.all(sol.h == 120.0)


def test_turntable_programme_8h_truth():
    """The paper-000 calibration sequence (20 °/s, 19 positions, repeated) for 8 h at 100 Hz."""
    site, rate, dur = Site(LAT, 0.0), 100.0, 8 * 3600.0
    motion = Motion(segments_from_program(TurntableProgram.calibration19(rate_deg_s=20.0),
                                          dur + 10.0), site)
    blk = motion.increments(0.0, int(dur * rate), rate, angles=False)
    start = InsState.at_rest(motion.attitude(np.array([0.0]))[0], LAT)
    sol = integrate(start, blk.dtheta_rad, blk.dv_m_per_s, 1.0 / rate, output_every=100)
    north, east = horizontal_error(sol, LAT)
    assert np.hypot(north, east).max() < 5.0                     # acceptance: < 5 m
    psi = attitude_error(sol.attitude(), motion.attitude(sol.t_s))
    assert np.abs(psi).max() < 1e-9                              # rad


def test_chunked_run_equals_one_run():
    dt, n = 0.01, 20000
    rng = np.random.default_rng(3)
    c = rotation_matrix(np.array([0.3, 0.1, -1.2]))
    dth, dv = static_increments(c, LAT, n, dt)
    dth = dth + rng.normal(0, 1e-6, dth.shape)
    dv = dv + rng.normal(0, 1e-4, dv.shape)
    s0 = InsState.at_rest(c, LAT)
    one = integrate(s0, dth, dv, dt)
    a = integrate(s0, dth[:7001], dv[:7001], dt)
    b = integrate(a.final, dth[7001:], dv[7001:], dt)
    np.testing.assert_array_equal(np.concatenate([a.q, b.q]), one.q)
    np.testing.assert_array_equal(np.concatenate([a.lat, b.lat]), one.lat)
    np.testing.assert_array_equal(np.concatenate([a.v, b.v]), one.v)


# ------------------------------------------------------------------ linearised error model

def error_model(lat_deg, g):
    """dx/dt = A x + u of x = (ψ_E, ψ_N, ψ_U, δv_E, δv_N, δL, δλ) at rest, height held
    (T&W eqs. 12.6, 12.11, 12.13; ψ with C̃ = (I − [ψ×]) C)."""
    L = lat_deg * DEG
    r_m, r_e = radii_of_curvature(lat_deg)
    W = EARTH_RATE
    a = np.zeros((7, 7))
    # ψ̇ = −ω_ie × ψ + δω_ie + δω_en − C δω_ib
    a[0, 1], a[0, 2] = W * math.sin(L), -W * math.cos(L)
    a[1, 0] = -W * math.sin(L)
    a[2, 0] = W * math.cos(L)
    a[0, 4] = -1 / r_m                                  # δω_en,E = −δv_N/R_M
    a[1, 3] = 1 / r_e                                   # δω_en,N = δv_E/R_E
    a[2, 3] = math.tan(L) / r_e                         # δω_en,U = δv_E tan L/R_E
    a[1, 5] = -W * math.sin(L)                          # δω_ie,N = −Ω sin L δL
    a[2, 5] = W * math.cos(L)                           # δω_ie,U = Ω cos L δL
    # δv̇ = f × ψ − 2 ω_ie × δv + C δf, f = (0, 0, g)
    a[3, 1], a[4, 0] = -g, g
    a[3, 4], a[4, 3] = 2 * W * math.sin(L), -2 * W * math.sin(L)
    a[5, 4] = 1 / r_m
    a[6, 3] = 1 / (r_e * math.cos(L))
    return a


def test_biases_follow_the_linear_error_model():
    lat, dt, dur = LAT, 0.1, 8 * 3600.0
    n = int(dur / dt)
    c = rotation_matrix(np.array([0.0, 0.0, 0.5]))       # heading 0.5 rad, level
    b_g = np.array([0.01, -0.008, 0.006]) * DEG / HOUR
    b_a = np.array([50.0, -40.0, 30.0]) * MICRO_G
    dth, dv = static_increments(c, lat, n, dt, b_g, b_a)
    sol = integrate(InsState.at_rest(c, lat), dth, dv, dt, output_every=10)
    north, east = horizontal_error(sol, lat)
    psi = attitude_error(sol.attitude(), c)
    g = normal_gravity(lat)
    a = error_model(lat, g)
    u = np.zeros(7)
    u[0:3] = -(c @ b_g)
    u[3:5] = (c @ b_a)[:2]
    ref = solve_ivp(lambda t, x: a @ x + u, (0, dur), np.zeros(7), t_eval=sol.t_s,
                    method="DOP853", rtol=1e-10, atol=1e-16)
    r_m, r_e = radii_of_curvature(lat)
    x = ref.y
    pairs = {"psi_E": (psi[:, 0], x[0]), "psi_N": (psi[:, 1], x[1]), "psi_U": (psi[:, 2], x[2]),
             "v_E": (sol.v[:, 0], x[3]), "v_N": (sol.v[:, 1], x[4]),
             "north": (north, x[5] * r_m), "east": (east, x[6] * r_e * math.cos(lat * DEG))}
    for name, (got, want) in pairs.items():
        rel = np.abs(got - want).max() / np.abs(want).max()
        assert rel < 0.01, (name, rel)                           # acceptance: within 1 %
        # the rest (1e-3 here) is the model's own truncation: it halves when the biases are
        # halved (second-order terms such as ψ_U·ψ_E, ψ_U ≈ 1e-3 rad after 8 h)


def _crossings(t, y):
    s = np.signbit(y)
    k = np.nonzero(s[1:] != s[:-1])[0]
    return t[k] - y[k] * (t[k + 1] - t[k]) / (y[k + 1] - y[k])


def test_schuler_period():
    """North accelerometer bias at the equator: the North velocity error oscillates with the
    Schuler period; measured from its zero crossings over 8 h."""
    lat, dt, dur = 0.0, 0.1, 8 * 3600.0
    n = int(dur / dt)
    dth, dv = static_increments(np.eye(3), lat, n, dt, accel_bias=(0, 100 * MICRO_G, 0))
    sol = integrate(InsState.at_rest(np.eye(3), lat), dth, dv, dt, output_every=10)
    tz = _crossings(sol.t_s, sol.v[:, 1])
    half = np.polyfit(np.arange(tz.size), tz, 1)[0]
    measured = 2 * half
    g = normal_gravity(lat)
    lam = np.linalg.eigvals(error_model(lat, g))
    model = 2 * math.pi / np.abs(lam.imag).max()
    r_m, _ = radii_of_curvature(lat)
    textbook = 2 * math.pi * math.sqrt(r_m / g)
    assert abs(measured / model - 1) < 1e-3                      # acceptance: 0.1 %
    # at the equator the δL feedback of the Earth rate cancels its ψ_U coupling: the model's
    # period is the textbook 2π√(R_M/g) (84.28 min here); measured 7e-9 off both
    assert abs(measured / textbook - 1) < 1e-3
    assert 84.0 < textbook / 60 < 84.6


@pytest.mark.parametrize("lat", [34.0, -60.0])
def test_gyrocompass_heading_error_matches_bound(lat):
    c = rotation_matrix(np.array([0.002, -0.001, 0.7]))
    eps_e = 0.01 * DEG / HOUR
    dt, n = 0.01, 600 * 100
    dth, dv = static_increments(c, lat, n, dt, gyro_bias=c.T @ np.array([eps_e, 0, 0]))
    c_est = coarse_align(dth, dv, dt)
    psi_u = attitude_error(c_est, c)[2]
    bound = heading_error_bound(eps_e, lat)
    assert abs(abs(psi_u) / abs(bound) - 1) < 0.02              # acceptance: within 2 %
    assert np.sign(psi_u) == -np.sign(bound)


def test_fine_alignment_reaches_the_bound_and_levels():
    lat = LAT
    c = rotation_matrix(np.array([0.001, 0.002, 2.0]))
    eps = np.array([0.01, 0.0, 0.0]) * DEG / HOUR           # East gyro bias
    b_a = np.array([0.0, 0.0, 0.0])
    dt, n = 0.01, 1800 * 100
    rng = np.random.default_rng(7)
    dth, dv = static_increments(c, lat, n, dt, gyro_bias=c.T @ eps, accel_bias=b_a)
    dth += rng.normal(0, 0.003 * DEG / math.sqrt(HOUR) * math.sqrt(dt), dth.shape)
    dv += rng.normal(0, 30 * MICRO_G * math.sqrt(dt), dv.shape)
    al = align(dth, dv, dt, lat)
    psi = attitude_error(al.c_bn, c)
    bound = heading_error_bound(eps[0], lat)
    assert abs(psi[2] + bound) < 0.1 * abs(bound) + 3 * al.heading_sigma_rad
    assert np.all(np.abs(psi[:2]) < 20e-6)                   # level to 4 arcsec
    assert al.cov.shape == (3, 3) and al.heading_sigma_rad < 5e-3


def test_radii_of_curvature_limits():
    """Equator: R_M = a(1 − e²), R_E = a; pole: both a/√(1 − e²) (Groves eqs. 2.105–2.106)."""
    from rlgsim.ground.earth import WGS84_A, WGS84_E2
    r_m, r_e = radii_of_curvature(0.0)
    assert r_m == pytest.approx(WGS84_A * (1 - WGS84_E2), rel=1e-15) and r_e == WGS84_A
    r_m, r_e = radii_of_curvature(90.0)
    assert r_m == pytest.approx(WGS84_A / math.sqrt(1 - WGS84_E2), rel=1e-14)
    assert r_e == pytest.approx(r_m, rel=1e-14)


@pytest.mark.parametrize("bad", ["nan", "zero", "shape", "dt"])
def test_bad_increments_raise_one_line(bad):
    dth, dv = static_increments(np.eye(3), LAT, 10, 0.01)
    dt = 0.01
    if bad == "nan":
        dth[4, 1] = np.nan
    elif bad == "zero":
        dth, dv = dth[:0], dv[:0]
    elif bad == "shape":
        dth = dth[:, :1]
    else:
        dt = 0.0
    with pytest.raises(UserInputError) as e:
        integrate(InsState.at_rest(np.eye(3), LAT), dth, dv, dt)
    assert "\n" not in str(e.value)
