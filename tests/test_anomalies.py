"""Sensor anomalies with a labelled event record (rlgsim.sim.sensors.anomalies).

References: the closed-form hop temperatures of eq. (A1) on a slow up/down ramp; exact
bookkeeping of every pulse and reading; Poisson statistics over many blocks."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import deg_per_h_to_rad_per_s
from rlgsim.sim.sensors.anomalies import Anomalies
from rlgsim.sim.sensors.anomaly_model import AnomalyModel, Events
from rlgsim.sim.config import Ctx

CTX = Ctx("dev.toml", "anomalies")
HOP = {"nodes": ["A", "B"], "modes_per_k": 0.08, "range_modes": 2.2, "reference_c": 20.0,
       "bias_step_deg_per_h": 0.004}


def bound(table: dict, probes=("A", "B", "housing"), **kw) -> Anomalies:
    model = AnomalyModel.from_config(table, CTX)
    return Anomalies(model, node_names=("g.A", "g.B", "housing_air"), gyro_axes=("z",),
                     gyro_blocks=("g",), probe_names=probes, seed=kw.get("seed", 7), unit=0)


def ramp_nodes(T: np.ndarray) -> np.ndarray:
    return np.column_stack([T - 0.1, T + 0.1, T])        # mean of A and B is T


def run_hops(an: Anomalies, T: np.ndarray, block: int):
    st = an.initial_state(ramp_nodes(T[:1])[0])
    t = np.arange(1, T.size + 1, dtype=float)
    offs, ev = [], Events()
    for a in range(0, T.size, block):
        o, e, st = an.mode_hops(st, t[a:a + block], ramp_nodes(T[a:a + block]))
        offs.append(o)
        ev.extend(e)
    return np.concatenate(offs), ev.arrays()


def test_mode_hops_trace_the_hysteresis_loop_of_a_slow_up_down_ramp():
    an = bound({"mode_hop": HOP})
    T = np.concatenate([np.linspace(20.0, 60.0, 40001), np.linspace(60.0, -20.0, 80001)[1:],
                        np.linspace(-20.0, 20.0, 40001)[1:]])
    off, ev = run_hops(an, T, 600)
    kappa, R, ref = 0.08, 2.2, 20.0
    hop_T = T[np.round(ev["time_s"]).astype(int) - 1]
    up = ev["kind"] == "mode_hop_up"
    # k starts at 0; going up the hops happen at ref + (k + R/2)/κ, k = 0, 1, 2 ...
    k_up = np.arange(up.sum())
    heating = hop_T[up][:k_up.size]
    first_up = ev["time_s"][up] < 40001
    np.testing.assert_allclose(hop_T[up][first_up], ref + (k_up[:first_up.sum()] + R / 2) / kappa,
                               atol=0.002)
    # coming down, mode k+1 hops back at ref + (k + 1 − R/2)/κ: lower by the loop width
    down = ev["kind"] == "mode_hop_down"
    kmax = first_up.sum()
    k_down = np.arange(kmax - 1, kmax - 1 - down.sum(), -1)
    np.testing.assert_allclose(hop_T[down], ref + (k_down + 1 - R / 2) / kappa, atol=0.002)
    width = (ref + (0 + R / 2) / kappa) - (ref + (0 + 1 - R / 2) / kappa)
    assert width == pytest.approx(an.model.mode_hop.hysteresis_k) == pytest.approx(15.0)
    # the bias is a hysteretic function of temperature: at 30 °C going up vs coming down
    step = deg_per_h_to_rad_per_s(0.004)
    i_up = np.argmin(np.abs(T[:40001] - 30.0))
    i_dn = 40001 + np.argmin(np.abs(T[40001:120001] - 30.0))
    assert off[i_up, 0] == pytest.approx(0.0)
    assert off[i_dn, 0] == pytest.approx(step)
    # every event is exactly the step of the offset at its time, and nothing else steps
    idx = np.round(ev["time_s"]).astype(int) - 1
    d = np.diff(np.concatenate([[0.0], off[:, 0]]))
    np.testing.assert_allclose(d[idx], deg_per_h_to_rad_per_s(ev["size"]), rtol=1e-12)
    mask = np.ones(T.size, bool)
    mask[idx] = False
    assert np.all(d[mask] == 0)
    assert heating.size >= 3 and down.sum() >= 5
    # back at 20 °C after going round the loop from below: the mode is below the start one
    assert off[-1, 0] == pytest.approx(-step)


@pytest.mark.parametrize("block", [1, 599, 600, 7000])
def test_mode_hops_do_not_depend_on_the_block_length(block):
    an = bound({"mode_hop": HOP})
    T = 20 + 30 * np.sin(np.linspace(0, 6 * np.pi, 9000))
    ref_off, ref_ev = run_hops(an, T, 9000)
    off, ev = run_hops(an, T, block)
    assert np.array_equal(off, ref_off)
    for k in ref_ev:
        assert np.array_equal(ev[k], ref_ev[k])


TABLE = {"pulse_spikes": {"rate_per_h": 40.0, "max_pulses": 50},
         "imu_dropouts": {"rate_per_h": 30.0, "mean_samples": 40.0},
         "probe_glitches": {"rate_per_h": 6.0},
         "probe_stuck": {"rate_per_h": 4.0, "mean_duration_s": 300.0},
         "probe_dropouts": {"rate_per_h": 4.0, "mean_duration_s": 200.0}}


def pulse_run(an: Anomalies, n_blocks: int, n: int = 60000, rate: float = 100.0):
    rng = np.random.default_rng(3)
    st = an.initial_state(np.zeros(3))
    ins, outs, valids, ev = [], [], [], Events()
    for b in range(n_blocks):
        p = rng.integers(-3000, 3000, size=(n, 1)).astype(np.int32)
        o, v, e, st = an.pulses(st, b, b * n, rate, p)
        ins.append(p)
        outs.append(o)
        valids.append(v)
        ev.extend(e)
    return np.concatenate(ins), np.concatenate(outs), np.concatenate(valids), ev.arrays()


def test_every_pulse_event_is_visible_and_no_other_pulse_changes():
    an = bound(TABLE)
    pin, pout, valid, ev = pulse_run(an, 12)
    rate = 100.0
    expect = pin.astype(np.int64).copy()
    expect_valid = np.ones(len(pin), bool)
    spikes = ev["kind"] == "pulse_spike"
    drops = ev["kind"] == "imu_dropout"
    assert spikes.sum() >= 10 and drops.sum() >= 10
    for t0, t1 in zip(ev["time_s"][drops], ev["end_s"][drops]):
        i0, i1 = int(round(t0 * rate)) - 1, int(round(t1 * rate))
        expect_valid[i0:i1] = False
        expect[i0:i1] = 0
    for t, s in zip(ev["time_s"][spikes], ev["size"][spikes]):
        i = int(round(t * rate)) - 1
        assert expect_valid[i]
        expect[i, 0] += int(s)
    assert np.array_equal(pout, expect)
    assert np.array_equal(valid, expect_valid)
    # exact bookkeeping: logged + lost − spikes = what the counter produced
    assert pout.astype(np.int64).sum() + ev["size"][drops].sum() - ev["size"][spikes].sum() \
        == pin.astype(np.int64).sum()


def test_a_dropout_over_a_block_end_continues_in_the_next_block():
    an = bound({"imu_dropouts": {"rate_per_h": 60.0, "mean_samples": 30000.0}})
    pin, pout, valid, ev = pulse_run(an, 12)
    first = np.round(ev["time_s"] * 100.0).astype(int) - 1
    assert np.any(first % 60000 == 0)             # a continued run starts a block
    assert np.all(pout[~valid] == 0) and np.array_equal(pout[valid], pin[valid])
    lost = ev["size"].sum()
    assert pout.astype(np.int64).sum() + lost == pin.astype(np.int64).sum()
    assert (~valid).sum() > 30000


def probe_run(an: Anomalies, n_blocks: int, m: int = 600, step: float = 1.0):
    rng = np.random.default_rng(4)
    st = an.initial_state(np.zeros(3))
    ins, outs, ev = [], [], Events()
    for b in range(n_blocks):
        r = 20 + np.cumsum(rng.normal(0, 0.05, size=(m, 3)), axis=0) + b
        o, e, st = an.probes(st, b, b * m, step, r)
        ins.append(r)
        outs.append(o)
        ev.extend(e)
    return np.concatenate(ins), np.concatenate(outs), ev.arrays()


def test_every_probe_event_is_visible_and_no_other_reading_changes():
    an = bound(TABLE)
    rin, rout, ev = probe_run(an, 60)
    names = list(an.probe_names)
    expect = rin.copy()
    kinds = set(ev["kind"])
    assert kinds == {"probe_glitch", "probe_stuck", "probe_dropout"}
    for t0, t1, ch, kind, size in zip(ev["time_s"], ev["end_s"], ev["channel"], ev["kind"],
                                      ev["size"]):
        p = names.index(ch)
        i0, i1 = int(round(t0)) - 1, int(round(t1))
        if kind == "probe_glitch":
            assert size == pytest.approx(85.0 - rin[i0, p])
            expect[i0, p] = 85.0
        elif kind == "probe_dropout":
            assert size == pytest.approx(i1 - i0)
            expect[i0:i1, p] = np.nan
        else:
            assert size == pytest.approx(i1 - i0)
            expect[i0:i1, p] = expect[i0 - 1, p]            # the last logged reading
    np.testing.assert_array_equal(rout, expect)


def test_probe_events_continue_over_block_ends_and_repeat_exactly():
    an = bound(TABLE)
    _, a, ev_a = probe_run(an, 30)
    _, b, ev_b = probe_run(an, 30)
    np.testing.assert_array_equal(a, b)
    for k in ev_a:
        assert np.array_equal(ev_a[k], ev_b[k])
    # some stuck or dropout interval spans a block end (600 s) and is recorded once
    long = np.isin(ev_a["kind"], ["probe_stuck", "probe_dropout"])
    spans = np.floor((ev_a["time_s"][long] - 1) / 600) != np.floor((ev_a["end_s"][long] - 1)
                                                                    / 600)
    assert spans.any()


def test_event_rates_follow_the_preset():
    an = bound({"pulse_spikes": {"rate_per_h": 12.0, "max_pulses": 3}})
    _, _, _, ev = pulse_run(an, 200, n=6000, rate=100.0)       # 200 blocks of 60 s = 3.33 h
    expected = 12.0 * 200 * 60 / 3600
    assert abs(len(ev["time_s"]) - expected) < 5 * np.sqrt(expected)
    assert set(np.abs(ev["size"]).astype(int)) <= {1, 2, 3}


def test_no_anomalies_leave_everything_unchanged():
    an = bound({})
    assert not an.model.active
    p = np.arange(20, dtype=np.int32).reshape(10, 2) - 5
    an2 = Anomalies(an.model, node_names=("a",), gyro_axes=("x", "y"), probe_names=("p",))
    st = an2.initial_state(np.zeros(1))
    out, valid, ev, _ = an2.pulses(st, 0, 0, 100.0, p)
    assert np.array_equal(out, p) and valid.all() and len(ev) == 0
    r = np.linspace(0, 1, 12).reshape(12, 1)
    o, ev, _ = an2.probes(st, 0, 0, 1.0, r)
    assert np.array_equal(o, r) and len(ev) == 0


@pytest.mark.parametrize("table, key", [
    ({"mode_hop": {**HOP, "range_modes": 1.0}}, "anomalies.mode_hop.range_modes"),
    ({"mode_hop": {**HOP, "modes_per_k": 0}}, "anomalies.mode_hop.modes_per_k"),
    ({"mode_hop": {k: v for k, v in HOP.items() if k != "nodes"}}, "anomalies.mode_hop.nodes"),
    ({"pulse_spikes": {"rate_per_h": 1.0, "max_pulses": 2.5}}, "anomalies.pulse_spikes.max_pulses"),
    ({"probe_glitch": {"rate_per_h": 1.0}}, "anomalies.probe_glitch"),
    ({"probe_stuck": {"rate_per_h": -1.0}}, "anomalies.probe_stuck.rate_per_h"),
])
def test_bad_keys_are_one_line_errors(table, key):
    with pytest.raises(UserInputError) as e:
        AnomalyModel.from_config(table, CTX)
    assert key in str(e.value) and "dev.toml" in str(e.value) and "\n" not in str(e.value)


def test_unknown_mode_hop_node_is_an_error():
    with pytest.raises(UserInputError, match="mode_hop.nodes.*'Q'"):
        bound({"mode_hop": {**HOP, "nodes": ["Q"]}})


def test_lost_frames_remove_the_same_samples_from_another_instrument():
    an = bound({"imu_dropouts": {"rate_per_h": 60.0, "mean_samples": 50.0}})
    gin, gout, valid, ev = pulse_run(an, 3)
    acc = np.random.default_rng(9).integers(-50, 50, size=(len(valid), 2)).astype(np.int32)
    out, aev = an.lost_frames(valid, 0, 100.0, acc, ("ax", "ay"))
    assert np.all(out[~valid] == 0) and np.array_equal(out[valid], acc[valid])
    a = aev.arrays()
    lost = a["size"].sum()
    assert out.astype(np.int64).sum() + lost == acc.astype(np.int64).sum()
    assert set(a["channel"]) == {"ax", "ay"}
    # the runs are the gyro's runs (per block there may be more gyro events: block ends)
    assert len(a["time_s"]) // 2 <= (ev["kind"] == "imu_dropout").sum()


def test_a_drawn_unit_shifts_its_hop_temperatures_within_one_mode_spacing():
    hop = {**HOP, "modes_per_k_rel": 0.1, "bias_step_rel": 0.2}
    temps = []
    for seed in range(40):
        an = bound({"mode_hop": hop})
        an.realise_unit(np.random.default_rng(seed))
        mh = an.hops[0]
        temps.append(mh.reference_c + (0 + mh.range_modes / 2) / mh.modes_per_k)
        assert abs(mh.reference_c - 20.0) <= 0.5 / mh.modes_per_k
    again = bound({"mode_hop": hop})
    again.realise_unit(np.random.default_rng(39))
    assert again.hops[0] == mh                           # the same draw for the same stream
    # the first up-hop temperature spreads over about one mode spacing (1/κ = 12.5 K)
    assert 5.0 < np.ptp(temps) < 25.0
    nominal = bound({"mode_hop": HOP})
    assert nominal.hops[0].reference_c == 20.0           # unit 0: the design as written


def test_an_empty_block_neither_records_nor_loses_anything():
    """A short last block may hold no IMU sample (low rates): a running dropout waits."""
    an = bound({"imu_dropouts": {"rate_per_h": 3600.0, "mean_samples": 1e5}})
    st = an.initial_state(np.zeros(3))
    p = np.ones((1000, 1), dtype=np.int32)
    out, valid, ev, st = an.pulses(st, 0, 0, 100.0, p)
    assert st.imu_lost_left > 0
    out, valid, ev, st2 = an.pulses(st, 1, 1000, 100.0, np.zeros((0, 1), dtype=np.int32))
    assert len(ev) == 0 and out.shape == (0, 1) and st2.imu_lost_left == st.imu_lost_left
