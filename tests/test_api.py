"""The public Python API (src/rlgsim/api.py, docs/api.md): changed scenarios whose text matches,
runs into memory, DataTree views with a time coordinate on every group, window tables of a
dataset and of its exported recording, compensators on DataFrames, the cluster extra."""

from __future__ import annotations

import sys
import tomllib

import numpy as np
import pandas as pd
import pytest

import rlgsim
from rlgsim.ground.errors import UserInputError

SHORT = {"duration_min": 20, "acquisition.sample_rate_hz": 10}


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    d = tmp_path_factory.mktemp("api")
    sc = rlgsim.with_changes(rlgsim.load_scenario("demo_cycle"), SHORT)
    path = d / "short.h5"
    rlgsim.run(sc, path).close()
    return sc, path


def test_with_changes_text_matches_and_validates():
    sc = rlgsim.load_scenario("quickstart")
    ch = sc.with_changes({"chamber.segments[1].to_c": 35.0, "site.latitude_deg": 40.0},
                         seed=3, duration_h=None)
    assert tomllib.loads(ch.text) == ch.tables
    assert ch.tables["chamber"]["segments"][1]["to_c"] == 35.0 and ch.seed == 3
    assert ch.site.latitude_deg == 40.0
    assert "duration_h" not in ch.tables and ch.duration_s != sc.duration_s   # programme length
    assert sc.tables["chamber"]["segments"][1]["to_c"] == 40.0               # original intact
    assert rlgsim.with_changes(sc, {"chamber.segments[1].to_c": 35.0}).tables[
        "chamber"]["segments"][1] == {"type": "ramp", "to_c": 35.0, "rate_c_per_min": 1.0}
    with pytest.raises(UserInputError, match="start_cc: unknown key"):
        sc.with_changes({"chamber.start_cc": 3})
    with pytest.raises(UserInputError, match="no element"):
        sc.with_changes({"chamber.segments[9].to_c": 3})


def test_with_changes_keeps_the_comments_of_the_original(tmp_path):
    text = rlgsim.load_scenario("quickstart").text.replace(
        "start_c = 20.0", "start_c = 20.0  # the soak temperature\n# a note of the user")
    path = tmp_path / "mine.toml"
    path.write_text(text)
    ch = rlgsim.load_scenario(str(path)).with_changes({"chamber.start_c": 22.5, "seed": 5})
    assert tomllib.loads(ch.text) == ch.tables and ch.chamber.start_c == 22.5
    assert "start_c = 22.5  # the soak temperature\n# a note of the user\n" in ch.text
    assert "# The quickstart scenario" in ch.text                 # the file's own header
    assert ch.text.startswith("# scenario quickstart, from ")
    assert "with chamber.start_c = 22.5, seed = 5\n" in ch.text


def test_run_in_memory_and_tree_times(short, tmp_path, monkeypatch):
    sc, path = short
    monkeypatch.chdir(tmp_path)
    tree = rlgsim.run(sc)                         # into memory: no file left behind
    assert list(tmp_path.iterdir()) == []
    imu = tree["imu"]
    n = imu.sizes["sample"]
    assert n == 12000
    np.testing.assert_allclose(imu["sample_time"].values, (np.arange(n) + 1) / 10.0,
                               rtol=1e-15, atol=1e-12)
    for name, node in tree.children.items():     # a time coordinate on every group
        assert (any(c in node.coords for c in ("time", "sample_time", "t0"))
                or (name == "anomalies" and "time" in node.data_vars)), name   # event record
    assert "details" in tree["timeline"] and "attrs" not in tree["timeline"].data_vars
    lazy = rlgsim.open_tree(path)
    np.testing.assert_array_equal(lazy["imu"]["gyro_pulses"].values,
                                  tree["imu"]["gyro_pulses"].values)
    lazy.close()


def test_dataset_trees_resample_on_a_lazy_timedelta_twin_of_sample_time(short):
    _, path = short
    with rlgsim.open_tree(path) as tree:
        imu = tree["imu"].to_dataset()
        n, f = imu.sizes["sample"], 10.0
        el = imu["sample_elapsed"]
        assert el.dtype == np.dtype("timedelta64[ns]") and imu["sample_time"].dtype == float
        np.testing.assert_array_equal(el[[0, n - 1]].values.astype(np.int64),
                                      np.round(np.array([1.0, n]) / f * 1e9).astype(np.int64))
        per_min = imu["gyro_pulses"].resample(sample_elapsed="60s").sum()
        g = imu["gyro_pulses"].values
        m = int(60 * f)                       # a bin: the samples ending in [k·60 + 1/f, ...)
        np.testing.assert_array_equal(per_min.values[:3], g[:3 * m].reshape(3, m, -1).sum(1))
        probes = tree["probes"].to_dataset()
        assert probes["elapsed"].dtype == np.dtype("timedelta64[ns]")
        assert probes.resample(elapsed="10min").mean().sizes["elapsed"] > 1


def test_window_table_dataset_vs_recording_and_independent(short, tmp_path):
    _, path = short
    df = rlgsim.window_table(path)
    assert len(df) == 12 and df["time_s"].iloc[-1] == 1200.0
    # independent: window 3 from the raw pulses, K from the preset, the truth's Earth rate
    import h5py
    with h5py.File(path, "r") as f:
        p = f["imu/gyro_pulses"][3000:4000, 0].astype(float)
        k = 2.14 / (np.pi / 180 / 3600)
        dth = f["truth/dtheta_step"][300:400, 2].sum()
        temp = f["probes/temperature"][300:400, 0].mean()
    bias = (p.sum() / (k * 100.0) - dth / 100.0) * 180 / np.pi * 3600
    assert df["bias_deg_per_h"][3] == pytest.approx(bias, rel=1e-9)
    assert df["probe_g.A_c"][3] == pytest.approx(temp, rel=1e-12)
    out = rlgsim.export(path, "parquet", tmp_path / "short.parquet")
    rec = rlgsim.window_table(out.table)
    assert "true_bias_deg_per_h" not in rec.columns
    for c in rec.columns:
        np.testing.assert_allclose(rec[c], df[c], rtol=1e-12, atol=1e-12, err_msg=c)
    tree = rlgsim.open_tree(out.table)
    assert set(tree.children) == {"imu", "probes", "thermal", "turntable"}
    np.testing.assert_array_equal(tree["probes"]["time"].values, np.arange(1, 1201.0))


def test_compensator_on_dataframe_prints_column_names():
    from rlgsim.estimators.stepwise import StepwiseRegressor
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"probe_A_c": rng.normal(20, 5, 300), "uhfo_v": rng.normal(4, 0.1, 300)})
    y = 0.01 * df["probe_A_c"] - 0.2 * df["uhfo_v"] + rng.normal(0, 1e-4, 300)
    m = StepwiseRegressor().fit(df, y)
    assert "probe_A_c" in m.equation() and "uhfo_v" in m.equation()
    np.testing.assert_allclose(m.predict(df[["uhfo_v", "probe_A_c"]]), m.predict(df))
    with pytest.raises(ValueError, match="lacks the input"):
        m.predict(df[["uhfo_v"]])
    s = rlgsim.score(y, m.predict(df))
    assert s["rmse"] < 2e-4 and s["r2"] > 0.999


def test_scheduler_without_the_cluster_extra(monkeypatch, capsys):
    from rlgsim.lab.cli.montecarlo import connect
    monkeypatch.setitem(sys.modules, "distributed", None)        # as if not installed
    with pytest.raises(UserInputError, match=r"pip install 'rlgsim\[cluster\]'"):
        connect("tcp://127.0.0.1:8786")


def test_public_modules_declare_all():
    import importlib
    for mod in ("rlgsim.api", "rlgsim.ground.recording", "rlgsim.ground.recording_export",
                "rlgsim.ground.programme", "rlgsim.ground.datatree", "rlgsim.lab.recordings",
                "rlgsim.sim.run.scenario_changes", "rlgsim.estimators.recording_calibration",
                "rlgsim.sim.run.scenario", "rlgsim.sim.run.simulate", "rlgsim.lab.study",
                "rlgsim.ground.dataset_format", "rlgsim.ground.errors",
                "rlgsim.estimators.polynomial", "rlgsim.estimators.stepwise",
                "rlgsim.estimators.mlr", "rlgsim.estimators.lssvm",
                "rlgsim.estimators.robust_lssvm", "rlgsim.estimators.rvr",
                "rlgsim.estimators.rbf_network", "rlgsim.estimators.rbf_modified",
                "rlgsim.estimators.metrics", "rlgsim.estimators.columns",
                "rlgsim.estimators.calibration", "rlgsim.estimators.features"):
        m = importlib.import_module(mod)
        assert m.__all__ and all(hasattr(m, n) for n in m.__all__), mod
    for name in ("run", "open_tree", "with_changes", "window_table", "score", "calibrate",
                 "load_recording", "export"):
        assert callable(getattr(rlgsim, name))


def test_format_version_2_details_and_version_1_still_read(short, tmp_path):
    """The timeline's JSON details are 'details' (format 2); a version-1 file with 'attrs'
    reads to the same segments, tree and calibration windows."""
    import shutil

    import h5py

    from rlgsim.ground.dataset_format import FORMAT_VERSION, open_dataset
    _, path = short
    with h5py.File(path, "r") as f:
        assert int(f.attrs["rlgsim_format_version"]) == FORMAT_VERSION == 2
        assert "details" in f["timeline"] and "attrs" not in f["timeline"]
    old = tmp_path / "v1.h5"
    shutil.copy(path, old)
    with h5py.File(old, "r+") as f:
        f["timeline"].move("details", "attrs")
        f.attrs["rlgsim_format_version"] = 1
    with open_dataset(path) as a, open_dataset(old) as b:
        assert b.version == 1 and a.segments() == b.segments() and len(a.segments()) > 0
    t_old, t_new = rlgsim.open_tree(old, load=True), rlgsim.open_tree(path, load=True)
    np.testing.assert_array_equal(t_old["timeline"]["details"].values,
                                  t_new["timeline"]["details"].values)


def test_calibrate_api_uses_the_cli_filter_settings(tmp_path):
    """rlgsim.calibrate and `rlgsim calibrate` give the same table: one derivation of the
    filter settings from the device's noise levels (filter_settings)."""
    from _turntable_pulses import random_truth, write_dataset
    from rlgsim.estimators.calibration import (CampaignSettings, DatasetReader, _filter_settings,
                                               filter_settings)
    from rlgsim.lab.cli.main import main
    from rlgsim.sim.motion.turntable import TurntableProgram
    prog = TurntableProgram.calibration19(dwell_s=20.0, first_dwell_s=30.0)
    h5 = tmp_path / "run.h5"
    write_dataset(h5, random_truth(np.random.default_rng(5)), prog, prog.duration_s,
                  arw_deg_sqrt_h=0.003, vrw_ug_sqrt_hz=20.0, seed=2)
    reader = DatasetReader(h5)
    fs = filter_settings(reader.noise())
    assert fs.arw_rad_per_sqrt_s[0] == pytest.approx(0.003 * np.pi / 180 / 60)
    assert fs.vrw_m_per_s_per_sqrt_s[0] == pytest.approx(20.0 * 9.80665e-6)
    np.testing.assert_array_equal(_filter_settings(reader, CampaignSettings()).arw_rad_per_sqrt_s,
                                  fs.arw_rad_per_sqrt_s)
    reader.close()
    api = rlgsim.calibrate(h5)
    assert main(["calibrate", str(h5), "-o", str(tmp_path / "cli.csv"), "-q", "--workers", "1",
                 "--no-dataset"]) == 0
    cli = pd.read_csv(tmp_path / "cli.csv")
    assert list(api["status"]) == list(cli["status"]) == ["ok"]
    for c in ("gyro_bias_x_deg_per_h", "gyro_bias_y_deg_per_h", "gyro_sf_z_ppm",
              "accel_bias_x_ug", "gyro_bias_y_sigma_deg_per_h", "gyro_bias_x_true_deg_per_h"):
        np.testing.assert_allclose(api[c].astype(float), cli[c], rtol=1e-6, err_msg=c)
