"""Anomalies in a simulated run: a device preset with an ``[anomalies]`` table; the event
record in the dataset; every event visible and nothing else changed against the same run
without anomalies; bytes independent of the chunk size."""

from __future__ import annotations

import pathlib

import h5py
import numpy as np
import pytest

from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.simulate import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]
ANOMALIES = """
[anomalies.probe_glitches]
rate_per_h = 3.0
[anomalies.probe_stuck]
rate_per_h = 2.0
mean_duration_s = 120.0
[anomalies.probe_dropouts]
rate_per_h = 2.0
mean_duration_s = 60.0
"""


def write_case(tmp: pathlib.Path, extra: str, name: str) -> pathlib.Path:
    dev = (ROOT / "scenarios" / "devices" / "rlg8_003.toml").read_text()
    (tmp / f"{name}_dev.toml").write_text(dev + extra)
    sc = (ROOT / "scenarios" / "quickstart.toml").read_text()
    sc = sc.replace('device = "rlg8_003"', f'device = "{name}_dev.toml"')
    sc = sc.replace("duration_h = 2.0", "duration_h = 1.0")
    assert f"{name}_dev.toml" in sc
    path = tmp / f"{name}.toml"
    path.write_text(sc)
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("anomalies")
    plain = simulate(load_scenario(str(write_case(tmp, "", "plain"))), tmp / "plain.h5",
                     progress=False)
    case = write_case(tmp, ANOMALIES, "anom")
    a = simulate(load_scenario(str(case)), tmp / "a.h5", progress=False)
    b = simulate(load_scenario(str(case)), tmp / "b.h5", progress=False, chunk_s=600.0)
    return plain, a, b


def test_probe_events_are_recorded_and_visible_and_nothing_else_changes(runs):
    plain, a, _ = runs
    with h5py.File(plain) as fp, h5py.File(a) as fa:
        assert "anomalies" not in fp
        ev = fa["anomalies"]
        kinds = [k.decode() if isinstance(k, bytes) else k for k in ev["kind"][()]]
        chans = [k.decode() if isinstance(k, bytes) else k for k in ev["channel"][()]]
        assert {"probe_glitch", "probe_stuck", "probe_dropout"} <= set(kinds)
        names = [p.decode() if isinstance(p, bytes) else p for p in fa["probes/probe"][()]]
        ref = fp["probes/temperature"][()]
        got = fa["probes/temperature"][()]
        t = fa["probes/time"][()]
        expect = ref.copy()
        for t0, t1, ch, kind in zip(ev["time"][()], ev["end"][()], chans, kinds):
            p = names.index(ch)
            i0 = int(np.searchsorted(t, t0))
            i1 = int(np.searchsorted(t, t1)) + 1
            if kind == "probe_glitch":
                expect[i0, p] = 85.0
            elif kind == "probe_dropout":
                expect[i0:i1, p] = np.nan
            else:
                expect[i0:i1, p] = expect[i0 - 1, p]
        np.testing.assert_array_equal(got, expect)
        # the rest of the dataset is the run without anomalies
        np.testing.assert_array_equal(fa["imu/gyro_pulses"][()], fp["imu/gyro_pulses"][()])
        np.testing.assert_array_equal(fa["thermal/node_temperature"][()],
                                      fp["thermal/node_temperature"][()])


def test_the_event_record_does_not_depend_on_the_chunk_size(runs):
    _, a, b = runs
    with h5py.File(a) as fa, h5py.File(b) as fb:
        for name in ("anomalies/time", "anomalies/end", "anomalies/kind", "anomalies/channel",
                     "anomalies/size", "anomalies/event", "probes/temperature"):
            x, y = fa[name][()], fb[name][()]
            if x.dtype.kind == "f":
                np.testing.assert_array_equal(x, y)
            else:
                assert list(x) == list(y)
