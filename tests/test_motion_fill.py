"""Motion.increments (samples at rest filled with one product, turning motions and straddling
samples computed over windows) against the whole-block computation it replaced, bit for bit:
random blocks of several programmes — the shipped calibration programme, turns shorter than a
sample, zero-length motions, boundaries on and between sample edges, blocks before the first
and after the last motion — at rates from 0.1 to 1000 Hz."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.kinematics import Motion, TurntableSegment, segments_from_program
from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.schedule import build_timeline
from rlgsim.sim.motion.turntable import Hold, Rotate, TurntableProgram

SITE = Site(latitude_deg=39.9, height_m=50.0)


def whole_block(mo: Motion, t0_s: float, n: int, rate_hz: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The previous Motion.increments, verbatim (every sample interval split at the motion
    boundaries, each run of pieces in one motion integrated, pieces summed by reduceat); returns
    (Δθ, Δv, t_s)."""
    k0 = round(t0_s * rate_hz)
    edges = (k0 + np.arange(n + 1, dtype=float)) / rate_hz
    inside = mo._t0[(mo._t0 > edges[0]) & (mo._t0 < edges[-1])]
    if inside.size:
        pos = np.searchsorted(edges, inside)
        inside = inside[edges[pos] != inside]
        where = np.searchsorted(edges, inside)
        pts = np.insert(edges, where, inside)
        is_edge = np.insert(np.ones(n + 1, dtype=bool), where, False)
    else:
        pts = edges
        is_edge = None
    a, b = pts[:-1], pts[1:]
    delta = np.full(a.size, 1.0 / rate_hz)
    if is_edge is not None:
        split = ~(is_edge[:-1] & is_edge[1:])
        delta[split] = b[split] - a[split]
    dth = np.empty((3, a.size)).T
    dv = np.empty((3, a.size)).T
    for lo, hi, j in mo._runs(a):
        mo._integrate(j, a[lo:hi], delta[lo:hi], dth[lo:hi], dv[lo:hi])
    if inside.size:
        first = np.searchsorted(pts[:-1], edges[:-1])
        dth = np.add.reduceat(dth, first, axis=0)
        dv = np.add.reduceat(dv, first, axis=0)
    return dth, dv, edges[1:]


def same_bits(x: np.ndarray, y: np.ndarray) -> bool:
    x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
    return x.shape == y.shape and np.array_equal(x.view(np.int64), y.view(np.int64))


def _programmes() -> dict[str, Motion]:
    sc = load_scenario("paper000_short")
    tl = build_timeline(sc)
    out = {"paper000_short": Motion(tl.segments, sc.site)}
    short = TurntableProgram([Hold(3.0), Rotate("outer", 90.0, 20.0), Hold(0.013),
                              Rotate("inner", 0.5, 20.0), Rotate("inner", -45.0, 15.0),
                              Hold(7.25), Rotate("outer", -90.0, 40.0), Hold(1.0)],
                             start_outer_deg=10.0, start_inner_deg=30.0)
    out["short turns"] = Motion(segments_from_program(short, short.duration_s), SITE)
    static = dict(kind="static", axis=None, rate_deg_s=0.0, outer_deg=0.0, inner_deg=0.0)
    turn = dict(kind="rotate", axis="inner", rate_deg_s=10.0, outer_deg=0.0, inner_deg=0.0)
    out["zero-length motions"] = Motion([
        TurntableSegment(0.0, 2.0, "turntable", "a", static),
        TurntableSegment(2.0, 2.0, "turntable", "b", static),
        TurntableSegment(2.0, 2.5, "turntable", "c", turn),
        TurntableSegment(2.5, 2.5, "turntable", "d", {**turn, "inner_deg": 5.0}),
        TurntableSegment(2.5, 4.0, "turntable", "e", {**static, "inner_deg": 5.0}),
        TurntableSegment(4.0, 4.1, "turntable", "f", {**turn, "inner_deg": 5.0}),
        TurntableSegment(4.1, 9.0, "turntable", "g", {**static, "inner_deg": 6.0})], SITE)
    return out


PROGRAMMES = _programmes()


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("name", list(PROGRAMMES))
@pytest.mark.parametrize("rate_hz", [100.0, 73.0, 7.3, 1000.0, 0.1])
def test_increments_are_the_whole_block_computation(name, rate_hz, compiled, monkeypatch):
    """... with the windows computed by NumPy (Motion._exact) and by the compiled kernel
    (sim/motion/_kinematics_kernel.py)."""
    mo = PROGRAMMES[name]
    monkeypatch.setattr(mo, "compiled", compiled)
    if compiled:
        from rlgsim.sim.motion.kinematics import _compiled_window
        assert _compiled_window() is not None          # it agreed with NumPy's here
    rng = np.random.default_rng([zlib.crc32(name.encode()), int(rate_hz * 10)])
    t_end = mo.end_s
    blocks = 0
    for _ in range(60):
        # on the grid, from just before the first motion (within its tolerance) to past the end
        k0 = int(rng.integers(0, int(t_end * rate_hz * 1.1) + 2))
        n = int(rng.choice([1, 2, 3, 17, 450, int(rng.integers(1, 5000))]))
        t0 = k0 / rate_hz
        got = mo.increments(t0, n, rate_hz)
        dth, dv, t_s = whole_block(mo, t0, n, rate_hz)
        assert same_bits(got.dtheta_rad, dth) and same_bits(got.dv_m_per_s, dv)
        assert same_bits(got.t_s, t_s)
        # the table where each sample ends, as before
        o, i, seg = mo.angles(t_s)
        assert same_bits(got.outer_deg, o) and same_bits(got.inner_deg, i)
        np.testing.assert_array_equal(got.segment, seg)
        # the runs it calls constant hold one increment
        for lo, hi in got.constant:
            assert same_bits(got.dtheta_rad[lo:hi], np.repeat(dth[lo:lo + 1], hi - lo, axis=0))
            assert same_bits(got.dv_m_per_s[lo:hi], np.repeat(dv[lo:lo + 1], hi - lo, axis=0))
        blocks += 1
    assert blocks == 60


def test_blocks_of_the_paper000_programme_are_mostly_filled():
    mo = PROGRAMMES["paper000_short"]
    blk = mo.increments(4200.0, 60_000, 100.0, angles=False)
    held = sum(hi - lo for lo, hi in blk.constant)
    assert 0.9 * 60_000 < held < 60_000
    assert blk.outer_deg is None
    dth, _, t_s = whole_block(mo, 4200.0, 60_000, 100.0)
    assert same_bits(blk.dtheta_rad, dth)
    j = np.array([0, 5, 59_999])
    assert same_bits(blk.end_times(j), t_s[j])


def test_first_edge_at_is_searchsorted():
    rng = np.random.default_rng(3)
    for rate in (100.0, 73.0, 7.3, 0.1, 1000.0, 1 / 3):
        k0, n = int(rng.integers(0, 10**9)), int(rng.integers(1, 1000))
        edges = (k0 + np.arange(n + 1, dtype=float)) / rate
        t = np.concatenate([rng.uniform(edges[0], edges[-1], 50), edges[1:-1][:20],
                            np.nextafter(edges[1:-1][:20], np.inf),
                            np.nextafter(edges[1:-1][:20], -np.inf)])
        t = np.sort(t[(t > edges[0]) & (t < edges[-1])])
        np.testing.assert_array_equal(Motion._first_edge_at(t, k0, n, rate),
                                      np.searchsorted(edges, t))


def test_held_steps_leave_only_whole_steps_after_a_runs_first_unwritten():
    """``held_steps`` = r: every sample outside :attr:`MotionBlock.unwritten` is the full
    block's, and each unwritten run lies in a constant run after its first whole step."""
    mo = PROGRAMMES["paper000_short"]
    full = mo.increments(4200.0, 60_000, 100.0, angles=False)
    for r in (500, 100, 7):
        got = mo.increments(4200.0, 60_000, 100.0, angles=False, held_steps=r)
        assert got.constant == full.constant and got.unwritten
        written = np.ones(60_000, dtype=bool)
        for lo, hi in got.unwritten:
            assert lo % r == 0 and hi % r == 0 and hi > lo
            assert any(c0 + r <= lo and hi <= c1 for c0, c1 in got.constant)
            written[lo:hi] = False
        assert 0.8 * 60_000 < (~written).sum()
        assert same_bits(got.dtheta_rad[written], full.dtheta_rad[written])
        assert same_bits(got.dv_m_per_s[written], full.dv_m_per_s[written])
