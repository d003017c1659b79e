"""Lab data a newcomer brings (issue 29): logs the importer must read or refuse in one line —
a three-gyro log with one per-axis UHFO column, accelerometers in m/s² without a scale factor,
misleading hints (sample rate against gap, semicolons, ISO timestamps, Parquet strings)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rlgsim.ground.datatree import open_tree
from rlgsim.ground.recording import load_recording
from rlgsim.lab.cli.main import main

THREE = """\
[recording]
sample_rate_hz = 1
temperature_rate_hz = 1

[gyro]
axes = ["x", "y", "z"]
scale_factor_pulses_per_arcsec = 2.14
"""


def _chamber_log(path, hours=2.5, uhfo_axes=("z",)):
    """A 1 Hz three-gyro chamber log: rates in °/h, a probe and the chamber air ramping
    20 → 35 °C, UHFO logged for ``uhfo_axes`` only."""
    n = int(hours * 3600)
    t = np.arange(1, n + 1, dtype=float)
    air = 20.0 + 15.0 * np.clip(t / (0.8 * n), 0, 1)
    rng = np.random.default_rng(3)
    df = pd.DataFrame({"time_s": t})
    for i, a in enumerate("xyz"):
        df[f"gyro_{a}_rate_deg_per_h"] = 1.0 + 0.01 * i + 0.002 * (air - 20) \
            + 0.001 * rng.standard_normal(n)
    df["probe_A_c"] = air - 0.5
    df["chamber_air_c"] = air
    for a in uhfo_axes:
        df[f"uhfo_{a}_v"] = 3.0 + 0.01 * (air - 20)
    df.to_csv(path, index=False)
    path.with_suffix(".toml").write_text(THREE)
    return df


def test_three_gyro_log_with_one_per_axis_uhfo_opens_and_identifies(tmp_path):
    df = _chamber_log(tmp_path / "log.csv")
    tree = open_tree(tmp_path / "log.csv")
    u = tree["imu"]["uhfo"]
    assert list(tree["imu"]["gyro"].values) == ["x", "y", "z"]
    np.testing.assert_array_equal(u.sel(gyro="z").values, df["uhfo_z_v"].to_numpy())
    assert np.isnan(u.sel(gyro="x").values).all() and np.isnan(u.sel(gyro="y").values).all()
    from rlgsim.lab.identify.recording_data import read_recording
    z = read_recording(tmp_path / "log.csv", gyro="z")
    np.testing.assert_allclose(z.uhfo_v, df["uhfo_z_v"].to_numpy())
    assert read_recording(tmp_path / "log.csv", gyro="x").uhfo_v is None


def test_uhfo_of_an_axis_that_is_no_gyro_is_one_line(tmp_path, capsys):
    _chamber_log(tmp_path / "log.csv", hours=0.01, uhfo_axes=("q",))
    assert main(["info", str(tmp_path / "log.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "column 'uhfo_q_v': axis 'q' not allowed" in err[0], err


# ----------------------------------------------------------------------------- small logs

SMALL = """\
[recording]
sample_rate_hz = 100
{extra}
[gyro]
axes = ["x"]
scale_factor_pulses_per_arcsec = 2.14

[accelerometer]
axes = ["x", "y", "z"]
"""


def _small(rows=50, rate=100.0):
    t = np.arange(1, rows + 1) / rate
    return pd.DataFrame({"time_s": t, "gyro_x_pulses": np.arange(rows),
                         "accel_x_m_per_s2": 0.01 * np.arange(rows),
                         "accel_y_m_per_s2": np.zeros(rows),
                         "accel_z_m_per_s2": np.full(rows, 9.79)})


def _info(path, capsys):
    code = main(["info", str(path)])
    cap = capsys.readouterr()
    return code, cap.err.strip().splitlines(), cap.out


def _one_line(path, capsys, expected):
    before = path.read_bytes()
    code, err, _ = _info(path, capsys)
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err
    assert expected in err[0], err[0]
    assert path.read_bytes() == before


def test_accelerometers_in_m_per_s2_without_a_scale_factor(tmp_path):
    df = _small()
    df.to_csv(tmp_path / "a.csv", index=False)
    (tmp_path / "a.toml").write_text(SMALL.format(extra=""))
    imu = open_tree(tmp_path / "a.csv")["imu"]
    assert "accel_pulses" not in imu                 # no pulses without a scale factor
    sf = imu["specific_force"]
    assert sf.attrs["units"] == "m s-2"
    np.testing.assert_array_equal(sf.sel(accel="x").values, df["accel_x_m_per_s2"].to_numpy())
    np.testing.assert_array_equal(sf.sel(accel="z").values, df["accel_z_m_per_s2"].to_numpy())
    # with a scale factor, pulses too: a = pulses / (K/g0 · dt)
    (tmp_path / "a.toml").write_text(SMALL.format(extra="") + "scale_factor_pulses_per_s_per_g"
                                                              " = 5000.0\n")
    imu = open_tree(tmp_path / "a.csv")["imu"]
    from rlgsim.ground.units import G0
    np.testing.assert_allclose(imu["accel_pulses"].sel(accel="z").values,
                               9.79 / G0 * 5000.0 / 100.0, rtol=1e-14)


def test_a_wrong_sample_rate_is_not_called_a_gap(tmp_path, capsys):
    _small(rate=10.0).to_csv(tmp_path / "r.csv", index=False)
    (tmp_path / "r.toml").write_text(SMALL.format(extra=""))
    _one_line(tmp_path / "r.csv", capsys, "column 'time_s': the rows are 0.1 s apart (10 Hz) in "
                                          "49 of 49 steps, but the sidecar's sample_rate_hz = "
                                          "100 needs 0.01 s")
    df = _small(rows=200).drop(index=[50, 51])           # a real gap still reads as one
    df.to_csv(tmp_path / "r.csv", index=False)
    _one_line(tmp_path / "r.csv", capsys, "row 51: a gap of 0.03 s (2 missing sample(s))")


def test_semicolon_delimited_logs_with_decimal_points_or_commas(tmp_path, capsys):
    df = _small()
    df.to_csv(tmp_path / "s.csv", index=False, sep=";")
    (tmp_path / "s.toml").write_text(SMALL.format(extra=""))
    rec = load_recording(tmp_path / "s.csv")                # the header's ';' is found
    np.testing.assert_array_equal(rec.time_s, df["time_s"].to_numpy())
    df.to_csv(tmp_path / "s.csv", index=False, sep=";", decimal=",")
    _one_line(tmp_path / "s.csv", capsys, "(a decimal comma: give [recording] decimal = \",\"")
    (tmp_path / "s.toml").write_text(SMALL.format(extra='decimal = ","'))
    rec = load_recording(tmp_path / "s.csv")
    np.testing.assert_array_equal(rec.columns["accel_x_m_per_s2"],
                                  df["accel_x_m_per_s2"].to_numpy())
    # a tab-separated header that also has a comma in a name: the delimiter option
    (tmp_path / "s.toml").write_text(SMALL.format(extra='delimiter = "\\t"'))
    df.rename(columns={"accel_y_m_per_s2": "y, spare"}).to_csv(tmp_path / "s.csv", sep="\t",
                                                               index=False)
    (tmp_path / "s.toml").write_text(SMALL.format(extra='delimiter = "\\t"\nignore_columns = '
                                                        '["y, spare"]').replace(
        '["x", "y", "z"]', '["x", "z"]'))
    assert load_recording(tmp_path / "s.csv").accel_axes == ["x", "z"]
    (tmp_path / "s.toml").write_text(SMALL.format(extra='delimiter = ":"'))
    _one_line(tmp_path / "s.csv", capsys, "s.toml: recording.delimiter: value ':' not allowed")


def test_iso_timestamps_as_the_time_axis(tmp_path, capsys):
    df = _small()
    stamps = pd.Timestamp("2026-03-01T12:00:00") + pd.to_timedelta(df["time_s"], unit="s")
    df.insert(0, "Zeit", stamps.dt.strftime("%Y-%m-%dT%H:%M:%S.%f"))
    df = df.drop(columns="time_s")
    df.to_csv(tmp_path / "i.csv", index=False)
    (tmp_path / "i.toml").write_text(SMALL.format(extra="") + '\n[columns]\nZeit = "time_s"\n')
    rec = load_recording(tmp_path / "i.csv")
    np.testing.assert_allclose(rec.time_s, np.arange(1, 51) / 100.0, rtol=0, atol=1e-12)
    assert rec.time_origin == "2026-03-01T12:00:00"
    code, _, out = _info(tmp_path / "i.csv", capsys)
    assert code == 0 and "time origin: 2026-03-01T12:00:00" in out
    df.loc[7, "Zeit"] = "yesterday"
    df.to_csv(tmp_path / "i.csv", index=False)
    _one_line(tmp_path / "i.csv", capsys, "column 'Zeit', row 8: value 'yesterday' not allowed; "
                                          "the time column holds ISO 8601 timestamps")


def test_parquet_time_of_strings_refused_and_timestamps_read(tmp_path, capsys):
    df = _small()
    (tmp_path / "p.toml").write_text(SMALL.format(extra=""))
    df.assign(time_s=df["time_s"].map(repr)).to_parquet(tmp_path / "p.parquet")
    _one_line(tmp_path / "p.parquet", capsys, "column 'time_s': holds text (such as '0.01'); "
                                              "Parquet columns must be numbers")
    stamps = pd.Timestamp("2026-03-01T12:00:00", tz="Europe/Berlin") \
        + pd.to_timedelta(df["time_s"], unit="s")
    df.assign(time_s=stamps).to_parquet(tmp_path / "p.parquet")
    rec = load_recording(tmp_path / "p.parquet")
    np.testing.assert_allclose(rec.time_s, np.arange(1, 51) / 100.0, rtol=0, atol=1e-12)
    assert rec.time_origin == "2026-03-01T11:00:00"            # UTC


def test_trees_resample_on_a_timedelta_coordinate(tmp_path):
    df = _small(rows=600)
    df.to_csv(tmp_path / "a.csv", index=False)
    (tmp_path / "a.toml").write_text(SMALL.format(extra=""))
    imu = open_tree(tmp_path / "a.csv")["imu"].to_dataset()
    assert imu["sample_time"].dtype == np.float64                 # the seconds are kept
    out = imu["specific_force"].resample(sample_elapsed="2s").mean()
    ref = df["accel_x_m_per_s2"].to_numpy()
    # bins start at the first sample (0.01 s): rows 0..199, 200..399, 400..599
    np.testing.assert_allclose(out.sel(accel="x").values, ref.reshape(3, 200).mean(axis=1),
                               rtol=1e-15)



def test_with_changes_of_a_device_parameter():
    import tomllib

    import rlgsim
    from rlgsim.ground.errors import UserInputError
    sc = rlgsim.load_scenario("demo_cycle")
    before = sc.device.tables["gyro"]["bias"]["c1_deg_per_h_per_k"]
    ch = rlgsim.with_changes(sc, {"device.gyro.bias.c1_deg_per_h_per_k": 2.5e-4,
                                  "chamber.start_c": 21.0}, seed=9)
    assert ch.device.tables["gyro"]["bias"]["c1_deg_per_h_per_k"] == 2.5e-4 != before
    assert ch.device.parts["gyro"] is not sc.device.parts["gyro"]      # validated again
    assert ch.seed == 9 and ch.tables["chamber"]["start_c"] == 21.0
    assert tomllib.loads(ch.device.text)["gyro"]["bias"]["c1_deg_per_h_per_k"] == 2.5e-4
    assert ch.device.text.startswith("# device trplg_001, from ")
    assert sc.device.tables["gyro"]["bias"]["c1_deg_per_h_per_k"] == before    # untouched
    with pytest.raises(UserInputError, match="gyro.bias.c1_typo: unknown key"):
        rlgsim.with_changes(sc, {"device.gyro.bias.c1_typo": 1.0})


FAST = """\
name = "fast"
device = "trplg_001"
seed = 1
duration_s = {duration}

[acquisition]
sample_rate_hz = 100000

[chamber]
start_c = 20.0
"""


def test_a_short_run_at_100_khz_is_not_refused_by_the_block_budget(tmp_path, capsys):
    (tmp_path / "fast.toml").write_text(FAST.format(duration=10))
    assert main(["run", str(tmp_path / "fast.toml"), "-o", str(tmp_path / "fast.h5"),
                 "--chunk-s", "5", "-q"]) == 0
    import h5py
    import json
    from importlib.metadata import version
    with h5py.File(tmp_path / "fast.h5", "r") as f:
        assert f["imu/gyro_pulses"].shape[0] == 1_000_000
        made = json.loads(f.attrs["software_versions"])        # provenance (issue 29)
    assert list(made) == ["rlgsim", "numpy", "scipy", "h5py", "numba"]
    assert all(made[k] == version(k) for k in made)
    assert main(["info", str(tmp_path / "fast.h5")]) == 0
    assert f"made with: rlgsim {version('rlgsim')}, numpy {version('numpy')}" in \
        capsys.readouterr().out
    # a run of many 600 s blocks at that rate needs the whole block, whatever the chunk
    (tmp_path / "fast.toml").write_text(FAST.format(duration=7200))
    assert main(["run", str(tmp_path / "fast.toml"), "-o", str(tmp_path / "long.h5"),
                 "--chunk-s", "5", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "samples per block, whatever the chunk" in err[0], err
    assert not (tmp_path / "long.h5").exists()


def test_every_gyro_rate_unit_of_the_grammar_reads(tmp_path):
    """gyro_<axis>_rate_deg_per_h, _deg_per_s and _rate_rad_per_s (the split once lost the
    last one's underscore): the same rate through each."""
    n = 20
    rates = {"deg_per_h": 3600.0, "deg_per_s": 1.0, "rad_per_s": np.pi / 180}
    for unit, v in rates.items():
        pd.DataFrame({"time_s": np.arange(1, n + 1) / 10.0,
                      f"gyro_x_rate_{unit}": np.full(n, v)}).to_csv(tmp_path / "g.csv",
                                                                     index=False)
        (tmp_path / "g.toml").write_text("[recording]\nsample_rate_hz = 10\n")
        np.testing.assert_allclose(load_recording(tmp_path / "g.csv").gyro_rate_deg_per_h(),
                                   3600.0, rtol=1e-12)
