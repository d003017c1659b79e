"""Strapdown navigation from pulses (estimators/strapdown.py).

References: the exact turntable kinematics of sim/motion.py (closed-form integrals, checked
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
from rlgsim.sim import motion
from rlgsim.sim.earth import Site
from rlgsim.sim.turntable import Hold, Rotate, Spin, TurntableProgram


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
