"""Recipe ``vehicle`` (src/rlgsim/lab/studies/vehicle.py): a short chamber run trains the
compensators, a short drive with one GNSS outage scores them; the report and its rows."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import load_study, parse_study, run_study
from test_mission import MISSION

TRAIN = """
device = "rlg_imu_000"
seed = 8
duration_min = 40
[acquisition]
sample_rate_hz = 1
[chamber]
start_c = -20.0
[[chamber.segments]]
type = "ramp"
to_c = 20.0
duration_min = 40
"""

STUDY = """
[study]
name = "vehicle_test"
recipe = "vehicle"
[train]
scenario = "train.toml"
[mission]
scenario = "mission.toml"
[[compensator]]
name = "cubic T"
inputs = ["T"]
degree = 3
"""


def test_vehicle_study_runs_and_reports(tmp_path):
    (tmp_path / "train.toml").write_text(TRAIN)
    (tmp_path / "mission.toml").write_text(MISSION)
    study = parse_study(STUDY, str(tmp_path / "study.toml"), base_dir=tmp_path)
    report = run_study(study, tmp_path / "out", progress=False)
    rows = list(csv.DictReader(open(tmp_path / "out" / "scores.csv")))
    variants = [r["variant"] for r in rows]
    assert variants == ["raw", "raw", "cubic T", "cubic T", "cubic T", "cubic T", "oracle", "oracle",
                        "truth", "truth"]
    coast = {r["variant"]: float(r["value"]) for r in rows
             if r["metric"] == "coasting_error_outage1_m"}
    assert coast["truth"] < coast["raw"]
    # issue 27: the cold-soaked drive lies wholly below the chamber run's probe range (read
    # here from the two probe logs), so every mission window extrapolates
    from rlgsim.lab.studies.runs import probe_temperatures
    _, tr = probe_temperatures(tmp_path / "out" / "data" / "train.h5", ["gx.A", "gy.A", "gz.A"])
    _, mi = probe_temperatures(tmp_path / "out" / "data" / "mission.h5", ["gx.A", "gy.A", "gz.A"])
    assert all(np.nanmax(mi[k]) < np.nanmin(tr[k]) for k in tr)
    share = {r["metric"]: float(r["value"]) for r in rows if r["variant"] == "cubic T"}
    assert share["outside_range_pct"] == 100.0 and share["outside_excess_pct"] > 0
    assert "Inputs outside the training range" in report.read_text()
    assert list((tmp_path / "out").rglob("mission*.png")) and report.is_file()


def test_shipped_vehicle_study_validates():
    assert load_study("vehicle").recipe == "vehicle"


def test_bad_compensator_input():
    with pytest.raises(UserInputError, match="compensator\\[0\\].inputs: 'U' not allowed"):
        parse_study(STUDY.replace('inputs = ["T"]', 'inputs = ["U"]'), "s.toml")
