"""The dataset format and its one reader (src/rlgsim/ground/dataset_format.py).

References: the arrays written with the writer of sim/writer/dataset.py and read back with h5py
directly; files that are not rlgsim datasets (or of another version) must give one line.
"""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

import rlgsim
from rlgsim.ground import dataset_format as fmt
from rlgsim.ground.dataset_format import MissingVariableError, open_dataset
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.writer.dataset import DatasetWriter, add_group


@pytest.fixture()
def small(tmp_path):
    """A small dataset: a timeline, probes on a 1 s grid, pulses at 10 Hz, a truth table."""
    path = tmp_path / "small.h5"
    rng = np.random.default_rng(3)
    segs = [(0.0, 30.0, "turntable", "P01", {"kind": "static", "window": 0}),
            (30.0, 60.0, "turntable", "R01", {"kind": "rotate", "axis": "outer"}),
            (0.0, 60.0, "calibration", "calibration window 0", {"window": 0})]
    with DatasetWriter(path, {"seed": np.int64(7), "latitude_deg": 34.0,
                              "device_text": "[gyro]\n"}) as w:
        g = w.group(fmt.TIMELINE, "segments")
        g.coordinate("segment", np.arange(3, dtype=np.int32), units="1", dtype=np.int32,
                     description="index")
        g.variable("t0", ("segment",), units="s", data=[s[0] for s in segs], description="a")
        g.variable("t1", ("segment",), units="s", data=[s[1] for s in segs], description="b")
        for k, name in ((2, "track"), (3, "label")):
            g.variable(name, ("segment",), dtype=str, data=[s[k] for s in segs],
                       description=name)
        g.variable("attrs", ("segment",), dtype=str, data=[json.dumps(s[4]) for s in segs],
                   description="json")
        p = w.group(fmt.PROBES, "probes")
        p.coordinate("time", growing=True, units="s", description="t")
        p.coordinate("probe", ["g.A", "housing"], description="probe")
        p.variable("temperature", ("time", "probe"), units="degC", description="T")
        p.append("time", {"time": np.arange(1.0, 61.0),
                          "temperature": 20.0 + rng.normal(size=(60, 2))})
        imu = w.group(fmt.IMU, "imu", attrs={"sample_rate_hz": 10.0})
        imu.dimension("sample")
        imu.coordinate("gyro", ["x", "y", "z"], description="axis")
        imu.variable("gyro_pulses", ("sample", "gyro"), units="1", dtype=np.int32,
                     description="pulses")
        imu.append("sample", {"gyro_pulses": rng.integers(-50, 50, (600, 3)).astype(np.int32)})
        tr = w.group(fmt.TRUTH, "truth")
        tr.coordinate("coefficient", ["gyro.k0[x]", "gyro.bias.c1[x]"], description="c")
        tr.variable("coefficient_value", ("coefficient",), data=[1.5e5, 2e-3], description="v")
    return path


def test_reader_reads_what_was_written(small):
    with h5py.File(small) as f:
        pulses = f["imu/gyro_pulses"][...]
        temps = f["probes/temperature"][...]
    with open_dataset(small) as ds:
        assert ds.version == fmt.FORMAT_VERSION
        assert ds.attrs["seed"] == 7 and isinstance(ds.attrs["seed"], int)
        assert ds.attrs["device_text"] == "[gyro]\n"
        assert ds.groups() == [fmt.TIMELINE, fmt.PROBES, fmt.IMU, fmt.TRUTH]
        assert ds.has(fmt.IMU) and ds.has(fmt.IMU, "gyro_pulses")
        assert not ds.has(fmt.IMU, "accel_pulses") and not ds.has(fmt.THERMAL)
        assert ds.group_attrs(fmt.IMU)["sample_rate_hz"] == 10.0
        np.testing.assert_array_equal(ds.read(fmt.IMU, "gyro_pulses"), pulses)
        np.testing.assert_array_equal(ds.read(fmt.IMU, "gyro_pulses", slice(100, 250), 1),
                                      pulses[100:250, 1])
        np.testing.assert_array_equal(ds.read(fmt.PROBES, "temperature", columns=[0, 1]), temps)
        assert ds.length(fmt.IMU, "gyro_pulses") == 600
        # blocks of rows cover the variable exactly once, in order
        blocks = list(ds.read_blocks(fmt.IMU, "gyro_pulses", 256, columns=2))
        assert [k0 for k0, _ in blocks] == [0, 256, 512]
        np.testing.assert_array_equal(np.concatenate([b for _, b in blocks]), pulses[:, 2])
        assert [len(b) for _, b in ds.read_blocks(fmt.IMU, "gyro_pulses", 7, start=3,
                                                  stop=20)] == [7, 7, 3]
        assert ds.strings(fmt.PROBES, "probe") == ["g.A", "housing"]
        # rows whose step ends in (t0, t1]
        sl = ds.time_rows(fmt.PROBES, 10.0, 20.0)
        np.testing.assert_array_equal(ds.read(fmt.PROBES, "time", sl), np.arange(11.0, 21.0))
        segs = ds.segments()
        assert [s["label"] for s in segs] == ["P01", "R01", "calibration window 0"]
        assert segs[1] == dict(t0=30.0, t1=60.0, track="turntable", label="R01",
                               attrs={"kind": "rotate", "axis": "outer"})
        assert [s["label"] for s in ds.segments("calibration")] == ["calibration window 0"]
        assert ds.coefficients() == {"gyro.k0[x]": 1.5e5, "gyro.bias.c1[x]": 2e-3}
        info = {v.name: v for v in ds.variables(fmt.PROBES)}
        assert info["temperature"].dims == ("time", "probe")
        assert info["temperature"].units == "degC" and info["probe"].units is None
        assert info["time"].is_coordinate and not info["temperature"].is_coordinate


def test_missing_variable_is_one_line_and_a_key_error(small):
    with open_dataset(small) as ds:
        for group, name in ((fmt.IMU, "uhfo"), (fmt.THERMAL, "time")):
            with pytest.raises(MissingVariableError) as err:
                ds.read(group, name)
            assert isinstance(err.value, KeyError) and isinstance(err.value, UserInputError)
            assert str(err.value).startswith(f"{small}: the dataset has no ")
            assert "\n" not in str(err.value)
        with pytest.raises(KeyError):
            ds.group_attrs(fmt.THERMAL)


def _plain_h5(path, **attrs):
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)
        f.attrs.update(attrs)
    return path


@pytest.mark.parametrize("attrs, message", [
    ({}, "not an rlgsim dataset (HDF5 file without the rlgsim_format"),
    ({"rlgsim_format": "netCDF"}, "not an rlgsim dataset"),
    ({"rlgsim_format": "rlgsim dataset"}, "without a valid rlgsim_format_version"),
    ({"rlgsim_format": "rlgsim dataset", "rlgsim_format_version": "one"},
     "without a valid rlgsim_format_version"),
    ({"rlgsim_format": "rlgsim dataset", "rlgsim_format_version": 0}, "version 0 is not valid"),
    ({"rlgsim_format": "rlgsim dataset", "rlgsim_format_version": fmt.FORMAT_VERSION + 1},
     f"version {fmt.FORMAT_VERSION + 1} is newer than this rlgsim reads"),
])
def test_bad_marker_or_version_is_a_one_line_user_error(tmp_path, attrs, message):
    path = _plain_h5(tmp_path / "f.h5", **attrs)
    with pytest.raises(UserInputError) as err:
        open_dataset(path)
    text = str(err.value)
    assert message in text and text.startswith(str(path)) and "\n" not in text
    # the file was closed again: it can be opened for writing
    with h5py.File(path, "r+"):
        pass


def test_not_a_file_is_a_user_error(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    for path, message in ((tmp_path / "notes.txt", "not an HDF5 file"),
                          (tmp_path / "missing.h5", "no such file"),
                          (tmp_path, "is a directory")):
        with pytest.raises(UserInputError, match=message):
            open_dataset(path)


def test_public_entry_point_and_add_group(small):
    assert rlgsim.open_dataset is open_dataset
    with add_group(small, fmt.CALIBRATION, "added", {"k": 2.0}) as g:
        g.coordinate("window", np.arange(2, dtype=np.int32), units="1", dtype=np.int32,
                     description="w")
    with pytest.raises(RuntimeError):
        with add_group(small, fmt.CALIBRATION, "replaced") as g:
            raise RuntimeError("interrupted")
    with open_dataset(small) as ds:            # the interrupted write left the group alone
        assert ds.groups()[-1] == fmt.CALIBRATION
        assert ds.group_attrs(fmt.CALIBRATION) == {"description": "added", "k": 2.0}
        np.testing.assert_array_equal(ds.read(fmt.CALIBRATION, "window"), [0, 1])
