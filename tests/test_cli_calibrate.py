"""``rlgsim calibrate`` (src/rlgsim/lab/cli/calibrate.py): table, dataset group, figures, user errors."""

from __future__ import annotations

import csv

import h5py
import numpy as np
import pytest

from _turntable_pulses import random_truth, write_dataset
from rlgsim.lab.cli.main import main
from rlgsim.sim.motion.turntable import TurntableProgram

PROG = TurntableProgram.calibration19(dwell_s=20.0, first_dwell_s=30.0)


@pytest.fixture(scope="module")
def run_h5(tmp_path_factory):
    path = tmp_path_factory.mktemp("clical") / "run.h5"
    write_dataset(path, random_truth(np.random.default_rng(21)), PROG, 2 * PROG.duration_s,
                  arw_deg_sqrt_h=0.002, vrw_ug_sqrt_hz=10.0, seed=4)
    return path


def test_calibrate_writes_table_group_and_figures(run_h5, tmp_path, capsys):
    out = tmp_path / "table.csv"
    assert main(["calibrate", str(run_h5), "-o", str(out), "--plot", "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "calibrated 2 of 2 windows" in printed and "s per window" in printed
    rows = list(csv.DictReader(out.open()))
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert float(rows[0]["gyro_sf_x_pulse_per_arcsec"]) == pytest.approx(2.14, rel=1e-3)
    for stem in ("gyro", "accel", "misalignment"):
        png = tmp_path / f"table_{stem}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with h5py.File(run_h5, "r") as f:
        g = f["calibration"]
        assert list(g["window"][:]) == [0, 1]
        assert [s.decode() for s in g["status"][:]] == ["ok", "ok"]
        assert g["gyro_bias_x"].attrs["units"] == "degree h-1"
        np.testing.assert_allclose(g["gyro_bias_x"][:],
                                   [float(r["gyro_bias_x_deg_per_h"]) for r in rows])
        assert g["temperature_mean"].shape == (2, 2)
        assert "calibration.tmp" not in " ".join(f.keys())
    # a second run replaces the group
    assert main(["calibrate", str(run_h5), "-o", str(out), "-q", "--workers", "1"]) == 0


def test_calibrate_user_errors(run_h5, tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "missing.h5")]) == 2
    assert "no such dataset file" in capsys.readouterr().err
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    assert main(["calibrate", str(other)]) == 2
    assert "not an rlgsim dataset" in capsys.readouterr().err
    static = tmp_path / "static.h5"
    write_dataset(static, random_truth(np.random.default_rng(1)), TurntableProgram.static(),
                  100.0)
    assert main(["calibrate", str(static), "-q"]) == 2
    assert "no calibration windows" in capsys.readouterr().err
    assert main(["calibrate", str(run_h5), "--probe", "nope", "-q"]) == 2
    assert "no such probe" in capsys.readouterr().err
    assert main(["calibrate", str(run_h5), "--workers", "0"]) == 2
    assert main(["calibrate", str(run_h5), "-o", str(tmp_path / "no" / "t.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_calibrate_a_simulated_run_end_to_end(tmp_path, capsys):
    """rlgsim run (the full simulator: thermal network, sensor laws, flicker, pulses) → rlgsim
    calibrate: every window calibrated, errors against the stored truth within a few σ."""
    scenario = tmp_path / "cal.toml"
    scenario.write_text(
        'name = "cal"\ndevice = "rlg_imu_000"\nseed = 3\nduration_s = 1138\n'
        '[acquisition]\nsample_rate_hz = 50\n'
        '[chamber]\nstart_c = 20.0\n[[chamber.segments]]\ntype = "hold"\nduration_s = 1138\n'
        '[turntable]\nprogram = "calibration19"\ndwell_s = 25\nfirst_dwell_s = 38\n')
    h5 = tmp_path / "cal.h5"
    assert main(["run", str(scenario), "-o", str(h5), "-q"]) == 0
    out = tmp_path / "cal.csv"
    assert main(["calibrate", str(h5), "-o", str(out), "-q", "--workers", "1"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 2 and [r["status"] for r in rows] == ["ok", "ok"]
    from rlgsim.estimators.calibration import PARAMETERS, UNIT_NAMES
    z = np.array([[float(r[f"{p.name}_error_{UNIT_NAMES[p.unit]}"])
                   / float(r[f"{p.name}_sigma_{UNIT_NAMES[p.unit]}"]) for p in PARAMETERS]
                  for r in rows])
    assert np.abs(z).max() < 5.0 and np.sqrt((z ** 2).mean()) < 1.6
    assert 2.0 < float(rows[0]["nis"]) < 4.0
