"""The optional variables of a dataset: parts a scenario switches on (controlled heaters and
further boundaries in the thermal preset, sensor anomalies with IMU frame dropouts in the
device preset) write exactly the names of ``rlgsim.ground.dataset_format.OPTIONAL_VARIABLES``,
after the group's ``VARIABLES`` names, each declared by the schema room with the units and
dimensions docs/dataset.md gives; a run without them writes none."""

from __future__ import annotations

import pathlib
import re

import numpy as np
import pytest

from rlgsim.ground import dataset_format as fmt
from rlgsim.ground.dataset_format import open_dataset
from rlgsim.sim.writer.schema import DESCRIPTIONS
from rlgsim.sim.run.scenario import load_scenario
from rlgsim.sim.run.simulate import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]

# the IMU preset has every device-dependent part (accelerometers, UHFO); per-sample truth on
SCENARIO = """
name = "optional_parts"
device = "dev.toml"
seed = 31
duration_s = 1200

[acquisition]
sample_rate_hz = 100
thermal_step_s = 1
truth_samples = true

[chamber]
start_c = 10.0

[[chamber.segments]]
type = "ramp"
to_c = 30.0
rate_c_per_min = 2.0

[turntable]
program = "calibration19"
first_dwell_s = 60
dwell_s = 30
"""
# a laboratory boundary through a turntable node (rlg_imu brings its own thermostat on the
# base plate: docs/thermal.md §4.3)
THERMAL = """
[thermal.boundaries.lab]
temperature_c = 23.0

[thermal.nodes.table]
capacitance_j_per_k = 20000.0

[[thermal.links]]
between = ["table", "base"]
conductance_w_per_k = 1.0
[[thermal.links]]
between = ["table", "chamber_air"]
conductance_w_per_k = 3.0
[[thermal.links]]
between = ["table", "lab"]
conductance_w_per_k = 0.5

"""
ANOMALIES = """
[anomalies.pulse_spikes]
rate_per_h = 30.0
max_pulses = 40
[anomalies.imu_dropouts]
rate_per_h = 60.0
mean_samples = 20.0
"""
#: (group, variable) -> (dims, units) of every optional variable, as docs/dataset.md gives them
EXPECTED = {
    (fmt.THERMAL, "heater"): (("heater",), None),
    (fmt.THERMAL, "heater_power"): (("time", "heater"), "W"),
    (fmt.THERMAL, "boundary"): (("boundary",), None),
    (fmt.THERMAL, "boundary_temperature"): (("time", "boundary"), "degC"),
    (fmt.IMU, "sample_valid"): (("sample",), "1"),
    (fmt.ANOMALIES, "event"): (("event",), "1"),
    (fmt.ANOMALIES, "time"): (("event",), "s"),
    (fmt.ANOMALIES, "end"): (("event",), "s"),
    (fmt.ANOMALIES, "channel"): (("event",), None),
    (fmt.ANOMALIES, "kind"): (("event",), None),
    (fmt.ANOMALIES, "size"): (("event",), "see size_units"),
    (fmt.ANOMALIES, "size_units"): (("event",), None),
    # a run on a vehicle (tests/test_trajectory_runs.py writes it)
    (fmt.TRAJECTORY, "sample"): (("sample",), None),
    (fmt.TRAJECTORY, "enu"): (("enu",), None),
    (fmt.TRAJECTORY, "quaternion"): (("quaternion",), None),
    (fmt.TRAJECTORY, "latitude"): (("sample",), "degree"),
    (fmt.TRAJECTORY, "longitude"): (("sample",), "degree"),
    (fmt.TRAJECTORY, "height"): (("sample",), "m"),
    (fmt.TRAJECTORY, "velocity"): (("sample", "enu"), "m s-1"),
    (fmt.TRAJECTORY, "attitude"): (("sample", "quaternion"), "1"),
    (fmt.TRAJECTORY, "heading"): (("sample",), "degree"),
    (fmt.TRAJECTORY, "pitch"): (("sample",), "degree"),
    (fmt.TRAJECTORY, "roll"): (("sample",), "degree"),
    (fmt.TRAJECTORY, "gnss_visible"): (("sample",), "1"),
    (fmt.TRAJECTORY, "leg"): (("leg",), "1"),
    (fmt.TRAJECTORY, "leg_t0"): (("leg",), "s"),
    (fmt.TRAJECTORY, "leg_t1"): (("leg",), "s"),
    (fmt.TRAJECTORY, "leg_label"): (("leg",), None),
    (fmt.TRAJECTORY, "leg_kind"): (("leg",), None),
    (fmt.TRAJECTORY, "leg_gnss"): (("leg",), "1"),
}


@pytest.fixture(scope="module")
def full_run(tmp_path_factory) -> pathlib.Path:
    tmp = tmp_path_factory.mktemp("optional")
    th = (ROOT / "scenarios" / "thermal" / "rlg_imu.toml").read_text()
    (tmp / "th.toml").write_text(th + THERMAL)
    dev = (ROOT / "scenarios" / "devices" / "rlg_imu_000.toml").read_text()
    dev = re.sub(r'(?m)^thermal_preset = ".*"', 'thermal_preset = "th.toml"', dev)
    assert 'thermal_preset = "th.toml"' in dev
    (tmp / "dev.toml").write_text(dev + ANOMALIES)
    (tmp / "sc.toml").write_text(SCENARIO)
    return simulate(load_scenario(str(tmp / "sc.toml")), tmp / "full.h5", progress=False)


def test_the_optional_names_cover_the_documented_ones():
    assert set(EXPECTED) == {(g, v) for g, names in fmt.OPTIONAL_VARIABLES.items()
                             for v in names}
    for group, names in fmt.OPTIONAL_VARIABLES.items():
        assert not set(names) & set(fmt.VARIABLES.get(group, ())), group
    assert fmt.ANOMALIES not in fmt.VARIABLES and fmt.ANOMALIES in DESCRIPTIONS


def test_every_part_on_writes_exactly_variables_and_the_optional_ones(full_run):
    with open_dataset(full_run) as ds:
        assert ds.groups() == [*fmt.VARIABLES, fmt.ANOMALIES]
        for group in ds.groups():
            assert ds.group_attrs(group)["description"] == DESCRIPTIONS[group]
            info = {v.name: v for v in ds.variables(group)}
            assert tuple(info) == (fmt.VARIABLES.get(group, ())
                                   + fmt.OPTIONAL_VARIABLES.get(group, ())), group
            for name in fmt.OPTIONAL_VARIABLES.get(group, ()):
                v = info[name]
                assert v.description, (group, name)
                assert (v.dims, v.units) == EXPECTED[group, name], (group, name)
        # the parts are really there: one heater and one boundary on the thermal grid, lost
        # frames flagged, their events recorded
        n_time = ds.length(fmt.THERMAL, "time")
        assert ds.strings(fmt.THERMAL, "heater") == ["thermostat"]
        assert ds.strings(fmt.THERMAL, "boundary") == ["lab"]
        power = ds.read(fmt.THERMAL, "heater_power")
        assert power.shape == (n_time, 1) and 0.0 < power.max() <= 10.0
        np.testing.assert_allclose(ds.read(fmt.THERMAL, "boundary_temperature"), 23.0)
        valid = ds.read(fmt.IMU, "sample_valid")
        assert valid.dtype == np.int8 and valid.shape == (ds.length(fmt.IMU, "gyro_pulses"),)
        kinds = ds.strings(fmt.ANOMALIES, "kind")
        assert "imu_dropout" in kinds and "pulse_spike" in kinds
        assert 0 < np.count_nonzero(valid == 0) < valid.size
