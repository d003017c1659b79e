"""A route given as a table of timed positions and attitudes (sim/motion/position_table.py and
the geodetic legs of sim/motion/trajectory.py and its kernel).

References: the ECEF strapdown equations by DOP853 (tests/test_trajectory.py's ecef_reference:
another frame, another formulation) driven by the table route's rates; 40-node Gauss–Legendre
integrals of those rates for the increments; the table's own rows for the interpolation.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rlgsim.ground.earth import enu_to_ecef_matrix, geodetic_to_ecef
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import DEG
from rlgsim.sim.motion.position_table import read_position_table
from rlgsim.sim.motion.trajectory import InitialState, Trajectory
from rlgsim.sim.run.scenario import parse_scenario
from test_trajectory import START, ecef_reference, fine_integrals, manoeuvres


def table_of(tmp_path, every_s: float = 2.0, name: str = "route.csv") -> pd.DataFrame:
    """The manoeuvres' states every ``every_s`` as a table (written to ``name``)."""
    src = Trajectory(manoeuvres(), START, until_s=100.0)
    t = np.arange(0.0, 100.0 + 1e-9, every_s)
    st = src.states(t)
    df = pd.DataFrame({"time_s": t + 1000.0, "latitude_deg": np.degrees(st.lat),
                       "longitude_deg": np.degrees(st.lon), "height_m": st.height,
                       "heading_deg": np.degrees(st.euler[0]) % 360.0,
                       "pitch_deg": np.degrees(st.euler[1]), "roll_deg": np.degrees(st.euler[2])})
    if name.endswith(".parquet"):
        df.to_parquet(tmp_path / name)
    else:
        df.to_csv(tmp_path / name, index=False)
    return df


def route(tmp_path, name="route.csv", until=100.0):
    df = table_of(tmp_path, name=name)
    (lat, lon, h), legs, t0 = read_position_table(tmp_path / name)
    assert t0 == 1000.0
    return df, Trajectory(legs, InitialState(lat, lon, h), until_s=until)


@pytest.mark.parametrize("name", ["route.csv", "route.parquet"])
def test_passes_through_its_rows(tmp_path, name):
    df, traj = route(tmp_path, name)
    st = traj.states(df["time_s"].to_numpy() - 1000.0)
    np.testing.assert_allclose(np.degrees(st.lat), df["latitude_deg"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(st.height, df["height_m"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(st.euler[0]) % 360, df["heading_deg"], atol=1e-9)


def test_acceleration_and_angular_rate_are_continuous(tmp_path):
    _, traj = route(tmp_path)
    knots = traj.leg_starts[1:5]
    for t in knots:
        left = traj.leg_of(np.array([t]), side="left")[0]
        right = traj.leg_of(np.array([t]))[0]
        a = traj._velocity(int(left), np.array([t - traj.leg_starts[left]]))
        b = traj._velocity(int(right), np.array([0.0]))
        np.testing.assert_allclose(a[1], b[1], rtol=0, atol=1e-12)     # ω_nb^b
        np.testing.assert_allclose(a[3], b[3], rtol=0, atol=1e-9)      # v̇^n
        np.testing.assert_allclose(a[2], b[2], rtol=0, atol=1e-9)      # v^n


def test_table_kinematics_against_ecef_strapdown_equations(tmp_path):
    _, traj = route(tmp_path)
    ref = ecef_reference(traj, 40.0)
    for t, (r, v, c) in ref.items():
        s = traj.states(np.array([t]))
        cne = enu_to_ecef_matrix(s.lat[0], s.lon[0])
        assert np.linalg.norm(r - geodetic_to_ecef(s.lat[0], s.lon[0], s.height[0])) < 1e-5
        assert np.linalg.norm(v - cne @ s.v_n[0]) < 1e-8
        assert np.max(np.abs((cne @ s.c_bn[0]).T @ c - np.eye(3))) < 1e-11


def test_table_increments_are_the_exact_integrals(tmp_path):
    _, traj = route(tmp_path)
    mb = traj.increments(1.9, 30, 100.0)
    ref_th, ref_v = fine_integrals(traj, (190 + np.arange(31)) / 100.0, 100.0)
    assert np.max(np.abs(mb.dtheta_rad - ref_th)) < 64 * 2.2e-16 * np.max(np.abs(ref_th))
    assert np.max(np.abs(mb.dv_m_per_s - ref_v)) < 64 * 2.2e-16 * np.max(np.abs(ref_v))
    # the range check's compiled peaks on a table's legs: the NumPy formulas' (test_trajectory)
    (w, f, at), (wn, fn, atn) = traj.peak_inputs(), traj.peak_inputs_numpy()
    assert at == atn and w == pytest.approx(wn, rel=1e-14, abs=0)
    assert f == pytest.approx(fn, rel=1e-14, abs=0)


def test_run_from_a_table_scenario(tmp_path):
    table_of(tmp_path)
    text = ('device = "rlg_imu_000"\nduration_s = 60\n[acquisition]\nsample_rate_hz = 10\n'
            '[chamber]\nstart_c = 20.0\n[trajectory]\ntable = "route.csv"\n')
    sc = parse_scenario(text, str(tmp_path / "t.toml"), base_dir=tmp_path)
    assert sc.site.latitude_deg == pytest.approx(np.degrees(START.lat_rad))
    sc.trajectory.build(sc.duration_s)
    longer = parse_scenario(text.replace("duration_s = 60", "duration_s = 200"),
                            str(tmp_path / "t.toml"), base_dir=tmp_path)
    with pytest.raises(UserInputError, match="lasts longer than the position table"):
        longer.trajectory.build(longer.duration_s)


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d.assign(latitude_deg=d.latitude_deg.where(d.index != 7, d.latitude_deg + 0.05)),
     "row 8: the position jumps .* a discontinuous table"),
    (lambda d: d.assign(heading_deg=d.heading_deg.where(d.index != 5, d.heading_deg + 170)),
     "row 6: the attitude turns .* past the gyros' range"),
    (lambda d: d.assign(time_s=d.time_s.where(d.index != 3, 1000.0)),
     "row 4, column time_s: 1000 s is not after"),
    (lambda d: d.drop(columns="roll_deg"), "missing column 'roll_deg'"),
    (lambda d: d.assign(latitude_deg=89.95), "row 1, column latitude_deg: 89.95 not allowed"),
    (lambda d: d.head(3), "at least 4 rows"),
    (lambda d: d.assign(height_m=d.height_m.astype(object).where(d.index != 2, "x")),
     "row 3, column height_m: 'x' is not a number"),
])
def test_bad_tables_one_line(tmp_path, edit, expected):
    df = table_of(tmp_path)
    edit(df).to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(UserInputError, match=expected) as e:
        read_position_table(tmp_path / "bad.csv", max_rate_rad_s=50 * DEG)
    assert "\n" not in str(e.value)
