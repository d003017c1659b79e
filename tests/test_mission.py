"""Mission scores (src/rlgsim/lab/mission.py): a short cold drive with one GNSS outage through
the aided navigator, per variant.

References: the route's exact increments (the floor: only the filter's and the navigator's own
error remain) and the truth's temperature laws (the oracle); the raw pulses carry the bias laws
of a unit warming from -20 °C, which the filter cannot follow through the outage.
"""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.mission import score_mission
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate

MISSION = """
device = "rlg_imu_000"
seed = 4
duration_s = 1200
[acquisition]
sample_rate_hz = 10
[power]
on_at_s = 30
[chamber]
start_c = -20.0
[[chamber.segments]]
type = "ramp"
to_c = 10.0
duration_min = 20
[trajectory]
latitude_deg = 40.0
heading_deg = 45.0
[[trajectory.segment]]
kind = "hold"
duration_s = 400
[[trajectory.segment]]
kind = "accelerate"
speed_m_s = 20.0
duration_s = 30
[[trajectory.segment]]
kind = "turn"
by_deg = 90
duration_s = 20
[[trajectory.segment]]
kind = "hold"
duration_s = 300
gnss = false
[[trajectory.segment]]
kind = "hold"
duration_s = 450
"""


def test_mission_ranks_the_variants(tmp_path):
    sc = parse_scenario(MISSION, str(tmp_path / "m.toml"))
    out = simulate(sc, tmp_path / "m.h5", progress=False)
    r = score_mission(out)
    assert list(r) == ["raw", "oracle", "truth"]
    coast = {k: v["outage_error_m"] for k, v in r.items()}
    assert all(len(c) == 1 for c in coast.values())          # one outage: 450-750 s
    assert coast["truth"][0] < 2.0                            # the floor: fixes' noise level
    assert coast["raw"][0] > coast["truth"][0]
    # with fixes the position stays at the fixes' noise whatever the variant
    t = r["raw"]["t_s"]
    assert np.max(r["raw"]["horizontal_m"][(t > 60) & (t < 400)]) < 6.0


def test_a_turntable_run_is_refused(tmp_path):
    text = MISSION[:MISSION.index("[trajectory]")]
    sc = parse_scenario(text.replace("duration_s = 1200", "duration_s = 60"),
                        str(tmp_path / "t.toml"))
    out = simulate(sc, tmp_path / "t.h5", progress=False)
    with pytest.raises(UserInputError, match="no trajectory group"):
        score_mission(out)


def test_mission_figure(tmp_path):
    """The figure of a (tiny) mission is written: route, temperatures, errors."""
    from rlgsim.lab.mission_report import mission_figure
    text = MISSION.replace("duration_s = 1200", "duration_s = 120").replace(
        "duration_s = 400", "duration_s = 60")
    sc = parse_scenario(text, str(tmp_path / "f.toml"))
    out = simulate(sc, tmp_path / "f.h5", progress=False)
    scores = {"raw": {"t_s": np.array([60.0, 120.0]), "horizontal_m": np.array([1.0, 2.0])}}
    png = mission_figure(out, scores, tmp_path / "mission.png")
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
