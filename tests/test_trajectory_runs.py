"""A run on a vehicle: the ``[trajectory]`` table, gnss-ins-sim's motion-definition CSV, the
``trajectory`` group, determinism whatever the chunking, and bad trajectories (one line, exit 2).

References: the kinematics object the scenario builds (its exactness is tests/test_trajectory.py's
job) for the stored truth; gnss-ins-sim's documented command semantics (its ``pathgen``
docstring: types 1-5, body axes forward-right-down) for the reader, on a file written here.
"""

from __future__ import annotations

import filecmp
import math

import h5py
import numpy as np
import pytest

from rlgsim.ground import dataset_format as fmt
from rlgsim.ground.dataset_format import open_dataset
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import DEG
from rlgsim.lab.cli import main
from rlgsim.sim.motion.motion_def import read_motion_def
from rlgsim.sim.motion.trajectory import quaternion_from_euler
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate
from rlgsim.sim.writer.schema import DESCRIPTIONS
from test_dataset_optional import EXPECTED

DRIVE = """
name = "drive"
device = "rlg_imu_000"
seed = 11
duration_s = 1200
[acquisition]
sample_rate_hz = 10
truth_samples = true
[chamber]
start_c = -10.0
[[chamber.segments]]
type = "hold"
duration_min = 20
[trajectory]
latitude_deg = 34.0
longitude_deg = 108.9
height_m = 400.0
heading_deg = 30.0
{extra}
[[trajectory.segment]]
kind = "hold"
duration_s = 100
[[trajectory.segment]]
kind = "accelerate"
speed_m_s = 15.0
duration_s = 30
[[trajectory.segment]]
kind = "coordinated_turn"
by_deg = 90
duration_s = 40
[[trajectory.segment]]
kind = "climb"
pitch_deg = 3
duration_s = 20
[[trajectory.segment]]
kind = "hold"
duration_s = 600.35
gnss = false
[[trajectory.segment]]
kind = "turn"
{turn}
duration_s = 30
"""


def drive(extra: str = "", turn: str = "rate_deg_s = -3") -> str:
    return DRIVE.format(extra=extra, turn=turn)


def run(tmp_path, text: str, name: str = "d.h5", **kw):
    sc = parse_scenario(text, str(tmp_path / "drive.toml"), base_dir=tmp_path)
    return sc, simulate(sc, tmp_path / name, progress=False, **kw)


def test_drive_truth_group_and_bytes_whatever_the_chunking(tmp_path):
    sc, a = run(tmp_path, drive(), "a.h5", chunk_s=600)
    _, b = run(tmp_path, drive(), "b.h5", chunk_s=7200)
    assert filecmp.cmp(a, b, shallow=False)
    traj = sc.trajectory.build(sc.duration_s)
    with h5py.File(a) as f:
        g = f["trajectory"]
        n = g["latitude"].shape[0]
        assert n == 12000 and f["imu/gyro_pulses"].shape[0] == n
        t = (np.arange(n) + 1) / 10.0
        st = traj.states(t)
        assert np.array_equal(g["latitude"][...], np.degrees(st.lat))
        # velocity and attitude by the compiled kernel: the NumPy formulas to rounding
        np.testing.assert_allclose(g["velocity"][...], st.v_n, rtol=0, atol=1e-13)
        np.testing.assert_allclose(g["attitude"][...],
                                   quaternion_from_euler(*st.euler), rtol=0, atol=1e-15)
        # the per-sample true increments are the trajectory's
        mb = traj.increments(0.0, n, 10.0)
        assert np.array_equal(f["truth/dtheta"][...], mb.dtheta_rad)
        assert np.array_equal(f["truth/dv"][...], mb.dv_m_per_s)
        vis = g["gnss_visible"][...]
        assert vis[:1900].all() and not vis[1901:7900].any() and vis[-1]
        assert list(f["trajectory/leg_label"].asstr()[...][:3]) == ["hold", "accelerate",
                                                                 "coordinated_turn (roll in)"]
        # a static mount in the turntable group
        assert not np.any(f["turntable/outer_angle"][...])
        heading = g["heading"][...]
    assert heading[0] == pytest.approx(30.0) and heading[2000] == pytest.approx(120.0)
    # the optional group's layout (rlgsim.ground.dataset_format.OPTIONAL_VARIABLES)
    with open_dataset(a) as ds:
        assert ds.groups() == [*fmt.VARIABLES, fmt.TRAJECTORY]
        assert ds.group_attrs(fmt.TRAJECTORY)["description"] == DESCRIPTIONS[fmt.TRAJECTORY]
        info = [(v.name, v.dims, v.units) for v in ds.variables(fmt.TRAJECTORY)]
    assert info == [(name, *EXPECTED[fmt.TRAJECTORY, name])
                    for name in fmt.OPTIONAL_VARIABLES[fmt.TRAJECTORY]]


def test_kinematics_ahead_are_the_kinematics_in_place(tmp_path, monkeypatch):
    """A vehicle's blocks are computed ahead in worker threads (the increments in one, the
    truth rows in the other, by the compiled rows kernel); the file is the one of every block
    computed on the main thread (the rows by NumPy from the states) —
    at a rate whose thermal steps hold uneven numbers of samples (7.3 Hz)."""
    from rlgsim.sim.sensors.imu import ImuSimulator
    text = drive().replace("sample_rate_hz = 10", "sample_rate_hz = 7.3")
    _, ahead = run(tmp_path, text, "ahead.h5")
    monkeypatch.setattr(ImuSimulator, "_queue_motion", lambda self, k_taken: None)
    _, here = run(tmp_path, text, "here.h5")
    assert filecmp.cmp(ahead, here, shallow=False)


def test_a_stopped_drive_stops_its_kinematics_thread(tmp_path):
    """A vehicle's kinematics start in their own worker before the file is laid out and run
    blocks ahead: a run stopped after its first block stops that worker and leaves no file."""
    import itertools
    import threading

    asked = itertools.count()
    sc = parse_scenario(drive(), str(tmp_path / "drive.toml"), base_dir=tmp_path)
    with pytest.raises(KeyboardInterrupt):
        simulate(sc, tmp_path / "x.h5", progress=False, should_stop=lambda: next(asked) >= 1)
    assert next(asked) == 2                     # one block ran
    assert not [t for t in threading.enumerate() if t.name.startswith("rlgsim-")]
    assert not (tmp_path / "x.h5").exists()


def test_gnss_ins_sim_motion_definition(tmp_path):
    """Types 1 and 2 with gnss-ins-sim's axes: forward x → our y, down z → our −z."""
    csv = tmp_path / "route.csv"
    csv.write_text(
        "ini lat (deg),ini lon (deg),ini alt (m),ini vx_body (m/s),ini vy_body (m/s),"
        "ini vz_body (m/s),ini yaw (deg),ini pitch (deg),ini roll (deg)\n"
        "32,120,10,5,0,0,45,0,0\n"
        "command type,yaw (deg),pitch (deg),roll (deg),vx_body (m/s),vy_body (m/s),"
        "vz_body (m/s),command duration (s),GPS visibility\n"
        "1,0,0,0,1,0,0,10,1\n"
        "1,0,0,0,0,0,0,0,1\n"
        "2,90,0,0,15,0,0,60,0\n"
        "3,0,0,0,0,0,0,5,1\n"
        "5,10,0,0,15,0,0,1,1\n")
    md = read_motion_def(csv)
    assert md.lat_rad == pytest.approx(32 * DEG) and md.height_m == 10
    first, second = md.legs[0], md.legs[1]
    assert first.duration_s == 10 and first.kind == "rate" and first.gnss
    np.testing.assert_allclose(first.end(), [45 * DEG, 0, 0, 0, 15.0, 0])
    # type 2: to heading 90°, forward speed 15 m/s; 45° at ≤ 0.5 rad/s² and 2 rad/s:
    # T = sqrt(10/√3 · 0.785/0.5) = 3.01 s (the speed is already 15 m/s)
    assert second.kind == "smooth" and not second.gnss
    assert second.duration_s == pytest.approx(math.sqrt(10 / math.sqrt(3) * (45 * DEG) / 0.5))
    np.testing.assert_allclose(second.end(), [90 * DEG, 0, 0, 0, 15.0, 0], atol=1e-12)
    # type 3 of no change is skipped; type 5 (+10° in 1 s) is faster than the limits: 1 s
    assert len(md.legs) == 3 and md.legs[2].duration_s == 1.0
    np.testing.assert_allclose(md.legs[2].end()[0], 100 * DEG)


@pytest.mark.parametrize("extra, turn, expected", [
    ("", "rate_deg_s = 500", "past the gyros' range gyro_range_deg_s = 400"),
    ("gyro_range_deg_s = 2", "rate_deg_s = -3", "past the gyros' range gyro_range_deg_s = 2"),
    ("", "rate_deg_s = 3\nlabel = 'x'\nfoo = 1", "foo"),
])
def test_bad_trajectories_one_line_exit_2(tmp_path, capsys, extra, turn, expected):
    path = tmp_path / "bad.toml"
    path.write_text(drive(extra, turn))
    assert main(["run", str(path), "-o", str(tmp_path / "x.h5"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize("change, expected", [
    (("duration_s = 30\n", "duration_s = -30\n"), "duration must be >= 0"),
    (("latitude_deg = 34.0", "latitude_deg = 95.0"), "latitude_deg"),
    (("latitude_deg = 34.0", "latitude_deg = 89.95"), "singular at the poles"),
    (("[trajectory]", "[turntable]\nprogram = 'static'\n[trajectory]"), "not allowed with"),
])
def test_bad_scenario_values(change, expected):
    text = drive().replace(*change)
    with pytest.raises(UserInputError, match=expected) as e:
        parse_scenario(text, "drive.toml")
    assert "\n" not in str(e.value)


def test_route_across_the_pole_is_refused():
    text = """
device = "rlg_imu_000"
[chamber]
start_c = 20.0
[trajectory]
latitude_deg = 89.7
speed_m_s = 20.0
[[trajectory.segment]]
kind = "hold"
duration_h = 1
"""
    sc = parse_scenario(text, "pole.toml")
    with pytest.raises(UserInputError, match=r"pole.toml: trajectory: leg 0 \(hold\) reaches "
                                             r"latitude \+89.9° at t = 1\d{3}.* crosses a pole"):
        sc.trajectory.build(sc.duration_s)


@pytest.mark.parametrize("row, expected", [
    ("1,0,0,0,1,0,0,-10,1", "column 8: command duration -10 s is negative"),
    ("7,0,0,0,1,0,0,10,1", "command type 7 not allowed"),
    ("1,0,0,0,x,0,0,10,1", "column 5: 'x' is not a number"),
    ("1,0,0,0,1,0,10,1", "expected 9 numbers, got 8"),
])
def test_bad_motion_definition_rows(tmp_path, row, expected):
    csv = tmp_path / "bad.csv"
    csv.write_text("h\n32,120,0,0,0,0,0,0,0\nh\n1,0,0,0,0,0,0,1,1\n" + row + "\n")
    with pytest.raises(UserInputError, match=expected) as e:
        read_motion_def(csv)
    assert "line 5" in str(e.value) and "\n" not in str(e.value)
