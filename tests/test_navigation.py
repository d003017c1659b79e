"""Navigation scores (rlgsim.lab.navigation), ``rlgsim navigate`` and ``rlgsim.navigate``.

A 75-min paper-000 run (1 h static lead-in, then the 19-position turntable sequence) and a
synthetic static recording. The truth variant is the mechanization's floor; a model that
predicts exactly the true gyro law must navigate exactly like the gyro oracle.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import rlgsim
from rlgsim.ground.earth import earth_rate_enu, normal_gravity
from rlgsim.lab.cli import main
from rlgsim.lab.navigation import navigate
from rlgsim.lab.navigation_source import open_source


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from rlgsim.lab.api import load_scenario, with_changes
    from rlgsim.sim.run.simulate import simulate
    sc = with_changes(load_scenario("paper000_short"), duration_h=1.25)
    return simulate(sc, tmp_path_factory.mktemp("nav") / "p000.h5")


def test_variants_floor_and_model_path(dataset):
    src = open_source(dataset)
    try:
        law = src.law_gyro.copy()
    finally:
        src.close()
    ds = navigate(dataset, models={"true law": law}, span_s=3000.0)
    assert list(ds["variant"].values) == ["raw", "true law", "oracle (gyros)", "oracle", "truth"]
    assert ds.attrs["vertical_channel"].startswith("held")
    assert ds.attrs["align_end_s"] == 600.0 and ds.attrs["navigation_end_s"] == 3600.0
    truth = ds.sel(variant="truth")
    assert float(truth["horizontal_error_m"].max()) < 0.01             # mechanization floor
    assert abs(float(truth["heading_error_end_arcmin"])) < 1e-4
    a, b = ds.sel(variant="true law"), ds.sel(variant="oracle (gyros)")
    np.testing.assert_array_equal(a["horizontal_error_m"].values, b["horizontal_error_m"].values)
    # the raw IMU (bias, scale factor, misalignment left in) errs far more than the floor
    assert float(ds.sel(variant="raw")["error_end_m"]) > 1.0
    # the heading bound of the raw data is its residual East gyro bias over the alignment
    assert math.isfinite(float(ds.sel(variant="raw")["heading_bound_arcmin"]))


def test_cli_writes_solution_and_report(dataset, tmp_path, capsys):
    out = tmp_path / "nav"
    assert main([ "navigate", str(dataset), "--span-h", "0.5", "-o", str(out), "-q"]) == 0
    sol = pd.read_csv(out / "solution.csv")
    assert {"variant", "time_s", "horizontal_error_m", "heading_error_arcmin"} <= set(sol.columns)
    assert set(sol["variant"]) == {"raw", "oracle (gyros)", "oracle", "truth"}
    text = (out / "report.md").read_text()
    assert "radial rate [nmi/h]" in text and "ranks before" in text
    assert (out / "navigation.png").stat().st_size > 10000
    assert pd.read_csv(out / "summary.csv", index_col=0).shape[0] == 4


def test_cli_zero_length_span(dataset, capsys):
    assert main(["navigate", str(dataset), "--span-h", "0.0001"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nothing left to navigate" in err


def _recording(tmp_path, *, site=True, gyros="xyz", accels="xyz", nan=False, minutes=20):
    f, lat = 10.0, 45.0
    n = int(minutes * 60 * f)
    w = earth_rate_enu(lat)
    g = normal_gravity(lat, 100.0)
    cols = {"time_s": (np.arange(n) + 1) / f}
    for i, a in enumerate(gyros):
        cols[f"gyro_{a}_rate_rad_per_s"] = np.full(n, w[i])
    for i, a in enumerate(accels):
        cols[f"accel_{a}_m_per_s2"] = np.full(n, (0.0, 0.0, g)[i])
    if nan:
        cols["gyro_x_rate_rad_per_s"][5] = np.nan
    pd.DataFrame(cols).to_csv(tmp_path / "rec.csv", index=False)
    side = ["[recording]", "sample_rate_hz = 10"]
    if site:
        side += ["[site]", "latitude_deg = 45.0", "height_m = 100.0"]
    side += ["[gyro]", f"axes = {list(gyros)!r}".replace("'", '"'),
             "scale_factor_pulses_per_arcsec = 2.0"]
    if accels:
        side += ["[accelerometer]", f"axes = {list(accels)!r}".replace("'", '"'),
                 "scale_factor_pulses_per_s_per_g = 5000.0"]
    (tmp_path / "rec.toml").write_text("\n".join(side) + "\n")
    return tmp_path / "rec.csv"


def test_recording_navigates(tmp_path):
    ds = rlgsim.navigate(_recording(tmp_path))
    assert list(ds["variant"].values) == ["raw"]
    assert float(ds["horizontal_error_m"].max()) < 0.05
    assert ds.attrs["vertical_channel"] == "held at the initial height 100 m"


@pytest.mark.parametrize("case, words", [
    ({"site": False}, "[site] latitude_deg missing"),
    ({"gyros": "x"}, "navigation needs three gyros"),
    ({"accels": ""}, "navigation needs three accelerometers"),
    ({"nan": True}, "gyro_x_rate_rad_per_s"),
])
def test_bad_recordings_one_line(tmp_path, capsys, case, words):
    path = _recording(tmp_path, **case)
    assert main(["navigate", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "out").exists()


def test_an_export_navigates_like_its_dataset_from_power_on(tmp_path):
    """A recording's alignment starts at power-on as its dataset's does (the row after the last
    power_on reading of 0, a slow column): the export of a run powered at 60 s gives the
    dataset's raw errors (same pulses, same first sample; to rounding of the summation order,
    well inside 1e-9 m of a 0.1–10 m error). Before, it aligned over the unpowered minute."""
    from rlgsim.lab.api import load_scenario, with_changes
    from rlgsim.sim.run.simulate import simulate
    sc = with_changes(load_scenario("paper000_short"), {"power.on_at_s": 60.0},
                      duration_h=0.1)
    h5 = simulate(sc, tmp_path / "p.h5")
    assert main(["export", str(h5), "-o", str(tmp_path / "p.csv"), "-q"]) == 0
    a, b = open_source(h5), open_source(tmp_path / "p.csv")
    assert a.start == b.start == 60 * 100
    ds_a = navigate(h5, align_s=120.0)
    ds_b = navigate(tmp_path / "p.csv", align_s=120.0)
    np.testing.assert_allclose(ds_b["horizontal_error_m"].sel(variant="raw").values,
                               ds_a["horizontal_error_m"].sel(variant="raw").values,
                               rtol=0, atol=1e-9)
