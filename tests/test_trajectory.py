"""A vehicle's exact kinematics (sim/motion/legs.py, sim/motion/trajectory.py and its compiled
quadrature sim/motion/_trajectory_kernel.py).

References, independent of the code under test:

* the **strapdown equations in the Earth-fixed (ECEF) frame** (Groves 2013 eqs. 5.27-5.36:
  ṙ = v, v̇ = C_b^e f^b − 2Ω×v + g^e, Ċ_b^e = C_b^e[ω_ib^b×] − [Ω×]C_b^e) integrated by scipy's
  DOP853 from the true initial state, driven by the trajectory's ω_ib^b(t) and f^b(t): they
  must reproduce the trajectory's own geodetic position, ENU velocity and attitude. This checks
  every term of the ENU formulation (Earth rate, transport rate, Coriolis, gravity) through a
  different frame;
* **fine Gauss–Legendre quadrature** (10 nodes on each of 4 sub-intervals, NumPy) of those
  rates over each sample (split where a leg ends inside it): the increments must be these
  integrals to float64 rounding;
* the **turntable's static site** (sim/motion/site.py) for a vehicle at rest.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rlgsim.ground.earth import (WGS84_A, WGS84_E2, enu_to_ecef_matrix, geodetic_to_ecef,
                                 normal_gravity_rad)
from rlgsim.ground.frames import skew
from rlgsim.ground.units import DEG, EARTH_RATE
from rlgsim.sim.motion.legs import rate_leg, smooth_leg
from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.trajectory import (InitialState, Trajectory, attitude_from_euler,
                                          quaternion_from_euler)
from rlgsim.ground.frames import quat_to_dcm

START = InitialState(34.0 * DEG, 108.9 * DEG, 400.0)
OMEGA = np.array([0.0, 0.0, EARTH_RATE])


def manoeuvres(t_hold: float = 10.0) -> list:
    """Stand, accelerate, a smooth 90° turn while climbing, a rolled rate turn, a dive."""
    x = np.zeros(6)
    x[0] = 30.0 * DEG
    legs = [rate_leg(x, np.zeros(6), t_hold)]
    legs.append(rate_leg(legs[-1].end(), np.array([0, 0, 0, 0, 1.5, 0]), 20.005))
    x = legs[-1].end()
    legs.append(smooth_leg(x, x + np.array([90 * DEG, 5 * DEG, 10 * DEG, 0, 5.0, 0]), 25.0))
    legs.append(rate_leg(legs[-1].end(), np.array([3 * DEG, 0.2 * DEG, 0, 0.05, 0.2, 0.1]),
                         30.0))
    x = legs[-1].end()
    legs.append(smooth_leg(x, x + np.array([-40 * DEG, -15 * DEG, -10 * DEG, 0, -8.0, 0]),
                           14.9973))
    return legs


def ecef_to_geodetic(r: np.ndarray) -> tuple[float, float, float]:
    """Geodetic (L, λ, h) of an ECEF position by fixed-point iteration (converges to rounding
    in a few steps below 10 km height)."""
    x, y, z = r
    p = math.hypot(x, y)
    lon = math.atan2(y, x)
    lat = math.atan2(z, p * (1 - WGS84_E2))
    for _ in range(20):
        n = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(lat) ** 2)
        h = p / math.cos(lat) - n
        lat = math.atan2(z, p * (1 - WGS84_E2 * n / (n + h)))
    return lat, lon, h


def ecef_reference(traj: Trajectory, t_end: float) -> dict[float, tuple]:
    """The ECEF strapdown equations driven by the trajectory's rates, leg by leg (the rates may
    jump at a leg's start), from the true state at 0: {leg end: (r^e, v^e, C_b^e)}."""
    s0 = traj.states(np.array([0.0]))
    cne = enu_to_ecef_matrix(s0.lat[0], s0.lon[0])
    y = np.concatenate([geodetic_to_ecef(s0.lat[0], s0.lon[0], s0.height[0]),
                        cne @ s0.v_n[0], (cne @ s0.c_bn[0]).ravel()])

    def rhs(t: float, y: np.ndarray, leg: int) -> np.ndarray:
        w, f = traj._inputs(leg, np.array([t - traj._t0[leg]]))
        r, v, c = y[:3], y[3:6], y[6:].reshape(3, 3)
        lat, lon, h = ecef_to_geodetic(r)
        g = enu_to_ecef_matrix(lat, lon) @ np.array([0, 0, -normal_gravity_rad(lat, h)])
        return np.concatenate([v, c @ f[0] - 2 * np.cross(OMEGA, v) + g,
                               (c @ skew(w[0]) - skew(OMEGA) @ c).ravel()])
    out = {}
    for leg in range(len(traj.legs)):
        a, b = traj._t0[leg], min(traj._t1[leg], t_end)
        if b <= a:
            break
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-13,
                        atol=np.r_[[1e-7] * 3, [1e-10] * 3, [1e-14] * 9], args=(leg,))
        y = sol.y[:, -1]
        out[b] = (y[:3], y[3:6], y[6:].reshape(3, 3))
    return out


def test_kinematics_against_ecef_strapdown_equations():
    traj = Trajectory(manoeuvres(), START, until_s=120.0)
    ref = ecef_reference(traj, 120.0)
    for t, (r, v, c) in ref.items():
        s = traj.states(np.array([t]))
        cne = enu_to_ecef_matrix(s.lat[0], s.lon[0])
        r_traj = geodetic_to_ecef(s.lat[0], s.lon[0], s.height[0])
        # the reference's own error at these tolerances: ~1e-7 m, 1e-10 m/s, 1e-13 rad per leg
        assert np.linalg.norm(r - r_traj) < 1e-5, t
        assert np.linalg.norm(v - cne @ s.v_n[0]) < 1e-8, t
        dc = (cne @ s.c_bn[0]).T @ c - np.eye(3)
        assert np.max(np.abs(dc)) < 1e-11, t
    # and the run moved: 120 s of driving, turning and climbing
    end = traj.states(np.array([120.0]))
    assert end.height[0] - START.height_m > 10.0 and np.linalg.norm(end.v_n[0]) > 5.0


def test_a_missing_term_would_fail_the_reference():
    """The reference check is sharp: dropping Coriolis from f^b moves the position by metres."""
    traj = Trajectory(manoeuvres(), START, until_s=60.0)
    real = traj._inputs

    def no_coriolis(j, tau):
        w, f = real(j, tau)
        c, _, v_n, _, _ = traj._velocity(j, tau)
        lat = traj._positions(j, tau)[0]
        wie = np.stack([np.zeros_like(lat), EARTH_RATE * np.cos(lat), EARTH_RATE * np.sin(lat)],
                       -1)
        return w, f - np.einsum("kji,kj->ki", c, np.cross(2 * wie, v_n))
    traj._inputs = no_coriolis
    ref = ecef_reference(traj, 60.0)
    traj._inputs = real
    r, _, _ = ref[max(ref)]
    s = traj.states(np.array([max(ref)]))
    assert np.linalg.norm(r - geodetic_to_ecef(s.lat[0], s.lon[0], s.height[0])) > 1e-3


def fine_integrals(traj: Trajectory, edges: np.ndarray, rate_hz: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """10-node Gauss–Legendre on 4 sub-intervals of each piece, pieces split at leg starts; a
    whole sample lasts exactly 1/f (its edges' difference carries the rounding of t)."""
    x, wq = np.polynomial.legendre.leggauss(10)
    dth, dv = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        cuts = [a, *[t for t in traj._t0 if a < t < b], b]
        sw, sf = np.zeros(3), np.zeros(3)
        for p, q in zip(cuts[:-1], cuts[1:]):
            length = 1.0 / rate_hz if len(cuts) == 2 else q - p
            for s in range(4):
                lo = p + length * s / 4
                h = length / 4
                t = lo + 0.5 * h * (x + 1)
                leg = traj.leg_of(np.array([p]))[0]
                w, f = traj._inputs(int(leg), t - traj._t0[leg])
                sw += 0.5 * h * (wq @ w)
                sf += 0.5 * h * (wq @ f)
        dth.append(sw)
        dv.append(sf)
    return np.array(dth), np.array(dv)


def assert_exact_integrals(traj, t0: float, n: int, rate_hz: float) -> None:
    """The ``n`` samples' increments from ``t0`` equal the fine reference integrals to float64
    rounding of sums of a few hundred terms of the increments' size."""
    mb = traj.increments(t0, n, rate_hz)
    k0 = round(t0 * rate_hz)
    ref_th, ref_v = fine_integrals(traj, (k0 + np.arange(n + 1)) / rate_hz, rate_hz)
    tol_th = 64 * np.finfo(float).eps * np.max(np.abs(ref_th)) + 1e-22
    tol_v = 64 * np.finfo(float).eps * np.max(np.abs(ref_v))
    assert np.max(np.abs(mb.dtheta_rad - ref_th)) < tol_th
    assert np.max(np.abs(mb.dv_m_per_s - ref_v)) < tol_v


@pytest.mark.parametrize("rate_hz, t0, n", [(100.0, 9.9, 40), (100.0, 30.0, 20),
                                            (100.0, 74.99, 15), (1.0, 28.0, 6)])
def test_increments_are_the_exact_integrals(rate_hz, t0, n):
    """Samples inside legs and across leg starts (10 s on the grid; 30.005 s and 74.9973 s
    inside a sample); at 1 Hz each sample is cut into 50 sub-intervals."""
    traj = Trajectory(manoeuvres(), START, until_s=120.0)
    assert_exact_integrals(traj, t0, n, rate_hz)


def constant_attitude_legs() -> list:
    """Legs of constant attitude (the 2- and 3-point quadratures of
    sim/motion/_trajectory_block.py): a minimum-jerk (quintic) speed-up to 30 m/s in 8 s, a
    climb at 20 m/s up along a 25° pitch held, a quintic stop, a hold at rest."""
    x = np.zeros(6)
    x[0], x[1] = 40.0 * DEG, 25.0 * DEG
    legs = [smooth_leg(x, x + np.array([0, 0, 0, 0, 30.0, 0]), 8.0)]
    legs.append(rate_leg(legs[-1].end(), np.zeros(6), 20.0))
    x = legs[-1].end()
    legs.append(smooth_leg(x, x * np.array([1, 1, 1, 0, 0, 0]), 6.0))
    legs.append(rate_leg(legs[-1].end(), np.zeros(6), 10.0))
    return legs


@pytest.mark.parametrize("rate_hz, t0, n", [(100.0, 0.0, 50), (100.0, 3.5, 40),
                                            (100.0, 27.9, 30), (1.0, 0.0, 40), (0.5, 0.0, 20)])
def test_constant_attitude_legs_are_exact_integrals(rate_hz, t0, n):
    """The legs of constant attitude take 3 (velocity changing) or 2 (holding) Gauss–Legendre
    points per ≤ 0.02-s sub-interval with the dense position at each, the climb at a held
    velocity its fitted 10-s chunks: still the integrals to float64 rounding of the 10-point
    reference, at 100 Hz and across 1-s and 2-s samples."""
    traj = Trajectory(constant_attitude_legs(), START, until_s=50.0)
    assert list(traj._level) == [1, 2, 1, 2, 2]          # and the hold to the end
    assert list(traj._chunk[[1, 3, 4]]) == [10.0, 0.0, 0.0]  # the rest stand still; the
    assert 0.04 <= min(traj._chunk[[0, 2]]) <= max(traj._chunk[[0, 2]]) <= 1.0  # speed-up
    # and the stop take Chebyshev chunks of ≥ 4 samples (sim/motion/_trajectory_cheb.py)
    assert_exact_integrals(traj, t0, n, rate_hz)


def test_fitted_chunks_near_the_pole_are_exact_integrals():
    """An aircraft holding 250 m/s at 85° N (the integrands' time scale R cos L / v ≈ 2200 s:
    2.2-s chunks): the samples around a chunk's end are the 10-point reference integrals, and
    the same numbers whichever block starts inside the chunk."""
    x = np.zeros(6)
    x[0], x[4] = 20.0 * DEG, 250.0
    traj = Trajectory([rate_leg(x, np.zeros(6), 30.0)], InitialState(85.0 * DEG, 0.0, 9000.0),
                      until_s=30.0)
    chunk = traj._chunk[0]
    assert 2.0 < chunk < 2.4
    assert_exact_integrals(traj, round(3 * chunk, 2) - 0.1, 20, 100.0)
    whole, part = traj.increments(0.0, 700, 100.0), traj.increments(3.33, 367, 100.0)
    assert np.array_equal(whole.dtheta_rad[333:], part.dtheta_rad)
    assert np.array_equal(whole.dv_m_per_s[333:], part.dv_m_per_s)


def test_at_rest_the_vehicle_senses_earth_rate_and_gravity():
    traj = Trajectory([rate_leg(np.zeros(6), np.zeros(6), 50.0)], START, until_s=100.0)
    mb = traj.increments(40.0, 3000, 100.0)
    site = Site(34.0, 400.0)
    np.testing.assert_allclose(mb.dtheta_rad, np.broadcast_to(site.earth_rate_enu * 0.01,
                                                              (3000, 3)), rtol=0, atol=1e-21)
    np.testing.assert_allclose(mb.dv_m_per_s, np.broadcast_to(site.specific_force_enu * 0.01,
                                                              (3000, 3)), rtol=0, atol=4e-17)
    s = traj.states(np.array([90.0]))
    assert s.lat[0] == START.lat_rad and s.height[0] == START.height_m


def test_standing_still_samples_are_one_increment():
    """A stop (a smooth leg to speed 0, then a hold) is told to the IMU stage as a run of
    samples holding one increment — the numbers every sample has anyway."""
    legs = manoeuvres()[:2]
    x = legs[-1].end()
    legs.append(smooth_leg(x, x * np.array([1, 1, 1, 0, 0, 0]), 10.0))
    legs.append(rate_leg(legs[-1].end(), np.zeros(6), 30.0))
    traj = Trajectory(legs, START, until_s=80.0)
    mb = traj.increments(20.0, 5000, 100.0)
    start = math.ceil((traj.leg_starts[3] - 20.0) * 100)          # the first whole sample
    assert mb.constant == ((start, 5000),)
    single = traj.increments(45.0, 1, 100.0)
    assert single.constant == ()
    assert np.array_equal(mb.dtheta_rad[2500], single.dtheta_rad[0])
    assert np.array_equal(mb.dv_m_per_s[2500], single.dv_m_per_s[0])
    assert np.all(mb.dv_m_per_s[start:] == mb.dv_m_per_s[start])


def test_positions_are_solve_ivps_to_its_tolerance():
    """The route's positions are stepped by the compiled DOP853 (sim/motion/_trajectory_route.py:
    scipy's method, tableau and controller, the stage sums in stage order instead of a BLAS
    ``dot``): leg by leg they are solve_ivp's DOP853 solution up to the integration's own
    error. Each of the two keeps every step's local error estimate below its scale
    atol + rtol·|y|, so they differ by at most 2 × steps × that scale (the sum of both
    solutions' local errors); a standing leg holds its start (what DOP853's steps of a zero
    rate give, bit for bit)."""
    from rlgsim.sim.motion.trajectory import _ATOL, _RTOL, _dense
    traj = Trajectory(manoeuvres(), START, until_s=120.0)
    assert traj._still[0] and traj._position[0][1] is None
    for j in (1, 2, 3, 4):
        y0, (first, count) = traj._position[j]
        ref = solve_ivp(traj_rhs(traj, j), (0.0, traj.legs[j].duration_s), y0,
                        method="DOP853", rtol=_RTOL, atol=_ATOL, dense_output=True)
        tau = np.linspace(0.0, traj.legs[j].duration_s, 101)
        ours, theirs = _dense(traj._dense[first:first + count], tau), ref.sol(tau)
        scale = np.asarray(_ATOL)[:, None] + _RTOL * np.abs(theirs)
        steps = max(count, len(ref.t) - 1)
        assert np.all(np.abs(ours - theirs) <= 2 * steps * scale), j
    still = solve_ivp(traj_rhs(traj, 0), (0.0, traj.legs[0].duration_s), traj._position[0][0],
                      method="DOP853", rtol=_RTOL, atol=_ATOL, dense_output=True)
    assert np.array_equal(still.sol(np.linspace(0.0, traj.legs[0].duration_s, 7)),
                          np.repeat(traj._position[0][0][:, None], 7, axis=1))


def traj_rhs(traj: Trajectory, j: int):
    """The right-hand side of leg ``j``'s position integration."""
    from rlgsim.sim.motion._trajectory_kernel import position_rate_at
    return lambda tau, p: position_rate_at(traj._coef, traj._dcoef, j, tau, p[0], p[2],
                                           WGS84_E2, WGS84_A)


def test_same_numbers_whatever_block_asks():
    """A sample's increments do not depend on which call computes it. (And the range check's
    compiled peaks are the NumPy formulas' on the same grid — sums of a few products in another
    order: within 1e-14, ~45 ulps — the largest rate at the same time.)"""
    traj = Trajectory(manoeuvres(), START, until_s=120.0)
    (w, f, at), (wn, fn, atn) = traj.peak_inputs(), traj.peak_inputs_numpy()
    assert at == atn and w == pytest.approx(wn, rel=1e-14, abs=0)
    assert f == pytest.approx(fn, rel=1e-14, abs=0)
    whole = traj.increments(0.0, 12000, 100.0)
    for t0, n in ((29.0, 1700), (41.37, 300)):  # from inside the Chebyshev chunks of the
        part = traj.increments(t0, n, 100.0)     # speed-up and of the smooth turn
        k = round(t0 * 100)
        assert np.array_equal(whole.dtheta_rad[k:k + n], part.dtheta_rad)
        assert np.array_equal(whole.dv_m_per_s[k:k + n], part.dv_m_per_s)


@pytest.mark.parametrize("until", [42.3, 30.0])
def test_numpy_peaks_end_with_the_run(until):
    """The NumPy reference of the range check's peaks stops at the run's end as the kernel does
    (a leg's grid cut there, the legs after it left out): a run ending inside the smooth turn,
    before its peak rate at 42.505 s, and one ending at a leg's start."""
    traj = Trajectory(manoeuvres(), START, until_s=until)
    (w, f, at), (wn, fn, atn) = traj.peak_inputs(), traj.peak_inputs_numpy()
    assert at == atn <= until and w == pytest.approx(wn, rel=1e-14, abs=0)
    assert f == pytest.approx(fn, rel=1e-14, abs=0)
    assert wn < Trajectory(manoeuvres(), START, until_s=120.0).peak_inputs_numpy()[0]


def test_range_check_leaves_out_only_legs_under_the_ranges():
    """The range check (``peak_inputs(below=...)``) leaves out the legs of constant attitude and
    velocity whose bounds are under both ranges — each such leg's own grid peaks are under them
    (the bounds hold) — and its peaks, when over a range, are the full grid's, time and all;
    with ranges no hold's bounds are under, it is the full grid's."""
    from rlgsim.sim.motion._trajectory_kernel import peak_inputs
    from rlgsim.sim.motion.trajectory import _EARTH
    traj = Trajectory(constant_attitude_legs() + manoeuvres()[1:], START, until_s=200.0)
    full = traj.peak_inputs()
    below = (0.999 * full[0], 0.999 * full[1])
    calm = traj._calm_legs(*below)
    assert calm.sum() >= 3 and traj.peak_inputs(below=below) == full
    for j in np.flatnonzero(calm):
        skip = np.ones(len(calm), dtype=np.int64)
        skip[j] = 0
        own = np.empty(3)
        peak_inputs(traj._coef, traj._dcoef, traj._d2coef, traj._legs_i, traj._legs_f,
                    traj._dense, _EARTH, 0.5, skip, own)
        assert own[0] < below[0] and own[1] < below[1]
    assert not traj._calm_legs(1e-6, 1.0).any()
    assert traj.peak_inputs(below=(1e-6, 1.0)) == full


def test_attitude_convention_and_quaternion():
    """Heading 90° points the nose (body y) East; pitch lifts it; roll drops the right wing
    (body x); the stored quaternion is the same rotation."""
    c = attitude_from_euler(np.array([90 * DEG]), np.array([0.0]), np.array([0.0]))[0]
    np.testing.assert_allclose(c @ [0, 1, 0], [1, 0, 0], atol=1e-15)
    c = attitude_from_euler(np.array([0.0]), np.array([10 * DEG]), np.array([20 * DEG]))[0]
    assert (c @ [0, 1, 0])[2] > 0 and (c @ [1, 0, 0])[2] < 0
    h, p, r = np.array([0.3, -2.0]), np.array([0.1, 0.7]), np.array([-0.4, 1.2])
    np.testing.assert_allclose(quat_to_dcm(quaternion_from_euler(h, p, r)),
                               attitude_from_euler(h, p, r), atol=1e-15)


def test_smooth_leg_limits_and_ends():
    from rlgsim.sim.motion.legs import SMOOTH_PEAK_ACCEL, SMOOTH_PEAK_RATE, smooth_time
    leg = smooth_leg(np.zeros(6), np.array([1.0, 0, 0, 0, 2.0, 0]), 4.0)
    tau = np.linspace(0, 4, 40001)
    rates = leg.rates(tau)
    assert np.allclose(leg.values(np.array([4.0]))[:, 0], [1, 0, 0, 0, 2, 0], atol=1e-15)
    assert abs(rates[0, 0]) < 1e-15 and abs(rates[0, -1]) < 1e-15
    assert np.max(np.abs(rates[0])) == pytest.approx(SMOOTH_PEAK_RATE / 4, rel=1e-9)
    acc = np.gradient(rates[0], tau)
    assert np.max(np.abs(acc)) == pytest.approx(SMOOTH_PEAK_ACCEL / 16, rel=1e-6)
    t = smooth_time(np.array([1.0, 0, 0, 0, 0, 0]), np.full(6, 2.0), np.full(6, 0.5))
    assert t == pytest.approx(max(SMOOTH_PEAK_RATE / 2, math.sqrt(SMOOTH_PEAK_ACCEL / 0.5)))
