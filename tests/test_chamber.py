"""Chamber programmes: segments → setpoint, rate limit, validation of the [chamber] table."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from rlgsim.sim.thermal.chamber import (ChamberProgram, Hold, PiecewiseLinear, RandomProfile, Ramp, Repeat,
                         Step, rate_limit)
from rlgsim.sim.config import Ctx
from rlgsim.ground.errors import UserInputError

CTX = Ctx("scen.toml", "chamber")


def program(segments, **kw) -> ChamberProgram:
    table = {"start_c": kw.pop("start_c", 20.0), "segments": segments, **kw}
    return ChamberProgram.from_config(table, CTX)


# --------------------------------------------------------------------------- piecewise linear


def test_piecewise_linear_interpolates_and_holds_the_ends():
    pl = PiecewiseLinear([0, 10, 20], [1.0, 3.0, 3.0])
    np.testing.assert_allclose(pl([-5, 0, 5, 10, 15, 25]), [1, 1, 2, 3, 3, 3])
    assert pl.end_s == 20.0
    with pytest.raises(ValueError):
        PiecewiseLinear([0, 2, 1], [0, 0, 0])


def test_piecewise_linear_jump_takes_the_later_value():
    pl = PiecewiseLinear([0, 10, 10, 20], [0.0, 0.0, 5.0, 5.0])
    np.testing.assert_allclose(pl([5, 9.999, 10, 15, 30]), [0, 0, 5, 5, 5])


# --------------------------------------------------------------------------- segments


def test_paper_003_cycle_expands_to_the_expected_breakpoints():
    """Paper 003 cycle 1: 20 °C 2 h, 1 °C/min to −40, 2 h, to 60, 2 h, ... back to 20, 2 h."""
    legs = [{"type": "hold", "duration_h": 2}]
    for to in (-40, 60, -40, 60, 20):
        legs += [{"type": "ramp", "to_c": to, "rate_c_per_min": 1.0},
                 {"type": "hold", "duration_h": 2}]
    p = program(legs)
    sp = p.setpoint(None)
    ramp_min = 60 + 100 + 100 + 100 + 40
    assert sp.end_s == pytest.approx((6 * 2 * 60 + ramp_min) * 60)
    assert sp(np.array([2 * 3600 + 30 * 60]))[0] == pytest.approx(-10.0)
    assert sp.max_abs_rate_c_per_min() == pytest.approx(1.0)
    # within the chamber's limit: the rate limit changes nothing
    rl = p.rate_limited(sp)
    t = np.linspace(0, sp.end_s, 5001)
    np.testing.assert_allclose(rl(t), sp(t), atol=1e-9)


def test_ramp_by_duration_and_unit_spellings():
    p = program([{"type": "ramp", "to_c": 30.0, "duration_min": 20},
                 {"type": "hold", "duration_s": 60},
                 {"type": "ramp", "to_c": 10.0, "duration_h": 0.5}])
    sp = p.setpoint()
    np.testing.assert_allclose(sp.t_s, [0, 1200, 1260, 3060])
    np.testing.assert_allclose(sp.y, [20, 30, 30, 10])


def test_repeat_and_cycle_nest():
    inner = [{"type": "ramp", "to_c": 30.0, "rate_c_per_min": 2.0},
             {"type": "ramp", "to_c": 20.0, "rate_c_per_min": 2.0}]
    p = program([{"type": "repeat", "count": 3,
                  "segments": [{"type": "cycle", "count": 2, "segments": inner},
                               {"type": "hold", "duration_min": 10}]}])
    sp = p.setpoint()
    # each inner cycle 10 min; 2 per repeat + 10 min hold; 3 repeats
    assert sp.end_s == pytest.approx(3 * (2 * 10 + 10) * 60)
    assert np.sum(sp.y == 30.0) == 6
    assert isinstance(p.segments[0], Repeat) and isinstance(p.segments[0].segments[0], Repeat)


def test_random_profile_is_seeded_and_within_bounds():
    seg = {"type": "random", "legs": 40, "min_c": -20.0, "max_c": 50.0,
           "min_rate_c_per_min": 0.5, "max_rate_c_per_min": 3.0,
           "min_hold_min": 5, "max_hold_min": 30, "min_change_c": 5.0}
    p = program([seg])
    a = p.setpoint(np.random.default_rng(3))
    b = p.setpoint(np.random.default_rng(3))
    c = p.setpoint(np.random.default_rng(4))
    np.testing.assert_array_equal(a.t_s, b.t_s)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(a.y, c.y)
    assert a.y[1:].min() >= -20.0 and a.y[1:].max() <= 50.0
    dt, dy = np.diff(a.t_s), np.diff(a.y)
    moving = dy != 0
    rates = np.abs(dy[moving] / dt[moving]) * 60
    assert rates.min() >= 0.5 - 1e-9 and rates.max() <= 3.0 + 1e-9
    assert np.all(np.abs(dy[moving]) >= 5.0 - 1e-9)
    holds = dt[~moving] / 60
    assert holds.min() >= 5 - 1e-9 and holds.max() <= 30 + 1e-9
    assert moving.sum() == 40 and (~moving).sum() == 40
    assert isinstance(p.segments[0], RandomProfile)
    with pytest.raises(ValueError):
        p.setpoint(None)


# --------------------------------------------------------------------------- rate limit


def test_step_becomes_a_ramp_at_the_maximum_rate():
    p = program([{"type": "hold", "duration_min": 10}, {"type": "step", "to_c": 40.0},
                 {"type": "hold", "duration_min": 30}], max_rate_c_per_min=4.0)
    sp = p.setpoint()
    assert isinstance(p.segments[1], Step)
    rl = p.rate_limited(sp)
    np.testing.assert_allclose(rl.t_s, [0, 600, 600 + 5 * 60, 600 + 30 * 60])
    np.testing.assert_allclose(rl.y, [20, 20, 40, 40])
    assert rl.max_abs_rate_c_per_min() == pytest.approx(4.0)


def test_fast_ramp_is_slowed_and_the_hold_shortened():
    p = program([{"type": "ramp", "to_c": 80.0, "rate_c_per_min": 20.0},
                 {"type": "hold", "duration_min": 30},
                 {"type": "ramp", "to_c": 20.0, "rate_c_per_min": 1.0}],
                max_rate_c_per_min=5.0)
    sp = p.setpoint()
    rl = p.rate_limited(sp)
    # 60 K at 5 °C/min takes 12 min (programme: 3 min); the programme clock is kept
    assert rl(np.array([12 * 60.0]))[0] == pytest.approx(80.0)
    assert rl(np.array([6 * 60.0]))[0] == pytest.approx(50.0)
    assert rl.end_s == pytest.approx(sp.end_s)
    t = np.linspace(12 * 60, sp.end_s, 1000)
    np.testing.assert_allclose(rl(t), sp(t), atol=1e-9)


def test_rate_limit_against_a_fine_time_step_simulation():
    """Exact event-based limiter vs a brute-force slew-limited tracker on a 0.01 s grid."""
    sp = PiecewiseLinear([0, 100, 100, 400, 500, 900, 950], [0, 0, 30, 10, 10, -20, 25])
    r = 0.1                             # K/s
    rl = rate_limit(sp, r)
    t = np.arange(0, 1500, 0.01)
    x = sp(t)
    y = np.empty_like(t)
    y[0] = x[0]
    for k in range(1, t.size):                                       # reference only
        y[k] = y[k - 1] + np.clip(x[k] - y[k - 1], -r * 0.01, r * 0.01)
    assert np.max(np.abs(rl(t) - y)) < 0.01
    assert rl.max_abs_rate_c_per_min() <= r * 60 * (1 + 1e-9)
    assert np.all(np.diff(rl.t_s) > 0)
    assert rl.y[-1] == 25.0


def test_catch_up_continues_after_the_programme_ends():
    p = program([{"type": "step", "to_c": 50.0}], max_rate_c_per_min=1.0)
    rl = p.rate_limited(p.setpoint())
    assert rl.end_s == pytest.approx(30 * 60)
    assert rl.y[-1] == 50.0


def test_defaults_and_air_lag():
    p = program([{"type": "hold", "duration_h": 1}])
    assert p.max_rate_c_per_min == 10.0 and p.air_tau_s == 60.0
    p = program([{"type": "hold", "duration_h": 1}], air_tau_s=0, max_rate_c_per_min=3)
    assert p.air_tau_s == 0.0 and p.max_rate_c_per_min == 3.0
    assert isinstance(p.segments[0], Hold)


# --------------------------------------------------------------------------- validation


GOOD = {"start_c": 20.0, "max_rate_c_per_min": 5.0, "air_tau_s": 90.0,
        "segments": [{"type": "hold", "duration_min": 10},
                     {"type": "ramp", "to_c": 40.0, "rate_c_per_min": 1.0},
                     {"type": "repeat", "count": 2,
                      "segments": [{"type": "ramp", "to_c": 30.0, "duration_min": 5}]}]}


@pytest.mark.parametrize("edit, key", [
    (lambda d: d.update(start=20.0), "start"),                                   # misspelt
    (lambda d: d.pop("start_c"), "start_c"),
    (lambda d: d.update(start_c="20"), "start_c"),                               # wrong type
    (lambda d: d.update(max_rate_c_per_min=0.0), "max_rate_c_per_min"),
    (lambda d: d.update(air_tau_s=-1.0), "air_tau_s"),
    (lambda d: d["segments"][0].update(type="soak"), "type"),
    (lambda d: d["segments"][0].update(duration_min=-10), "duration_min"),       # negative
    (lambda d: d["segments"][0].update(duration_h=1), "duration_h"),             # two units
    (lambda d: d["segments"][0].update(duraton_min=1), "duraton_min"),
    (lambda d: d["segments"][0].pop("duration_min"), "duration"),
    (lambda d: d["segments"][1].update(rate_c_per_min=0.0), "rate_c_per_min"),   # rate 0
    (lambda d: d["segments"][1].update(rate_c_per_min=True), "rate_c_per_min"),
    (lambda d: d["segments"][1].update(duration_min=5), "rate_c_per_min"),       # both
    (lambda d: d["segments"][1].pop("rate_c_per_min"), "rate_c_per_min"),        # neither
    (lambda d: d["segments"][1].update(to_c=500.0), "to_c"),
    (lambda d: d["segments"][2].update(count=0), "count"),
    (lambda d: d["segments"][2]["segments"][0].update(duration_min=0), "duration_min"),
    (lambda d: d["segments"][2]["segments"][0].update(rate=1.0), "rate"),
    (lambda d: d.update(segments=[{"type": "random", "legs": 3, "min_c": 10, "max_c": 0,
                                   "min_rate_c_per_min": 1, "max_rate_c_per_min": 2,
                                   "min_hold_s": 0, "max_hold_s": 10}]), "max_c"),
    (lambda d: d.update(segments=[{"type": "random", "legs": 3, "min_c": 0, "max_c": 10,
                                   "min_rate_c_per_min": 1, "max_rate_c_per_min": 0.5,
                                   "min_hold_s": 0, "max_hold_s": 10}]), "max_rate_c_per_min"),
    (lambda d: d.update(segments=[{"type": "random", "legs": 3, "min_c": 0, "max_c": 10,
                                   "min_rate_c_per_min": 1, "max_rate_c_per_min": 2,
                                   "min_hold_s": 0}]), "max_hold"),
    (lambda d: d.update(segments="hold"), "segments"),
])
def test_bad_tables_raise_user_errors_naming_the_key(edit, key):
    d = copy.deepcopy(GOOD)
    edit(d)
    with pytest.raises(UserInputError) as err:
        ChamberProgram.from_config(d, CTX)
    msg = str(err.value)
    assert msg.startswith("scen.toml: chamber")
    assert key in msg


def test_good_table_parses():
    p = ChamberProgram.from_config(copy.deepcopy(GOOD), CTX)
    assert p.start_c == 20.0 and p.max_rate_c_per_min == 5.0 and p.air_tau_s == 90.0
    assert isinstance(p.segments[1], Ramp) and p.segments[1].rate_c_per_min == 1.0
    sp = p.rate_limited(p.setpoint())
    assert sp.end_s == pytest.approx(600 + 20 * 60 + 2 * 300)


# --------------------------------------------------------------------------- properties

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 2000.0), st.floats(-50.0, 80.0)), min_size=1,
                max_size=12),
       st.floats(0.01, 2.0))
def test_rate_limit_properties(points, rate):
    """For any piecewise-linear programme (jumps allowed): the limited setpoint is continuous
    with increasing breakpoints, never faster than the limit, starts at the programme's start
    and ends on its final value, no earlier than the programme ends."""
    times = np.cumsum([p[0] for p in points])
    times[0] = 0.0
    sp = PiecewiseLinear(times, [p[1] for p in points])
    rl = rate_limit(sp, rate)
    assert np.all(np.diff(rl.t_s) > 0) or rl.t_s.size == 1
    # |Δy| ≤ r·Δt on every piece (absolute tolerance: catch-up points are rounded values)
    assert np.all(np.abs(np.diff(rl.y)) <= rate * np.diff(rl.t_s) * (1 + 1e-9) + 1e-9)
    # the start is the programme's start, up to the limiter's caught-up tolerance (1e-12 of
    # the temperatures involved: a jump smaller than that at t = 0 is taken as caught up)
    eps = 1e-12 * max(1.0, float(np.max(np.abs(sp.y))))
    assert abs(rl.y[0] - sp.y[0]) <= eps and rl.y[-1] == pytest.approx(sp.y[-1], abs=1e-9)
    assert rl.end_s >= sp.end_s - 1e-9
    # after its last breakpoint the limited setpoint holds the programme's final value
    t = np.linspace(0, rl.end_s, 400)
    gap = np.abs(rl(t) - sp(t))
    assert np.all(gap[t >= rl.end_s] <= 1e-6)
