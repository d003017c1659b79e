"""Strapdown navigation from pulses (estimators/strapdown.py).

References: the exact turntable kinematics of sim/motion/kinematics.py (closed-form integrals, checked
against quadrature in test_motion.py). The rotation helpers are tested in test_frames.py.
"""

from __future__ import annotations


import numpy as np
import pytest

from _turntable_pulses import SITE, nominal, random_truth, window
from rlgsim.estimators.kalman_calibration import initial_attitude, motion_breaks
from rlgsim.estimators import strapdown
from rlgsim.estimators.strapdown import SensorModel, coarse_level, navigate
from rlgsim.ground import earth, frames
from rlgsim.ground.frames import body_to_enu as table_attitude
from rlgsim.ground.frames import rotation_matrix
from rlgsim.ground.units import ARCSEC
from rlgsim.sim.motion import kinematics as motion
from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.turntable import Hold, Rotate, Spin, TurntableProgram


def test_site_model_and_table_convention_are_the_simulators():
    """Written once (rlgsim.ground): the navigation and the simulator share the functions."""
    assert strapdown.normal_gravity is earth.normal_gravity
    assert strapdown.earth_rate_enu is earth.earth_rate_enu
    assert strapdown.table_attitude is frames.body_to_enu is motion.body_to_enu
    for lat, h in ((34.0, 0.0), (-60.0, 1200.0), (90.0, 0.0)):
        s = Site(lat, h)
        assert s.gravity == strapdown.normal_gravity(lat, h)
        np.testing.assert_array_equal(s.earth_rate_enu, strapdown.earth_rate_enu(lat))


def test_compensation_inverts_the_pulse_model():
    rng = np.random.default_rng(1)
    m = random_truth(rng, sf_ppm=300.0, asf_ppm=500.0, mis_arcsec=60.0)
    dth = rng.normal(size=(1000, 3)) * 1e-3
    dv = rng.normal(size=(1000, 3)) * 0.1
    ng, na = m.pulses(dth, dv, 0.01)
    th2, dv2 = m.compensate(ng, na, 0.01)
    np.testing.assert_allclose(th2, dth, rtol=0, atol=1e-16)
    np.testing.assert_allclose(dv2, dv, rtol=0, atol=1e-15)
    # the compiled pass is the formula's arithmetic in numpy, term by term, bit for bit
    y_g = ng * (1.0 / m.k_g) - m.d_g * 0.01
    k_a = np.where(na >= 0, 1.0 / m.k_a_pos, 1.0 / m.k_a_neg)
    y_a = na * k_a - m.d_a * 0.01
    for got, y, e in ((th2, y_g, np.linalg.inv(m.e_g)), (dv2, y_a, np.linalg.inv(m.e_a))):
        np.testing.assert_array_equal(got, y[:, :1] * e[:, 0] + y[:, 1:2] * e[:, 1]
                                      + y[:, 2:] * e[:, 2])
    # K_a⁺ and K_a⁻ are really used according to the sign
    assert not np.allclose(m.k_a_pos, m.k_a_neg)
    with pytest.raises(ValueError, match="k_g"):
        SensorModel(k_g=[1, 0, 1], k_a_pos=[1, 1, 1], k_a_neg=[1, 1, 1])


def test_error_free_navigation_holds_velocity_over_a_calibration_window():
    """Error-free device, noise off: the 40-min 19-position window navigates to < 1e-6 m/s."""
    truth = random_truth(np.random.default_rng(2))
    ng, na, motions, blk = window(truth)                    # real-valued pulses, no noise
    dth, dv = truth.compensate(ng, na, 0.01)
    nav = navigate(dth, dv, 0.01, table_attitude(0.0, 0.0), SITE.latitude_deg,
                   breaks=motion_breaks(motions, 100.0, len(dth)))
    assert np.abs(nav.v).max() < 1e-6
    idx = np.arange(0, len(dth), 997)
    err = np.einsum("nji,njk->nik", nav.attitude(idx), blk.attitude()[idx]) - np.eye(3)
    assert np.abs(err).max() < 1e-10                         # rad


def test_static_and_continuous_rotation_navigation():
    truth = nominal()
    for prog, dur in ((TurntableProgram.static(30.0, 200.0), 3600.0),
                      (TurntableProgram([Hold(5.0), Spin("outer", 20.0, 180.0), Hold(5.0)],
                                        start_inner_deg=30.0), 190.0)):
        ng, na, motions, blk = window(truth, prog, duration_s=dur)
        dth, dv = truth.compensate(ng, na, 0.01)
        c0 = table_attitude(prog.start_outer_deg, prog.start_inner_deg)
        nav = navigate(dth, dv, 0.01, c0, SITE.latitude_deg,
                       breaks=motion_breaks(motions, 100.0, len(dth)))
        assert np.abs(nav.v).max() < 1e-6


def test_coarse_levelling_and_initial_attitude():
    c_true = table_attitude(90.0, 270.0)
    tilt = rotation_matrix(np.array([20.0, -35.0, 0.0]) * ARCSEC)
    f_b = (tilt @ c_true).T @ np.array([0.0, 0.0, 9.8])    # what a tilted IMU would sense
    c = coarse_level(c_true, f_b)
    np.testing.assert_allclose(c @ f_b / np.linalg.norm(f_b), [0, 0, 1], atol=1e-15)
    # heading (the table's) kept: the levelled x axis stays in the commanded vertical plane
    assert abs(np.cross(c[:, 0], c_true[:, 0]) @ np.array([0, 0, 1.0])) < 1e-9
    # from pulses: the first dwell's mean specific force levels the commanded attitude
    truth = random_truth(np.random.default_rng(4), abias_ug=0.0, mis_arcsec=0.0)
    prog = TurntableProgram([Hold(60.0), Rotate("outer", 90.0)])
    ng, na, motions, _ = window(truth, prog)
    _, dv = truth.compensate(ng, na, 0.01)
    np.testing.assert_allclose(initial_attitude(motions, dv, 100.0, 30.0),
                               table_attitude(0.0, 0.0), atol=1e-12)


def _navigate_numpy(dtheta, dv, dt_s, c0, latitude_deg, breaks):
    """The vectorised numpy formulation navigate() had before its compiled loop (blocked
    quaternion scan, rotation helpers of rlgsim.ground.frames): the reference it must equal."""
    n = dtheta.shape[0]
    w_ie = earth.earth_rate_enu(latitude_deg)
    g = earth.normal_gravity(latitude_deg, 0.0)
    prev = np.empty_like(dtheta)
    prev[0] = dtheta[0]
    prev[1:] = dtheta[:-1]
    b = np.asarray(breaks, dtype=np.intp)
    prev[b[(b > 0) & (b < n)]] = dtheta[b[(b > 0) & (b < n)]]
    q = frames.quat_from_rotvec(dtheta + frames.cross_rows(prev, dtheta) / 12.0)
    q[0] = frames.quat_mul(frames.dcm_to_quat(c0), q[0])
    q_bi = frames.quat_cumprod(q)
    t = (np.arange(n) + 1.0) * dt_s
    a_dv = frames.cross_rows(dtheta, dv)
    dV = dv + 0.5 * a_dv + frames.cross_rows(dtheta, a_dv) / 12.0
    q_start = np.empty_like(q_bi)
    q_start[0] = frames.dcm_to_quat(c0)
    q_start[1:] = q_bi[:-1]
    dv_n = frames.rotate_about(-w_ie, t - 0.5 * dt_s, frames.quat_rotate(q_start, dV))
    dv_n[:, 2] -= g * dt_s
    return q_bi, np.cumsum(dv_n, axis=0)


def test_compiled_navigation_equals_the_numpy_formulation():
    """A 40-min calibration window (rotations, rate steps, coning breaks): the compiled loop
    gives the numpy formulation's attitude and velocity to rounding after 240 000 samples:
    quaternions 1e-11 (4e-6 arcsec; the sequential product rounds like eps·n, the blocked scan
    like eps·√n), velocity 1e-7 m/s (g times that attitude difference over 40 min; 1 % of the
    calibration's velocity measurement σ ~1e-5 m/s, on an uncalibrated velocity of ~1.5 m/s)."""
    truth = random_truth(np.random.default_rng(5))
    ng, na, motions, _ = window(truth, TurntableProgram.calibration19(), seed=3)
    dth, dv = nominal().compensate(ng, na, 0.01)
    c0 = initial_attitude(motions, dv, 100.0, 60.0)
    br = motion_breaks(motions, 100.0, dth.shape[0])
    nav = navigate(dth, dv, 0.01, c0, SITE.latitude_deg, breaks=br)
    q_ref, v_ref = _navigate_numpy(dth, dv, 0.01, c0, SITE.latitude_deg, br)
    sign = np.sign(np.sum(nav.q_bi * q_ref, axis=1))[:, None]      # q and −q are one rotation
    np.testing.assert_allclose(nav.q_bi * sign, q_ref, rtol=0, atol=1e-11)
    np.testing.assert_allclose(nav.v, v_ref, rtol=0, atol=1e-7)
    assert np.max(np.abs(nav.v)) > 1e-4            # the window's velocity error is not trivial
