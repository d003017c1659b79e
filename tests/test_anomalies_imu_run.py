"""Gyro anomalies in a simulated run (mode hops, pulse spikes, IMU frame dropouts): every
recorded event is visible in the pulses or the true bias, nothing else changes, and the pulse
bookkeeping stays exact."""

from __future__ import annotations

import pathlib

import h5py
import numpy as np
import pytest

from rlgsim.ground.units import deg_per_h_to_rad_per_s
from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.simulate import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]
PULSES = """
[anomalies.pulse_spikes]
rate_per_h = 20.0
max_pulses = 40
[anomalies.imu_dropouts]
rate_per_h = 10.0
mean_samples = 30.0
"""
# quickstart: the chamber goes 20 → 40 → 20 °C; the gyro block follows with a lag
HOPS = """
[anomalies.mode_hop]
nodes = ["A", "B", "C"]
modes_per_k = 0.3
range_modes = 1.2
reference_c = 20.0
bias_step_deg_per_h = 0.02
"""


def write_case(tmp: pathlib.Path, extra: str, name: str) -> pathlib.Path:
    dev = (ROOT / "scenarios" / "devices" / "rlg8_003.toml").read_text()
    (tmp / f"{name}_dev.toml").write_text(dev + extra)
    sc = (ROOT / "scenarios" / "quickstart.toml").read_text()
    sc = sc.replace('device = "rlg8_003"', f'device = "{name}_dev.toml"')
    path = tmp / f"{name}.toml"
    path.write_text(sc)
    return path


def text(a) -> list[str]:
    return [x.decode() if isinstance(x, bytes) else str(x) for x in a]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("imu_anomalies")
    out = {}
    for name, extra in (("plain", ""), ("pulses", PULSES), ("hops", HOPS)):
        out[name] = simulate(load_scenario(str(write_case(tmp, extra, name))),
                             tmp / f"{name}.h5", progress=False)
    out["pulses_chunked"] = simulate(load_scenario(str(tmp / "pulses.toml")),
                                     tmp / "pulses_c.h5", progress=False, chunk_s=600.0)
    return out


def test_spikes_and_dropouts_are_exactly_the_recorded_events(runs):
    with h5py.File(runs["plain"]) as fp, h5py.File(runs["pulses"]) as fa:
        rate = float(fa.attrs["sample_rate_hz"])
        ref = fp["imu/gyro_pulses"][()].astype(np.int64)
        got = fa["imu/gyro_pulses"][()].astype(np.int64)
        valid = fa["imu/sample_valid"][()].astype(bool)
        ev = fa["anomalies"]
        kinds, size = text(ev["kind"][()]), ev["size"][()]
        t0, t1 = ev["time"][()], ev["end"][()]
        expect = ref.copy()
        expect_valid = np.ones(len(ref), bool)
        n_spike = n_drop = 0
        for k, s, a, b in zip(kinds, size, t0, t1):
            i0, i1 = int(round(a * rate)) - 1, int(round(b * rate))
            if k == "imu_dropout":
                assert s == ref[i0:i1, 0].sum()
                expect[i0:i1] = 0
                expect_valid[i0:i1] = False
                n_drop += 1
        for k, s, a in zip(kinds, size, t0):
            if k == "pulse_spike":
                expect[int(round(a * rate)) - 1, 0] += int(s)
                n_spike += 1
        assert n_spike >= 10 and n_drop >= 5
        np.testing.assert_array_equal(got, expect)
        np.testing.assert_array_equal(valid, expect_valid)
        # the truth is untouched: read-out anomalies are not part of the bias
        np.testing.assert_array_equal(fa["truth/gyro_bias"][()], fp["truth/gyro_bias"][()])


def test_mode_hops_step_the_true_bias_exactly_at_the_recorded_events(runs):
    with h5py.File(runs["plain"]) as fp, h5py.File(runs["hops"]) as fh:
        d = fh["truth/gyro_bias"][()][:, 0] - fp["truth/gyro_bias"][()][:, 0]
        t = fh["truth/time"][()]
        ev = fh["anomalies"]
        kinds = text(ev["kind"][()])
        assert "mode_hop_up" in kinds and "mode_hop_down" in kinds
        # the mode the gyro locks on at the start carries its own (constant) offset k0·Δb
        k0 = d[0] / deg_per_h_to_rad_per_s(0.02)
        assert k0 == pytest.approx(round(k0), abs=1e-9) and round(k0) != 0
        step = np.diff(np.concatenate([[d[0]], d]))
        idx = np.searchsorted(t, ev["time"][()])
        np.testing.assert_allclose(step[idx], deg_per_h_to_rad_per_s(ev["size"][()]),
                                   rtol=1e-9, atol=1e-18)
        rest = np.ones(t.size, bool)
        rest[idx] = False
        assert np.max(np.abs(step[rest])) < 1e-18
        # the pulses carry the bias steps: the extra phase is the integral of the offset
        K = fh["truth/gyro_scale_factor"][()][:, 0]
        extra = float(np.sum(d * K * float(fh.attrs["thermal_step_s"])))
        got = int(fh["imu/gyro_pulses"][()].astype(np.int64).sum()
                  - fp["imu/gyro_pulses"][()].astype(np.int64).sum())
        assert abs(got - extra) <= 1.0 + 1e-6 * abs(extra)
        assert abs(extra) > 10


def test_gyro_anomalies_do_not_depend_on_the_chunk_size(runs):
    with h5py.File(runs["pulses"]) as fa, h5py.File(runs["pulses_chunked"]) as fb:
        for name in ("imu/gyro_pulses", "imu/sample_valid", "anomalies/time",
                     "anomalies/size"):
            assert np.array_equal(fa[name][()], fb[name][()]), name
