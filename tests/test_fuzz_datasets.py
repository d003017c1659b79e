"""Damaged datasets (issue 15): a bad format version, a non-finite or disordered timeline, a
malformed JSON segment attribute, NaN probe readings in a dataset a study reuses — every reader
(``rlgsim info``, ``rlgsim calibrate``, the studies) answers with one line naming the file and
what is wrong, exit code 2, never a traceback; a hypothesis fuzz of root attributes and
timeline values through the one reader."""

from __future__ import annotations

import pathlib
import shutil

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rlgsim.ground.dataset_format import open_dataset
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.main import main
from scenario_helpers import CAL_SCENARIO, one_line, tiny_study



@pytest.fixture(scope="module")
def good(tmp_path_factory) -> pathlib.Path:
    folder = tmp_path_factory.mktemp("ds")
    (folder / "cal.toml").write_text(CAL_SCENARIO)
    assert main(["run", str(folder / "cal.toml"), "-o", str(folder / "cal.h5"), "-q"]) == 0
    return folder / "cal.h5"


def damaged(good: pathlib.Path, tmp_path: pathlib.Path, change) -> pathlib.Path:
    path = tmp_path / "bad.h5"
    shutil.copy(good, path)
    with h5py.File(path, "r+") as f:
        change(f)
    return path


def _set_attr(key, value):
    def change(f):
        f.attrs[key] = value
    return change


def _timeline(name, fn):
    def change(f):
        ds = f["timeline"][name]
        values = ds[...]
        fn(values)
        ds[...] = values
    return change


def _details(f) -> str:
    return "details" if "details" in f["timeline"] else "attrs"


def _bad_json(f):
    ds = f["timeline"][_details(f)]
    values = ds.asstr()[...].astype(object)
    values[2] = '{"kind": "static", '
    ds[...] = values


def _json_list(f):
    ds = f["timeline"][_details(f)]
    values = ds.asstr()[...].astype(object)
    values[1] = "[1, 2]"
    ds[...] = values


CASES = {
    "version abc": (_set_attr("rlgsim_format_version", "abc"), "rlgsim_format_version"),
    "version 99": (_set_attr("rlgsim_format_version", 99), "version 99"),
    "version 0": (_set_attr("rlgsim_format_version", 0), "version"),
    "nan t0": (_timeline("t0", lambda v: v.__setitem__(slice(None), np.nan)), "timeline/t0"),
    "one nan t0": (_timeline("t0", lambda v: v.__setitem__(3, np.nan)), "timeline/t0"),
    "t1 before t0": (_timeline("t1", lambda v: v.__setitem__(2, -5.0)), "timeline/t1"),
    "malformed json": (_bad_json, "JSON"),
    "json not an object": (_json_list, "JSON"),
    "nan duration": (_set_attr("duration_s", np.nan), "duration_s"),
    "rate -1": (_set_attr("sample_rate_hz", -1.0), "sample_rate_hz"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_info_and_calibrate_on_damaged_datasets(good, tmp_path, capsys, case):
    change, needle = CASES[case]
    bad = damaged(good, tmp_path, change)
    line = one_line(capsys, ["calibrate", str(bad), "-o", str(tmp_path / "t.csv"), "-q",
                             "--workers", "1"])
    assert "bad.h5" in line and needle in line, line
    assert not (tmp_path / "t.csv").exists()
    # info lists the variables without decoding the timeline: it may succeed, never crash
    code = main(["info", str(bad)])
    err = capsys.readouterr().err
    assert code in (0, 2) and "Traceback" not in err, err
    if code == 2:
        assert len(err.strip().splitlines()) == 1 and needle in err, err


def test_study_reusing_a_dataset_with_nan_probe_readings(tmp_path, capsys):
    # the short cycle's study (two ~100-min runs, one fit): a reused dataset's check is the same
    # whatever the study's size (the demo's two 8-h runs cost seconds of the suite, issue 30)
    study = tiny_study(tmp_path / "study")
    out = tmp_path / "tiny"
    assert main(["study", str(study), "-o", str(out), "-q"]) == 0
    data = sorted((out / "data").glob("*.h5"))[0]
    with h5py.File(data, "r+") as f:
        t = f["probes/temperature"]
        row = t[10]
        row[:] = np.nan
        t[10] = row
    (out / "report.md").unlink()
    line = one_line(capsys, ["study", str(study), "-o", str(out), "-q"])
    assert data.name in line and "probes/temperature" in line, line
    assert not (out / "report.md").exists()


ATTRS = ["rlgsim_format_version", "duration_s", "thermal_step_s", "sample_rate_hz", "seed",
         "block_s", "software_version"]
VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**62, 2**62),
                   # HDF5 cannot store a NUL in a string attribute (h5py refuses
                   # it while the test damages the file): any other text
                   st.text(max_size=8).filter(lambda v: "\x00" not in v), st.just(b"\xff\xfe"))


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(key=st.sampled_from(ATTRS), value=VALUES, row=st.integers(0, 5),
       t=st.floats(allow_nan=True, allow_infinity=True))
def test_fuzzed_root_attrs_and_timeline_through_the_reader(good, tmp_path, key, value, row, t):
    def change(f):
        f.attrs[key] = value
        ds = f["timeline/t0"]
        v = ds[...]
        v[min(row, v.size - 1)] = t
        ds[...] = v
    bad = damaged(good, tmp_path, change)
    try:
        with open_dataset(bad) as ds:
            ds.segments()
    except UserInputError as exc:
        assert "\n" not in str(exc)
