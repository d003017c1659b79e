"""The simpy timeline: segments per track, events on the thermal grid, few simpy events."""

from __future__ import annotations

import numpy as np
import pytest
import simpy

from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.schedule import PiecewiseConstant, TRACKS, build_timeline

from scenario_helpers import quickstart, scenario



def _with(**tables: dict):
    """The quickstart scenario with tables updated."""
    d = quickstart()
    for name, body in tables.items():
        d.setdefault(name, {}).update(body)
    return scenario(d)


def test_piecewise_constant():
    p = PiecewiseConstant([0.0, 10.0, 20.0], [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(p([0.0, 9.99, 10.0, 15.0, 20.0, 1e9]), [0, 0, 1, 1, 0, 0])
    with pytest.raises(ValueError):
        PiecewiseConstant([0.0, 0.0], [1.0, 0.0])


def test_quickstart_timeline_tracks_and_chamber_segments():
    sc = load_scenario("quickstart")
    tl = build_timeline(sc)
    assert tl.duration_s == 7200.0 and tl.n_steps == 7200
    assert {s.track for s in tl.segments} >= {"chamber", "power", "turntable", "acquisition"}
    assert [s.track for s in tl.segments] == sorted((s.track for s in tl.segments),
                                                    key=TRACKS.index)
    chamber = tl.track("chamber")
    kinds = [s.attrs["kind"] for s in chamber]
    assert kinds == ["hold", "ramp", "hold", "ramp", "hold"]
    # 15 min hold, 20 min ramp to 40 °C at 1 °C/min, 45 min hold, 20 min back, then hold
    np.testing.assert_allclose([s.t0_s for s in chamber], [0, 900, 2100, 4800, 6000])
    assert chamber[-1].t1_s == 7200.0
    assert chamber[1].attrs["rate_c_per_min"] == pytest.approx(1.0)
    assert chamber[3].attrs["rate_c_per_min"] == pytest.approx(-1.0)
    # segments of a track tile [0, duration]
    for track in ("chamber", "power", "turntable", "acquisition"):
        segs = tl.track(track)
        assert segs[0].t0_s == 0.0 and segs[-1].t1_s == tl.duration_s
        assert all(a.t1_s == b.t0_s for a, b in zip(segs, segs[1:]))
    # the setpoint follows the programme
    np.testing.assert_allclose(tl.setpoint(np.array([0.0, 900.0, 1500.0, 2100.0, 7200.0])),
                               [20.0, 20.0, 30.0, 40.0, 20.0])


def test_power_events_are_put_on_the_thermal_grid():
    sc = _with(power={"on_at_s": 100.4, "off_at_s": 3000.6})
    tl = build_timeline(sc)
    power = tl.track("power")
    assert [(s.label, s.t0_s, s.t1_s) for s in power] == [
        ("off", 0.0, 100.0), ("on", 100.0, 3001.0), ("off", 3001.0, 7200.0)]
    np.testing.assert_array_equal(tl.power(np.array([99.0, 100.0, 3000.0, 3001.0])),
                                  [0, 1, 1, 0])


def test_thermal_step_grid_and_duration_rounding():
    sc = _with(acquisition={"thermal_step_s": 5})
    tl = build_timeline(sc)
    assert tl.step_s == 5.0 and tl.n_steps == 1440
    assert np.all(np.round(tl.setpoint.t_s / 5.0) * 5.0 == tl.setpoint.t_s)


def test_turntable_programme_gives_calibration_windows():
    sc = _with(turntable={"program": "calibration19"})
    tl = build_timeline(sc)
    windows = tl.track("calibration")
    # 7200 s of back-to-back 2400 s windows
    assert len(windows) == 3
    np.testing.assert_allclose([w.t0_s for w in windows], [0.0, 2400.0, 4800.0])
    assert all(w.attrs["motions"] == 37 for w in windows)
    motions = tl.track("turntable")
    assert len(motions) == 3 * 37
    assert motions[-1].t1_s == pytest.approx(7200.0)


def test_few_simpy_events_never_one_per_sample(monkeypatch):
    count = {"n": 0}
    real_step = simpy.Environment.step

    def counting_step(self):
        count["n"] += 1
        return real_step(self)

    monkeypatch.setattr(simpy.Environment, "step", counting_step)
    sc = load_scenario("quickstart")
    tl = build_timeline(sc)
    n_samples = tl.duration_s * sc.acquisition.sample_rate_hz
    assert 0 < count["n"] < 50 and count["n"] < n_samples / 1000
