"""The optional thermal parts in a simulated run: a real chamber ([chamber.controller]), a
further boundary, a controlled heater and a nonlinear link in the thermal preset. The dataset
records the heater power and the boundary temperature; bytes do not depend on the chunk size;
the run matches the integrator driven directly."""

from __future__ import annotations

import pathlib
import re

import h5py
import numpy as np
import pytest

from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.schedule import build_timeline
from rlgsim.sim.run.simulate import simulate
from rlgsim.sim.thermal.integrator import ThermalIntegrator

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXTRA = """
[thermal.boundaries.lab]
temperature_c = 23.0
amplitude_c = 1.0
period_h = 0.5

[thermal.nodes.table]
capacitance_j_per_k = 20000.0

[[thermal.links]]
between = ["table", "housing_air"]
conductance_w_per_k = 0.8
[[thermal.links]]
between = ["table", "chamber_air"]
conductance_w_per_k = 3.0
[[thermal.links]]
between = ["table", "lab"]
conductance_w_per_k = 0.5
[[thermal.links]]
between = ["housing_air", "table"]
radiation_exact = { emissivity = 0.8, area_cm2 = 400.0 }

[thermal.heaters.cabinet]
node = "housing_air"
sensor = "housing_air"
setpoint_c = 30.0
max_power_w = 8.0
kp_w_per_k = 4.0
ti_s = 1500.0
"""


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("thermal_run")
    th = (ROOT / "scenarios" / "thermal" / "rlg_single.toml").read_text()
    (tmp / "th.toml").write_text(th + EXTRA)
    dev = (ROOT / "scenarios" / "devices" / "rlg8_003.toml").read_text()
    dev = re.sub(r'(?m)^thermal_preset = ".*"', 'thermal_preset = "th.toml"', dev)
    assert 'thermal_preset = "th.toml"' in dev
    # the device's run-to-run table names mount links of its own network (base–table), which this
    # single-block network does not have; this test is about the optional thermal parts
    dev, n = re.subn(r"(?ms)^\[run_to_run\]\n.*?(?=^\[|\Z)", "", dev)
    assert n == 1 and "mount_links" not in dev
    (tmp / "dev.toml").write_text(dev)
    sc = (ROOT / "scenarios" / "quickstart.toml").read_text()
    sc = sc.replace('device = "rlg8_003"', 'device = "dev.toml"')
    sc = sc.replace("duration_h = 2.0", "duration_h = 1.0")
    sc = sc.replace("start_c = 20.0", "start_c = 20.0\n\n[chamber.controller]\n"
                                      "ripple_amplitude_c = 0.3\nripple_period_s = 300.0", 1)
    (tmp / "sc.toml").write_text(sc)
    scenario = load_scenario(str(tmp / "sc.toml"))
    a = simulate(scenario, tmp / "a.h5", progress=False)
    b = simulate(scenario, tmp / "b.h5", progress=False, chunk_s=600.0)
    return scenario, a, b


def test_the_run_records_heater_power_and_boundary_temperature(case):
    scenario, a, _ = case
    with h5py.File(a) as f:
        g = f["thermal"]
        P = g["heater_power"][()]
        lab = g["boundary_temperature"][()]
        t = g["time"][()]
        assert P.shape == (t.size, 1) and lab.shape == (t.size, 1)
        assert 0.0 <= P.min() and P.max() <= 8.0 and np.ptp(P) > 0.1
        np.testing.assert_allclose(lab[:, 0], 23.0 + np.sin(2 * np.pi * t / 1800.0),
                                   atol=1e-12)
        air, sp = g["chamber_air"][()], g["chamber_setpoint"][()]
        assert 0.2 < np.max(np.abs(air - sp)[:600]) < 0.4       # the chamber's ripple
        # the same as the integrator driven directly over the whole run
        net = scenario.device.thermal.network
        tl = build_timeline(scenario)
        integ = ThermalIntegrator(net, tl.step_s, 60.0, controller=scenario.chamber.controller)
        tt = np.arange(tl.n_steps + 1) * tl.step_s
        st, _ = integ.propagate(integ.initial_state(20.0, True), tl.setpoint(tt),
                                tl.power(tt[:-1]))
        np.testing.assert_allclose(g["node_temperature"][()], st[:, 1:], atol=1e-9)
        np.testing.assert_allclose(P, integ.last_heater_power_w, atol=1e-9)


def test_optional_thermal_parts_do_not_depend_on_the_chunk_size(case):
    _, a, b = case
    with h5py.File(a) as fa, h5py.File(b) as fb:
        for name in ("thermal/chamber_air", "thermal/node_temperature", "thermal/heater_power",
                     "thermal/boundary_temperature", "imu/gyro_pulses", "probes/temperature"):
            assert np.array_equal(fa[name][()], fb[name][()]), name
