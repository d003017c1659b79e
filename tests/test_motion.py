"""Site, turntable programmes and exact kinematics (sim/motion/site.py, sim/motion/turntable.py, sim/motion/kinematics.py).

References: numerical quadrature (scipy.integrate.quad) of the rate and specific force written
directly from the gimbal angles (not from the Rodrigues closed form under test), the GRS-80
series formula for normal gravity, and closed-form totals for full turns and static mounts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from rlgsim.ground.earth import normal_gravity
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import body_to_enu
from rlgsim.ground.units import DEG, EARTH_RATE
from rlgsim.sim.config import Ctx
from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.kinematics import Motion, TurntableSegment, segments_from_program
from rlgsim.sim.motion.turntable import TableMotion, TurntableProgram, Rotate, Hold, Spin

SITE = Site()


def fsum0(x: np.ndarray) -> np.ndarray:
    """Exactly rounded column sums (numpy's axis-0 sum is naive, error ~ n·eps)."""
    return np.array([math.fsum(col) for col in np.asarray(x).T])


def truth_rates(motion: Motion, t: float) -> tuple[np.ndarray, np.ndarray]:
    """ω_ib^b and f^b at time t from the angles: C = R_x(o) R_z(i), ω_nb^b from the axis."""
    o, i, j = motion.angles(np.array([t]))
    c = body_to_enu(o[0], i[0])
    seg = min(int(np.searchsorted(motion._t0, t, side="right") - 1), motion._m - 1)
    rate = motion._rate[seg]
    axis = motion._axis[seg]
    if axis == "outer":
        u = np.array([math.cos(i[0] * DEG), -math.sin(i[0] * DEG), 0.0])
    elif axis == "inner":
        u = np.array([0.0, 0.0, 1.0])
    else:
        u = np.zeros(3)
    return rate * u + c.T @ SITE.earth_rate_enu, c.T @ SITE.specific_force_enu


def quad_increment(motion: Motion, a: float, b: float, breaks=()) -> tuple[np.ndarray, np.ndarray]:
    pts = [p for p in breaks if a < p < b]
    out_w, out_f = np.zeros(3), np.zeros(3)
    for c in range(3):
        out_w[c] = quad(lambda t: truth_rates(motion, t)[0][c], a, b, points=pts or None,
                        epsabs=1e-15, epsrel=1e-13, limit=200)[0]
        out_f[c] = quad(lambda t: truth_rates(motion, t)[1][c], a, b, points=pts or None,
                        epsabs=1e-14, epsrel=1e-13, limit=200)[0]
    return out_w, out_f


# ------------------------------------------------------------------------------------- site

def test_site_earth_rate_and_gravity():
    s = Site(34.0, 0.0)
    lat = 34.0 * DEG
    np.testing.assert_allclose(s.earth_rate_enu, [0, EARTH_RATE * math.cos(lat),
                                                  EARTH_RATE * math.sin(lat)], rtol=0, atol=1e-20)
    # GRS-80 series form (Moritz 1980); GRS-80 γ_e exceeds WGS-84 by 1.4e-6 m/s², series ~1e-6
    series = 9.780327 * (1 + 0.0053024 * math.sin(lat) ** 2 - 0.0000058 * math.sin(2 * lat) ** 2)
    assert abs(s.gravity - series) < 4e-6
    np.testing.assert_array_equal(s.gravity_enu, [0, 0, -s.gravity])
    # free-air gradient ≈ −3.086e-6 m/s² per m
    assert normal_gravity(34.0, 1000.0) - normal_gravity(34.0, 0.0) == pytest.approx(-3.086e-3,
                                                                                      rel=3e-3)
    assert normal_gravity(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert normal_gravity(90.0) == pytest.approx(9.8321849378, abs=1e-9)


def test_site_from_config_errors():
    assert Site.from_config(None, Ctx("s.toml", "site")) == Site()
    with pytest.raises(UserInputError, match="latitude_deg"):
        Site.from_config({"latitude_deg": 95.0}, Ctx("s.toml", "site"))
    with pytest.raises(UserInputError, match="did you mean 'height_m'"):
        Site.from_config({"heigth_m": 5.0}, Ctx("s.toml", "site"))


# -------------------------------------------------------------------------------- turntable

def test_calibration_sequence_duration_positions_and_coverage():
    p = TurntableProgram.calibration19()
    assert p.duration_s == 2400.0 and p.continuous and p.calibration
    ms = list(p.motions(until_s=p.duration_s))
    static = [m for m in ms if m.kind == "static"]
    turns = [m for m in ms if m.kind == "rotate"]
    assert len(static) == 19 and len(turns) == 18
    assert [m.position for m in static] == list(range(1, 20))
    assert all(abs(abs(m.angle_deg) - 90.0) < 1e-12 and abs(m.rate_deg_s) == 20.0 for m in turns)
    assert sum(m.duration_s for m in ms) == 2400.0
    assert {m.window for m in ms} == {0}
    # each body axis points up and down at some dwell; every turn is about a horizontal axis
    # except none: check turns about each body axis with the axis horizontal
    up = set()
    turned = set()
    for m in static:
        col = body_to_enu(m.outer_deg, m.inner_deg)[2]     # Up in body components
        k = int(np.argmax(np.abs(col)))
        up.add((k, np.sign(col[k])))
    for m in turns:
        c = body_to_enu(m.outer_deg, m.inner_deg)
        u = np.array([math.cos(m.inner_deg * DEG), -math.sin(m.inner_deg * DEG), 0.0]) \
            if m.axis == "outer" else np.array([0.0, 0.0, 1.0])
        assert abs((c @ u)[2]) < 1e-12                     # rotation axis horizontal
        turned.add(int(np.argmax(np.abs(u))))
    assert up == {(k, s) for k in range(3) for s in (-1.0, 1.0)}
    assert turned == {0, 1, 2}
    # ends where it starts, so repetitions join
    last = ms[-1]
    assert (last.outer_deg, last.inner_deg) == (0.0, 0.0)


def test_continuous_repetition_labels_and_cut():
    p = TurntableProgram.calibration19()
    ms = list(p.motions(until_s=3 * 2400.0 + 100.0))
    assert [m.window for m in ms if m.position == 1 and m.kind == "static"] == [0, 1, 2, 3]
    assert ms[-1].duration_s == 100.0 and ms[-1].window == 3 and ms[-1].label == "P01"
    assert sum(m.duration_s for m in ms) == pytest.approx(3 * 2400.0 + 100.0, abs=1e-9)
    assert all(m.continuous for m in ms)
    it = p.motions()                                       # endless without until_s
    assert sum(1 for _, m in zip(range(500), it)) == 500
    # kinds and labels line up
    for m in ms:
        assert (m.kind == "static") == (m.axis is None) == (m.rate_deg_s == 0.0)
        assert m.label.startswith("P" if m.kind == "static" else "R")


def test_static_program_and_custom_config():
    s = TurntableProgram.static(90.0, 45.0)
    (m,) = list(s.motions())
    assert m == TableMotion(math.inf, "static", None, 0.0, 90.0, 45.0, "static", 1, None, False)
    assert list(s.motions(until_s=10.0))[0].duration_s == 10.0
    ctx = Ctx("sc.toml", "turntable")
    p = TurntableProgram.from_config({
        "program": "custom", "outer_deg": 0, "inner_deg": 0, "continuous": True,
        "calibration": True,
        "motions": [{"type": "hold", "duration_s": 10},
                    {"type": "repeat", "count": 2,
                     "motions": [{"type": "rotate", "axis": "inner", "angle_deg": 180},
                                 {"type": "hold", "duration_s": 5, "label": "half"}]},
                    {"type": "continuous", "axis": "outer", "rate_deg_s": -10,
                     "duration_s": 36}]}, ctx)
    ms = list(p.motions(until_s=p.duration_s))
    assert p.duration_s == 10 + 2 * (9 + 5) + 36
    assert [m.kind for m in ms] == ["static", "rotate", "static", "rotate", "static", "rotate"]
    assert [m.position for m in ms] == [1, 1, 2, 2, 3, 3]
    assert ms[2].label == "half" and ms[2].inner_deg == 180.0 and ms[4].inner_deg == 0.0
    assert ms[5].angle_deg == -360.0
    assert TurntableProgram.from_config({"program": "calibration19", "dwell_s": 60},
                                        ctx).duration_s == 159 + 18 * 64.5
    assert TurntableProgram.from_config(None, ctx).name == "static"


@pytest.mark.parametrize("table, match", [
    ({"program": "calibraton19"}, "did you mean 'calibration19'"),
    ({"program": "static", "dwell_s": 5}, "not used by program"),
    ({"program": "custom", "motions": [{"type": "rotate", "axis": "middle", "angle_deg": 9}]},
     "axis"),
    ({"program": "custom", "continuous": True,
      "motions": [{"type": "rotate", "axis": "inner", "angle_deg": 90}]}, "end where it starts"),
    ({"program": "custom", "motions": [{"type": "hold"}, {"type": "hold", "duration_s": 1}]},
     "only the last motion"),
    ({"program": "custom", "motions": [{"type": "hold", "duraton_s": 1}]}, "did you mean"),
    ({"program": "calibration19", "rate_deg_s": 0}, "rate_deg_s"),
])
def test_turntable_config_errors(table, match):
    with pytest.raises(UserInputError, match=match):
        TurntableProgram.from_config(table, Ctx("sc.toml", "turntable"))


# ----------------------------------------------------------------------------------- motion

def _custom(steps, start=(0.0, 0.0), duration=None):
    p = TurntableProgram(steps, start_outer_deg=start[0], start_inner_deg=start[1])
    return Motion(segments_from_program(p, duration or p.duration_s), SITE)


def test_increments_match_quadrature_inside_segments():
    # outer turn at inner = 30° (body axis (cos30, −sin30, 0)), then an inner turn, then static
    mo = _custom([Rotate("outer", 135.0, 20.0), Rotate("inner", -70.0, 15.0), Hold(10.0)],
                 start=(10.0, 30.0))
    rate = 50.0
    for t0 in (0.0, 1.0, 6.72, 8.0, 9.5, 20.0):
        blk = mo.increments(t0, 3, rate)
        for k in range(3):
            a = t0 + k / rate
            w, f = quad_increment(mo, a, a + 1 / rate)
            np.testing.assert_allclose(blk.dtheta_rad[k], w, rtol=0, atol=1e-14)
            np.testing.assert_allclose(blk.dv_m_per_s[k], f, rtol=0, atol=1e-13)


def test_increments_split_exactly_at_segment_boundaries():
    # 7 Hz: the boundaries at 4.5 s, 8.5 s and 8.5 + 70/15 s fall inside sample intervals
    mo = _custom([Rotate("outer", 90.0, 20.0), Rotate("inner", 80.0, 20.0),
                  Rotate("inner", -70.0, 15.0), Hold(5.0)], start=(0.0, 90.0))
    rate = 7.0
    bounds = mo._t0[1:-1]
    blk = mo.increments(0.0, int(19 * rate), rate)
    straddle = 0
    for k in range(blk.dtheta_rad.shape[0]):
        a, b = k / rate, (k + 1) / rate
        if any(a < p < b for p in bounds):
            straddle += 1
            w, f = quad_increment(mo, a, b, breaks=bounds)
            np.testing.assert_allclose(blk.dtheta_rad[k], w, rtol=0, atol=2e-14)
            np.testing.assert_allclose(blk.dv_m_per_s[k], f, rtol=0, atol=2e-13)
    assert straddle == 3
    # the naive rate×Δt at the sample end would be wrong by far more than that
    k = int(4.5 * rate)
    naive = truth_rates(mo, (k + 1) / rate)[0] / rate
    assert np.abs(naive - blk.dtheta_rad[k]).max() > 1e-3


def test_full_turn_sums_to_two_pi_plus_earth():
    for axis, start in (("outer", (0.0, 40.0)), ("inner", (90.0, 0.0))):
        mo = _custom([Spin(axis, 20.0, 18.0)], start=start)          # 360° in 18 s
        blk = mo.increments(0.0, 1800, 100.0)
        u = (np.array([math.cos(start[1] * DEG), -math.sin(start[1] * DEG), 0.0])
             if axis == "outer" else np.array([0.0, 0.0, 1.0]))
        earth = np.array([quad(lambda t: (mo.attitude(np.array([t]))[0].T
                                          @ SITE.earth_rate_enu)[c], 0, 18.0,
                               epsabs=1e-16, epsrel=1e-14, limit=200)[0] for c in range(3)])
        np.testing.assert_allclose(fsum0(blk.dtheta_rad), 2 * math.pi * u + earth, rtol=0,
                                   atol=1e-12)
        # specific force averages out over a full turn about a horizontal axis except along it
        c0 = body_to_enu(*start)
        g_along = (c0.T @ SITE.specific_force_enu) @ u * 18.0
        np.testing.assert_allclose(fsum0(blk.dv_m_per_s), g_along * u, rtol=0, atol=1e-11)
        # chunking does not change the bytes' sums beyond rounding, and the angles return
        blk2 = [mo.increments(t, 450, 100.0) for t in (0.0, 4.5, 9.0, 13.5)]
        np.testing.assert_allclose(np.concatenate([b.dtheta_rad for b in blk2]), blk.dtheta_rad,
                                   rtol=0, atol=1e-15)
        assert blk.outer_deg[-1] % 360 == pytest.approx(start[0], abs=1e-9)
        assert blk.inner_deg[-1] % 360 == pytest.approx(start[1], abs=1e-9)


@pytest.mark.parametrize("outer, inner", [(0.0, 0.0), (90.0, 270.0), (37.0, -123.0)])
def test_static_sums(outer, inner):
    mo = Motion(segments_from_program(TurntableProgram.static(outer, inner), 1000.0), SITE)
    blk = mo.increments(0.0, 100000, 100.0)
    c = body_to_enu(outer, inner)
    T = 1000.0
    np.testing.assert_allclose(fsum0(blk.dtheta_rad), c.T @ SITE.earth_rate_enu * T, rtol=1e-13,
                               atol=1e-16)
    np.testing.assert_allclose(fsum0(blk.dv_m_per_s), -(c.T @ SITE.gravity_enu) * T, rtol=1e-13,
                               atol=1e-12)
    np.testing.assert_allclose(blk.attitude()[-1], c, atol=1e-15)
    # beyond the end of the timeline the table holds its last angles
    late = mo.increments(2000.0, 10, 100.0)
    np.testing.assert_allclose(late.dv_m_per_s, np.tile(-(c.T @ SITE.gravity_enu) / 100, (10, 1)),
                               rtol=1e-13)


def test_calibration_window_labels_and_attitude():
    p = TurntableProgram.calibration19()
    segs = segments_from_program(p, 2 * 2400.0)
    mo = Motion(segs, SITE)
    blk = mo.increments(0.0, 2 * 2400 * 10, 10.0)
    # the sample ending at t belongs to the segment that contains (t − ε)
    t0 = np.array([s.t0_s for s in segs])
    expect = np.searchsorted(t0, blk.t_s, side="left") - 1
    np.testing.assert_array_equal(blk.segment, expect)
    windows = np.array([segs[j].attrs["window"] for j in blk.segment])
    assert (windows[blk.t_s <= 2400.0] == 0).all() and (windows[blk.t_s > 2400.0] == 1).all()
    # attitude at each dwell's end equals the commanded angles
    for s in segs[:37:2]:
        k = int(round(s.t1_s * 10)) - 1
        np.testing.assert_allclose(blk.attitude()[k],
                                   body_to_enu(s.attrs["outer_deg"], s.attrs["inner_deg"]),
                                   atol=1e-12)
    # integrated attitude: propagate C with the exact increments minus Earth (table rate only)
    # over the first turn and compare with the commanded end attitude
    from scipy.spatial.transform import Rotation
    k0, k1 = int(159.0 * 10), int(163.5 * 10)
    c = body_to_enu(0.0, 0.0)
    earth_n = Rotation.from_rotvec(SITE.earth_rate_enu / 10.0).as_matrix()
    for k in range(k0, k1):
        # C_{k+1} = R_n(ω_ie Δt)^T C_k R_b(Δθ_k)  (rotation-vector update; its non-commutativity
        # error is ~Δt²·w·Ω/12 per step, 1e-8 rad over the turn)
        c = earth_n.T @ c @ Rotation.from_rotvec(blk.dtheta_rad[k]).as_matrix()
    np.testing.assert_allclose(c, body_to_enu(90.0, 0.0), atol=3e-8)


def test_motion_rejects_inconsistent_segments():
    good = dict(kind="static", axis=None, rate_deg_s=0.0, outer_deg=0.0, inner_deg=0.0)
    with pytest.raises(ValueError, match="not contiguous"):
        Motion([TurntableSegment(0, 10, "turntable", "a", good),
                TurntableSegment(11, 20, "turntable", "b", good)], SITE)
    with pytest.raises(ValueError, match="starts at outer"):
        Motion([TurntableSegment(0, 10, "turntable", "a", good),
                TurntableSegment(10, 20, "turntable", "b", {**good, "outer_deg": 90.0})], SITE)
    mo = Motion([TurntableSegment(0, 10, "turntable", "a", {"kind": "static"}),
                 TurntableSegment(0, 10, "chamber", "x", {})], SITE)   # other tracks skipped
    np.testing.assert_allclose(mo.increments(0.0, 2, 100.0).dv_m_per_s[:, 2], SITE.gravity / 100)
    with pytest.raises(ValueError, match="sample grid"):
        mo.increments(0.005, 3, 100.0)


def test_lead_in_then_continuous_calibration():
    ctx = Ctx("sc.toml", "turntable")
    p = TurntableProgram.from_config({"program": "calibration19", "lead_in_h": 4}, ctx)
    ms = list(p.motions(until_s=4 * 3600 + 175 * 2400.0))
    assert ms[0].label == "lead-in" and ms[0].window is None and ms[0].duration_s == 14400.0
    assert ms[0].kind == "static" and ms[0].position == 0
    windows = {m.window for m in ms[1:]}
    assert windows == set(range(175))
    assert ms[-1].window == 174 and ms[-1].duration_s == 120.0     # the last window is whole
    with pytest.raises(UserInputError, match="only one of"):
        TurntableProgram.from_config({"program": "calibration19", "lead_in_h": 4,
                                      "lead_in_s": 5}, ctx)
    mo = Motion(segments_from_program(p, 14500.0), SITE)
    assert mo.angles(np.array([14399.0]))[0][0] == 0.0
