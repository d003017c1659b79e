"""Recordings (docs/recordings.md): a CSV recording built by hand with numpy/pandas (never
through rlgsim's exporter) through ``rlgsim info`` and ``rlgsim calibrate``, checked against
independent computations; export → import round trips; bad recordings give one line, exit 2."""

from __future__ import annotations

import csv
import json
import math

import h5py
import numpy as np
import pandas as pd
import pytest

from _turntable_pulses import random_truth, write_dataset
from rlgsim.ground.recording import load_recording
from rlgsim.lab.cli.main import main
from rlgsim.sim.motion.turntable import TurntableProgram
from scenario_helpers import demo_on_tiny_cycle

PROG = TurntableProgram.calibration19(dwell_s=20.0, first_dwell_s=30.0)
RATE = 100.0
SIDECAR = """\
[recording]
sample_rate_hz = 100
temperature_rate_hz = 1

[site]
latitude_deg = 34.0

[gyro]
axes = ["x", "y", "z"]
scale_factor_pulses_per_arcsec = 2.14

[accelerometer]
axes = ["x", "y", "z"]
scale_factor_pulses_per_s_per_g = 5000.0

[noise]
gyro_arw_deg_per_sqrt_h = 0.002
accel_vrw_ug_per_sqrt_hz = 10.0
"""


@pytest.fixture(scope="module")
def hand(tmp_path_factory):
    """A turntable run of a device with known errors (the test helper's measurement
    equations), as an rlgsim-layout HDF5 file and as a CSV recording + sidecar + programme
    written by hand from the same pulses."""
    d = tmp_path_factory.mktemp("rec")
    truth = random_truth(np.random.default_rng(21))
    h5 = d / "run.h5"
    write_dataset(h5, truth, PROG, 2 * PROG.duration_s, arw_deg_sqrt_h=0.002,
                  vrw_ug_sqrt_hz=10.0, seed=4)
    with h5py.File(h5, "r") as f:
        ng, na = f["imu/gyro_pulses"][()], f["imu/accel_pulses"][()]
        temps = f["probes/temperature"][()]
        tl = f["timeline"]
        segs = [(float(a), float(b), t.decode(), lab.decode(), json.loads(x))
                for a, b, t, lab, x in zip(tl["t0"][()], tl["t1"][()], tl["track"][()],
                                           tl["label"][()], tl["attrs"][()])]
    n = len(ng)
    df = pd.DataFrame({"time_s": np.arange(1, n + 1) / RATE})
    for i, a in enumerate("xyz"):
        df[f"gyro_{a}_pulses"] = ng[:, i]
    for i, a in enumerate("xyz"):
        df[f"accel_{a}_pulses"] = na[:, i]
    for j, name in enumerate(("gx", "ax")):           # 1 Hz probes: empty cells in between
        v = np.full(n, np.nan)
        v[int(RATE) - 1::int(RATE)] = temps[:, j]
        df[f"probe_{name}_c"] = v
    df.to_csv(d / "rec.csv", index=False)
    (d / "rec.toml").write_text(SIDECAR)
    with open(d / "prog.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t0_s", "t1_s", "kind", "axis", "rate_deg_per_s", "outer_deg", "inner_deg",
                    "position", "window", "label"])
        for a, b, track, label, x in segs:
            if track == "turntable":
                w.writerow([a, b, x["kind"], x["axis"] or "", x["rate_deg_s"], x["outer_deg"],
                            x["inner_deg"], -1 if x["position"] is None else x["position"],
                            x["window"], label])
    windows = [(a, b) for a, b, track, _, _ in segs if track == "calibration"]
    return dict(dir=d, h5=h5, csv=d / "rec.csv", prog=d / "prog.csv", truth=truth, ng=ng,
                na=na, temps=temps, windows=windows, df=df)


def test_info_of_a_hand_made_recording(hand, capsys):
    assert main(["info", str(hand["csv"])]) == 0
    out = capsys.readouterr().out
    assert f"samples: {len(hand['ng'])} at 100 Hz" in out
    assert "temperature rate: 1 Hz (942 readings)" in out
    # independent: mean rate = pulses / (K · Δt), K = 2.14 pulses/arcsec, in °/h
    rate = hand["ng"][:, 1] / (2.14 * (1 / RATE)) * 1.0          # arcsec/s
    line = next(s for s in out.splitlines() if s.strip().startswith("gyro_y_pulses"))
    mean = float(line.split("mean rate ")[1].split(" deg/h")[0])
    assert mean == pytest.approx(np.mean(rate) * 3600 / 3600, rel=1e-5)   # arcsec/s == °/h
    line = next(s for s in out.splitlines() if s.strip().startswith("probe_ax_c"))
    assert float(line.split("mean ")[1].split(",")[0]) == pytest.approx(hand["temps"][:, 1].mean(),
                                                                       rel=1e-5)


def test_calibrate_a_recording_with_its_programme(hand, tmp_path, capsys):
    out = tmp_path / "rec_cal.csv"
    assert main(["calibrate", str(hand["csv"]), "--programme", str(hand["prog"]), "-o",
                 str(out), "-q", "--workers", "1"]) == 0
    rec = pd.read_csv(out)
    assert list(rec["status"]) == ["ok", "ok"]
    # independent: the device's true parameters (drawn by the test), inside 5σ of the filter
    truth = hand["truth"]
    for i, a in enumerate("xyz"):
        est = rec[f"gyro_bias_{a}_deg_per_h"].to_numpy()
        sig = rec[f"gyro_bias_{a}_sigma_deg_per_h"].to_numpy()
        true = truth.d_g[i] / (math.pi / 180 / 3600)
        assert np.all(np.abs(est - true) < 5 * sig + 1e-3), (a, est, true, sig)
        est_sf = rec[f"gyro_sf_{a}_pulse_per_arcsec"].to_numpy()
        assert np.all(np.abs(est_sf / (truth.k_g[i] * math.pi / 180 / 3600) - 1) < 2e-5)
    # the window's mean probe reading: rows whose 1-s step ends in (t0, t1]
    t = np.arange(1, len(hand["temps"]) + 1, dtype=float)
    for w, (t0, t1) in enumerate(hand["windows"]):
        sel = (t > t0) & (t <= t1)
        assert rec["temp_gx_c"][w] == pytest.approx(hand["temps"][sel, 0].mean(), rel=1e-12)
    # the same pulses as a dataset: the same windows and filter settings, so the same numbers
    # (to 1e-6: the first campaign in a process differs from later ones by ~1e-8 relative)
    ds_out = tmp_path / "ds_cal.csv"
    assert main(["calibrate", str(hand["h5"]), "-o", str(ds_out), "-q", "--workers", "1",
                 "--no-dataset"]) == 0
    ds = pd.read_csv(ds_out)
    for c in ("gyro_bias_x_deg_per_h", "gyro_bias_y_deg_per_h", "gyro_sf_z_ppm",
              "accel_bias_z_ug", "accel_sf_neg_x_ppm", "gyro_mis_xy_arcsec",
              "gyro_bias_y_sigma_deg_per_h", "temp_ax_c"):
        np.testing.assert_allclose(rec[c].to_numpy(), ds[c].to_numpy(), rtol=1e-6, atol=1e-12,
                                   err_msg=c)
    # a recording has no truth: no _true/_error columns at all (the dataset has them)
    assert not [c for c in rec.columns if c.endswith(("_true", "_error")) or "_true_" in c
                or "_error_" in c]
    assert "gyro_bias_x_true_deg_per_h" in ds.columns and "gyro_bias_x_error_deg_per_h" in ds


def test_calibrate_recording_needs_a_programme(hand, capsys):
    assert main(["calibrate", str(hand["csv"]), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--programme" in err


def test_export_recording_round_trip(hand, tmp_path, capsys):
    """CSV → Parquet → CSV gives identical arrays; exporting the dataset gives the pulses and
    probes of the hand-made table bit for bit, and calibrates to the same table."""
    pq = tmp_path / "again.parquet"
    assert main(["export", str(hand["csv"]), "--format", "parquet", "-o", str(pq), "-q"]) == 0
    a, b = load_recording(hand["csv"]), load_recording(pq)
    np.testing.assert_array_equal(a.time_s, b.time_s)
    assert a.columns.keys() == b.columns.keys()
    for k in a.columns:
        np.testing.assert_array_equal(a.columns[k], b.columns[k], err_msg=k)
    back = tmp_path / "back.csv"
    assert main(["export", str(pq), "--format", "csv", "-o", str(back), "-q"]) == 0
    c = load_recording(back)
    for k in a.columns:
        np.testing.assert_array_equal(a.columns[k], c.columns[k], err_msg=k)
    # the dataset exported: same table as the hand-made one
    ex = tmp_path / "ds.csv"
    assert main(["export", str(hand["h5"]), "-o", str(ex)]) == 0
    assert "programme:" in capsys.readouterr().out
    e = load_recording(ex)
    np.testing.assert_array_equal(e.time_s, a.time_s)
    np.testing.assert_array_equal(e.gyro_pulses(), hand["ng"])
    np.testing.assert_array_equal(e.accel_pulses(), hand["na"])
    np.testing.assert_array_equal(e.probes()[1], hand["temps"])


def test_export_simulated_dataset_round_trip(tmp_path, capsys):
    """A simulated run (single gyro with UHFO) → CSV and Parquet → the dataset's arrays."""
    scen = tmp_path / "short.toml"
    scen.write_text('name = "short"\ndevice = "trplg_001"\nseed = 5\nduration_min = 10\n'
                    '[acquisition]\nsample_rate_hz = 10\n[chamber]\nstart_c = 20.0\n'
                    '[[chamber.segments]]\ntype = "ramp"\nto_c = 30.0\nrate_c_per_min = 1.0\n')
    h5 = tmp_path / "short.h5"
    assert main(["run", str(scen), "-o", str(h5), "-q"]) == 0
    # the second format's default name keeps the first export's sidecar (issue 29)
    for fmt, name in (("csv", "short_recording.csv"),
                      ("parquet", "short_recording_parquet.parquet")):
        assert main(["export", str(h5), "--format", fmt, "-q"]) == 0
        rec = load_recording(tmp_path / name)
        assert load_recording(tmp_path / "short_recording.csv").n_samples == rec.n_samples
        assert scen.read_text().startswith('name = "short"')      # the scenario is untouched
        with h5py.File(h5, "r") as f:
            n = f["imu/gyro_pulses"].shape[0]
            np.testing.assert_array_equal(rec.time_s, np.arange(1, n + 1) / 10.0)
            np.testing.assert_array_equal(rec.gyro_pulses(), f["imu/gyro_pulses"][()])
            t, temps = rec.probes()
            np.testing.assert_array_equal(t, f["probes/time"][()])
            np.testing.assert_array_equal(temps, f["probes/temperature"][()])
            ax = f["imu/gyro"][0].decode()
            np.testing.assert_array_equal(rec.slow(f"uhfo_{ax}_v")[1], f["imu/uhfo"][:, 0])
            np.testing.assert_array_equal(rec.slow("chamber_air_c")[1],
                                          f["thermal/chamber_air"][()])
        assert rec.sidecar.gyro_sf_pulse_per_arcsec == 2.14


# ----------------------------------------------------------------------------- bad input

def _bad(tmp_path, capsys, mutate, sidecar=SIDECAR.replace("temperature_rate_hz = 1\n", "")):
    rows = 50
    df = pd.DataFrame({"time_s": np.arange(1, rows + 1) / RATE,
                       "gyro_x_pulses": np.arange(rows), "gyro_y_pulses": np.zeros(rows),
                       "gyro_z_pulses": np.ones(rows), "accel_x_pulses": np.zeros(rows),
                       "accel_y_pulses": np.zeros(rows), "accel_z_pulses": np.full(rows, 500),
                       "probe_A_c": np.linspace(20, 21, rows)})
    df, sidecar = mutate(df, sidecar)
    path = tmp_path / "bad.csv"
    df.to_csv(path, index=False)
    (tmp_path / "bad.toml").write_text(sidecar)
    code = main(["info", str(path)])
    cap = capsys.readouterr()
    return code, cap.err, cap.out


def _set(col, row, value):
    def mutate(df, sc):
        df[col] = df[col].astype(object)
        df.loc[row, col] = value
        return df, sc
    return mutate


BAD = {
    "wrong unit": (lambda df, sc: (df.rename(columns={"probe_A_c": "probe_A_k"}), sc),
                   "column 'probe_A_k': unit or name not allowed; probe temperatures are in °C"),
    "rate unit": (lambda df, sc: (df.rename(columns={"gyro_x_pulses": "gyro_x_rate_mrad"}), sc),
                  "column 'gyro_x_rate_mrad': unit or name not allowed"),
    "missing time": (lambda df, sc: (df.drop(columns="time_s"), sc),
                     "column 'time_s' missing"),
    "missing axis": (lambda df, sc: (df.drop(columns="gyro_z_pulses"), sc),
                     "column 'gyro_z_pulses' (or a rate column) missing"),
    "not monotonic": (_set("time_s", 10, 0.05),
                      "column 'time_s', row 11: time 0.05 s after 0.1 s; time must increase"),
    "gap": (lambda df, sc: (df.drop(index=[20, 21]), sc),
            "column 'time_s', row 21: a gap of 0.03 s"),
    "NaN": (_set("probe_A_c", 7, float("nan")),
            "column 'probe_A_c', row 8: empty or NaN value not allowed; mark a missing reading "
            "with dropout = 1"),
    "text": (_set("gyro_y_pulses", 3, "abc"),
             "column 'gyro_y_pulses', row 4: value 'abc' not allowed; must be a number"),
    "Kelvin": (_set("probe_A_c", 5, 293.15),
               "column 'probe_A_c', row 6: value 293.15 not allowed; temperatures are in °C"),
    "fractional pulses": (_set("gyro_x_pulses", 2, 0.5),
                          "column 'gyro_x_pulses', row 3: value 0.5 not allowed; pulses are "
                          "whole counts"),
    "sidecar unknown key": (lambda df, sc: (df, sc.replace("latitude_deg", "latitude")),
                            "bad.toml: site.latitude: unknown key; allowed: height_m, "
                            "latitude_deg"),
    "sidecar no rate": (lambda df, sc: (df, sc.replace("sample_rate_hz = 100",
                                                       "description = 'x'")),
                        "bad.toml: recording.sample_rate_hz: missing"),
    "sidecar wrong rate": (lambda df, sc: (df, sc.replace("sample_rate_hz = 100",
                                                          "sample_rate_hz = 50")),
                           "the rows are 0.01 s apart (100 Hz) in 49 of 49 steps, but the sidecar's "
                           "sample_rate_hz = 50 needs 0.02 s; set [recording] sample_rate_hz"),
    "sidecar axes": (lambda df, sc: (df, sc.replace('axes = ["x", "y", "z"]\nscale_factor_pulses'
                                                    '_per_arcsec', 'axes = ["x", "y"]\nscale_'
                                                    'factor_pulses_per_arcsec')),
                     "column 'gyro_z_pulses': axis 'z' not allowed; the sidecar's [gyro] axes "
                     "are ['x', 'y']"),
    "sidecar syntax": (lambda df, sc: (df, sc + "\n[site\n"), "not a valid TOML sidecar"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_recordings_give_one_line_and_exit_2(tmp_path, capsys, case):
    mutate, expected = BAD[case]
    code, err, _ = _bad(tmp_path, capsys, mutate)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("rlgsim: error: ") and "Traceback" not in err
    assert expected in lines[0], lines[0]


def test_dropouts_are_recorded_as_such(tmp_path, capsys):
    def mutate(df, sc):
        df["dropout"] = 0
        df.loc[[10, 11, 12], "dropout"] = 1
        df["gyro_x_pulses"] = df["gyro_x_pulses"].astype(float)
        df.loc[[10, 11, 12], ["gyro_x_pulses", "probe_A_c"]] = np.nan
        return df, sc
    code, err, out = _bad(tmp_path, capsys, mutate)
    assert code == 0, err
    assert "dropouts: 3 sample(s) (0.03 s)" in out
    rec = load_recording(tmp_path / "bad.csv")
    assert rec.dropout.sum() == 3 and np.isnan(rec.gyro_pulses()[10, 0])


# ----------------------------------------------------------------------------- studies

def _single_gyro_csv(path, seed, hours=6.0):
    """A single-gyro recording made by hand: 10 Hz rate in °/h, 1 Hz probe and UHFO."""
    rng = np.random.default_rng(seed)
    f, n = 10.0, int(hours * 3600 * 10)
    t = np.arange(1, n + 1) / f
    T = 20.0 + 15.0 * np.sin(2 * np.pi * t / (hours * 3600)) + 0.2 * np.sin(t / 900.0)
    U = 4.0 + 0.01 * (T - 20.0) + 0.002 * np.sin(t / 1300.0)
    bias = 0.01 + 0.002 * (T - 20.0) + 1e-4 * (T - 20.0) ** 2 - 0.3 * (U - 4.0)
    earth = 7.292115e-5 * math.sin(math.radians(34.0)) * 180 / math.pi * 3600
    rate = earth + bias + rng.normal(0, 0.05, n)
    slow = np.full(n, np.nan)
    df = pd.DataFrame({"time_s": t, "gyro_z_rate_deg_per_h": rate})
    for name, v in (("probe_A_c", T), ("uhfo_v", U)):
        col = slow.copy()
        col[9::10] = v[9::10]
        df[name] = col
    df.to_csv(path, index=False)
    path.with_suffix(".toml").write_text('[recording]\nsample_rate_hz = 10\n'
                                         'temperature_rate_hz = 1\n[site]\nlatitude_deg = 34.0\n'
                                         '[gyro]\naxes = ["z"]\n')
    return t, rate - earth, T[9::10], U[9::10]


STUDY = """\
[study]
name = "hand"
recipe = "bias_compensation"
[data]
train = ["train.csv"]
test = ["test.csv"]
window_s = 100
[features]
temperature = "A"
uhfo = true
[[compensator]]
name = "LS cubic T"
kind = "polynomial"
inputs = ["T"]
params = { degree = 3 }
table = "Least squares"
[metrics]
cluster_s = 100
ddof = 1
"""


def test_study_on_hand_made_recordings(tmp_path, capsys):
    train = _single_gyro_csv(tmp_path / "train.csv", 1)
    test = _single_gyro_csv(tmp_path / "test.csv", 2)
    (tmp_path / "hand.toml").write_text(STUDY)
    out = tmp_path / "report"
    assert main(["study", str(tmp_path / "hand.toml"), "-o", str(out), "--quiet"]) == 0, \
        capsys.readouterr().err
    text = (out / "report.md").read_text()
    assert "Absent: the test run is a recording, which has no ground truth." in text
    assert "recording test.csv (no truth)" in text
    # independent: 100 s window means (1000 samples, 100 probe readings), numpy's cubic fit
    def windows(run):
        _, y, T, _ = run
        return y.reshape(-1, 1000).mean(axis=1), T.reshape(-1, 100).mean(axis=1)
    ytr, Ttr = windows(train)
    yte, Tte = windows(test)
    pred = np.polyval(np.polyfit(Ttr, ytr, 3), Tte)
    # a study of its own (no paper key): scores without paper columns (issue 29)
    row = pd.read_csv(out / "scores_least_squares.csv").iloc[0]
    assert row["before °/h"] == pytest.approx(np.std(yte, ddof=1), rel=1e-9)
    assert row["after °/h"] == pytest.approx(np.std(yte - pred, ddof=1), rel=1e-6)
    # a missing recording is one line, exit 2
    (tmp_path / "bad.toml").write_text(STUDY.replace("test.csv", "nope.csv"))
    assert main(["study", str(tmp_path / "bad.toml"), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "run 'nope.csv': no such recording" in err


def test_export_import_study_gives_the_datasets_paper_scores(tmp_path):
    """The demo study (every compensator and feature; on the 100-min tiny cycle rather than
    its two 8-h runs — the agreement does not depend on the length, the suite's time does) on
    its simulated datasets, and on the same runs exported as recordings (CSV and Parquet):
    every paper-style table agrees."""
    study = demo_on_tiny_cycle(tmp_path / "study")
    sim = tmp_path / "sim"
    assert main(["study", str(study), "-o", str(sim), "--quiet"]) == 0
    data = sim / "data"
    assert main(["export", str(data / "tiny_cycle-seed7001.h5"), "-o",
                 str(tmp_path / "train.csv"), "-q"]) == 0
    assert main(["export", str(data / "tiny_cycle-seed7002.h5"), "--format", "parquet", "-o",
                 str(tmp_path / "test.parquet"), "-q"]) == 0
    text = study.read_text()
    text = text.replace('train = [{ scenario = "tiny_cycle.toml", seed = 7001 }]',
                        'train = ["train.csv"]')
    text = text.replace('test = [{ scenario = "tiny_cycle.toml", seed = 7002 }]',
                        'test = ["test.parquet"]')
    assert 'train = ["train.csv"]' in text and 'test = ["test.parquet"]' in text
    (tmp_path / "rec.toml").write_text(text)
    rec = tmp_path / "rec"
    assert main(["study", str(tmp_path / "rec.toml"), "-o", str(rec), "--quiet"]) == 0
    tables = sorted(p.name for p in sim.glob("paper_*.csv"))
    assert tables and tables == sorted(p.name for p in rec.glob("paper_*.csv"))
    for name in tables + ["correlation.csv"]:
        a, b = pd.read_csv(sim / name), pd.read_csv(rec / name)
        assert list(a.columns) == list(b.columns)
        for c in a.columns:
            if "true b" in c:                       # the truth: absent from a recording
                assert b[c].isna().all()
            elif a[c].dtype.kind == "f":
                np.testing.assert_allclose(b[c], a[c], rtol=1e-9, err_msg=f"{name}: {c}")
            else:
                assert list(a[c]) == list(b[c]), (name, c)


def test_programme_from_the_scenario_equals_the_datasets(tmp_path):
    """--programme SCENARIO rebuilds exactly the dataset's turntable and calibration segments
    (and so does the exported programme CSV); calibrating with either gives the same table."""
    from rlgsim.ground.dataset_format import open_dataset
    from rlgsim.ground.programme import read_programme
    from rlgsim.lab.recordings import programme_segments
    scen = tmp_path / "tt.toml"
    scen.write_text('name = "tt"\ndevice = "rlg_imu_000"\nseed = 3\nduration_min = 42\n'
                    '[acquisition]\nsample_rate_hz = 10\n[chamber]\nstart_c = 20.0\n'
                    '[[chamber.segments]]\ntype = "hold"\nduration_min = 42\n'
                    '[turntable]\nprogram = "calibration19"\nrate_deg_s = 20.0\n')
    h5 = tmp_path / "tt.h5"
    assert main(["run", str(scen), "-o", str(h5), "-q"]) == 0
    with open_dataset(h5) as ds:
        want = [s for s in ds.segments() if s["track"] in ("turntable", "calibration")]
    assert programme_segments(scen) == want
    assert main(["export", str(h5), "-q"]) == 0
    csv_segs = read_programme(tmp_path / "tt_recording_programme.csv")
    key = lambda s: (s["track"], s["t0"])                                  # noqa: E731
    for a, b in zip(sorted(csv_segs, key=key), sorted(want, key=key)):
        assert (a["t0"], a["t1"], a["track"]) == (b["t0"], b["t1"], b["track"])
        for k in ("kind", "axis", "rate_deg_s", "outer_deg", "inner_deg", "window"):
            if a["track"] == "turntable":
                assert a["attrs"][k] == b["attrs"][k], (k, a, b)
    rec = tmp_path / "tt_recording.csv"
    for prog, out in ((scen, "a.csv"), (tmp_path / "tt_recording_programme.csv", "b.csv")):
        assert main(["calibrate", str(rec), "--programme", str(prog), "-o",
                     str(tmp_path / out), "-q", "--workers", "1"]) == 0
    a, b = pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv")
    assert list(a["status"]) == ["ok", "failed"]            # the second window is cut short
    np.testing.assert_allclose(a["gyro_bias_z_deg_per_h"], b["gyro_bias_z_deg_per_h"], rtol=1e-6)


def test_hdf5_and_parquet_tables_of_other_tools_with_column_mapping(tmp_path):
    n = 200
    t = np.arange(1, n + 1) / 10.0
    temp = np.linspace(20, 25, n)
    with h5py.File(tmp_path / "log.h5", "w") as f:
        g = f.create_group("log")
        g["Zeit"] = t
        g["T1"] = temp
        g["rate"] = np.full(n, 12.5)
        g["comment"] = np.zeros(n)
    (tmp_path / "log.toml").write_text(
        '[recording]\nsample_rate_hz = 10\nhdf5_group = "/log"\nignore_columns = ["comment"]\n'
        '[gyro]\naxes = ["z"]\n[columns]\nZeit = "time_s"\nT1 = "probe_A_c"\n'
        'rate = "gyro_z_rate_deg_per_h"\n')
    rec = load_recording(tmp_path / "log.h5")
    np.testing.assert_array_equal(rec.time_s, t)
    np.testing.assert_array_equal(rec.probes()[1][:, 0], temp)
    np.testing.assert_allclose(rec.gyro_rate_deg_per_h()[:, 0], 12.5)
    pd.DataFrame({"time_s": t, "gyro_z_rate_deg_per_h": np.full(n, 12.5),
                  "probe_A_c": temp}).to_parquet(tmp_path / "log2.parquet")
    (tmp_path / "log2.toml").write_text('[recording]\nsample_rate_hz = 10\n')
    rec2 = load_recording(tmp_path / "log2.parquet")
    np.testing.assert_array_equal(rec2.probes()[1][:, 0], temp)
    # a sidecar given on its own names its table
    (tmp_path / "alone.toml").write_text('[recording]\nsample_rate_hz = 10\n'
                                         'data = "log2.parquet"\n')
    np.testing.assert_array_equal(load_recording(tmp_path / "alone.toml").time_s, t)


def test_paper000_system_refuses_a_recording_in_one_line(tmp_path, capsys):
    """The turntable campaign recipe needs simulated calibration windows: a recording named as
    its scenario is one line, exit 2, saying so."""
    _single_gyro_csv(tmp_path / "run.csv", 1, hours=1.0)
    (tmp_path / "p0.toml").write_text("[study]\nname = 'p0'\nrecipe = 'paper000_system'\n"
                                      "[campaign]\nscenario = 'run.csv'\n")
    assert main(["study", str(tmp_path / "p0.toml"), "-o", str(tmp_path / "out"),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "campaign.scenario" in err
    assert "'run.csv' is a recording" in err and "simulated turntable campaign" in err
