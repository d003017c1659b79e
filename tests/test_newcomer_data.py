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
