"""Bad and extreme inputs of the commands that read vehicle runs and damaged datasets (issue 26's
adversarial sweep of ``rlgsim navigate``, ``study`` with the vehicle recipe, ``export``): each
case is one line naming the file/key/value and what is allowed, exit status 2, no traceback, no
input rewritten, nothing written. The inputs are those the sweep found failing (a traceback, a
run on a vehicle navigated as if it stood at its start, a report written over a file) plus a
few representatives; one static 3-min run is simulated once (the vehicle study's cases are
refused before any run: its 4-min drive is only parsed)."""

from __future__ import annotations

import dataclasses
import hashlib
import pathlib
import shutil

import h5py
import numpy as np
import pytest

from rlgsim.lab.cli.main import main
from scenario_helpers import one_line

STATIC = """
name = "fuzz_static"
device = "rlg_imu_000"
seed = 7
duration_h = 0.05
[acquisition]
sample_rate_hz = 10
[power]
on_at_s = 0
[chamber]
start_c = 20.0
[[chamber.segments]]
type = "hold"
duration_min = 3
"""

VEHICLE = """
name = "fuzz_vehicle"
device = "rlg_imu_000"
seed = 2601
duration_h = 0.0667
[acquisition]
sample_rate_hz = 10
[power]
on_at_s = 10
[chamber]
start_c = -30.0
[[chamber.segments]]
type = "ramp"
to_c = 0.0
duration_min = 4
[trajectory]
latitude_deg = 34.25
longitude_deg = 108.95
height_m = 400.0
heading_deg = 90.0
[[trajectory.segment]]
kind = "hold"
duration_s = 90.0
[[trajectory.segment]]
kind = "accelerate"
duration_s = 10.0
speed_m_s = 10.0
[[trajectory.segment]]
kind = "turn"
duration_s = 10.0
by_deg = 90.0
[[trajectory.segment]]
kind = "hold"
duration_s = 40.0
gnss = false
[[trajectory.segment]]
kind = "accelerate"
duration_s = 10.0
speed_m_s = 0.0
[[trajectory.segment]]
kind = "hold"
duration_s = 80.0
"""


@pytest.fixture(scope="session")
def runs(tmp_path_factory) -> dict[str, pathlib.Path]:
    """The static run, simulated once for the session, and a stand-in for a drive: the same
    file with the group that marks a run on a vehicle (``trajectory``, what the readers refuse
    on; simulating :data:`VEHICLE` costs the trajectory kernels' cold compile, ~8 s, which the
    sweep paid with real drives)."""
    from rlgsim.ground.dataset_format import TRAJECTORY
    folder = tmp_path_factory.mktemp("vehicle_fuzz")
    (folder / "static.toml").write_text(STATIC)
    out = {"static": folder / "static.h5", "vehicle": folder / "vehicle.h5"}
    assert main(["run", str(folder / "static.toml"), "-o", str(out["static"]), "-q"]) == 0
    shutil.copy(out["static"], out["vehicle"])
    with h5py.File(out["vehicle"], "r+") as f:
        g = f.create_group(TRAJECTORY)
        for name, value in (("latitude", 34.25), ("longitude", 108.95), ("height", 400.0),
                            ("heading", 90.0), ("pitch", 0.0), ("roll", 0.0)):
            g.create_dataset(name, data=np.full(1800, value))
        g.create_dataset("velocity", data=np.zeros((1800, 3)))
        g.create_dataset("gnss_visible", data=np.ones(1800, dtype=np.int8))
    return out


def _digest(folder: pathlib.Path) -> dict[str, str]:
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _delete(path):
    def change(f):
        del f[path]
    return change


def _replace(path, fn):
    def change(f):
        data = fn(f[path][...])
        del f[path]
        f.create_dataset(path, data=data)
    return change


def _attr(key, value):
    def change(f):
        f.attrs[key] = value
    return change


def _set(path, value):
    def change(f):
        f[path][...] = value
    return change


def _details(old: bytes, new: bytes):
    def change(f):
        ds = f["timeline/details"]
        ds[...] = np.array([v.replace(old, new) for v in ds[...]], dtype=object)
    return change


#: (id, which run, damage, words the one line must hold) for ``rlgsim navigate``
NAVIGATE = [
    ("vehicle run", "vehicle", None, "a run on a vehicle (group trajectory)"),
    ("vehicle run, truth group gone", "vehicle", _delete("truth"), "a run on a vehicle"),
    ("no truth group", "static", _delete("truth"), "no group 'truth'"),
    ("no imu group", "static", _delete("imu"), "no group 'imu'"),
    ("no timeline group", "static", _delete("timeline"), "no group 'timeline'"),
    ("no thermal group", "static", _delete("thermal"), "no group 'thermal'"),
    ("no gyro_pulses", "static", _delete("imu/gyro_pulses"), "imu/gyro_pulses"),
    ("no imu/gyro", "static", _delete("imu/gyro"), "imu/gyro"),
    ("no truth/coefficient", "static", _delete("truth/coefficient"), "truth/coefficient"),
    ("no coefficient_units", "static", _delete("truth/coefficient_units"),
     "truth/coefficient_units"),
    ("no gyro_bias", "static", _delete("truth/gyro_bias"), "truth/gyro_bias"),
    ("no power_on", "static", _delete("thermal/power_on"), "thermal/power_on"),
    ("gyro pulses 2 columns", "static", _replace("imu/gyro_pulses", lambda v: v[:, :2]),
     "imu/gyro_pulses"),
    ("gyro pulses 1-D", "static", _replace("imu/gyro_pulses", lambda v: v[:, 0]),
     "imu/gyro_pulses"),
    ("gyro pulses strings", "static", _replace("imu/gyro_pulses", lambda v: v.astype("S8")),
     "numbers of shape"),
    ("accel pulses 4 columns", "static",
     _replace("imu/accel_pulses", lambda v: np.hstack([v, v[:, :1]])), "imu/accel_pulses"),
    ("gyro bias 2 columns", "static", _replace("truth/gyro_bias", lambda v: v[:, :2]),
     "truth/gyro_bias"),
    ("gyro bias shorter than its random part", "static",
     _replace("truth/gyro_bias", lambda v: v[:10]), "truth/gyro_bias_random"),
    ("scale factor 0", "static", _set("truth/coefficient_value", 0.0), "finite number > 0"),
    ("latitude 95", "static", _attr("latitude_deg", 95.0), "latitude_deg must be in [-90, 90]"),
    ("latitude NaN", "static", _attr("latitude_deg", np.nan), "latitude_deg"),
    ("height inf", "static", _attr("height_m", np.inf), "height_m"),
    ("height -1e7", "static", _attr("height_m", -1e7), "height_m"),
    ("latitude missing", "static", lambda f: f.attrs.__delitem__("latitude_deg"),
     "root attribute latitude_deg = None"),
    ("turntable kind unknown", "static", _details(b'"kind": "static"', b'"kind": "rate"'),
     "turntable motion cannot be rebuilt"),
    ("a lost IMU frame", "static",
     lambda f: f["imu"].create_dataset("sample_valid", data=(np.arange(1800) != 1000)
                                       .astype(np.int8)),
     "imu/sample_valid: frame 1000 (100 s) was lost"),
]


@pytest.mark.parametrize("run, damage, words", [c[1:] for c in NAVIGATE],
                         ids=[c[0] for c in NAVIGATE])
def test_navigate_damaged_or_vehicle_dataset(runs, tmp_path, capsys, run, damage, words):
    path = tmp_path / "bad.h5"
    shutil.copy(runs[run], path)
    if damage is not None:
        with h5py.File(path, "r+") as f:
            damage(f)
    before = _digest(tmp_path)
    out = tmp_path / "out" / "p2" / "p3"               # -o p1/p2/p3 left p1/p2 (review 5)
    line = one_line(capsys, ["navigate", str(path), "--align-s", "60", "-q", "-o", str(out)])
    assert words in line and "bad.h5" in line
    assert _digest(tmp_path) == before                 # nothing rewritten, nothing written
    assert not (tmp_path / "out").exists()             # not even the output folders


#: (id, argv after ``navigate SOURCE --align-s 60 -q``, a file made first, words)
NAVIGATE_OUTPUT = [
    ("output folder is a file", ["-o", "{d}/f.txt"], "f.txt", "is a regular file, not a folder"),
    ("output folder is the input", ["-o", "{src}"], None, "is a regular file, not a folder"),
    ("output folder under a file", ["-o", "{d}/f.txt/x"], "f.txt", "f.txt/x"),
    ("output /dev/null", ["-o", "/dev/null"], None, "not a folder"),
    ("output a dangling link", ["-o", "{d}/link"], "link", "which does not exist"),
    ("output under /proc", ["-o", "/proc/rlgsim-navigation"], None,
     "cannot create the output folder"),
    ("report over the input", ["-o", "{d}"], None, "is also an input of this command"),
]


@pytest.mark.parametrize("argv, made, words", [c[1:] for c in NAVIGATE_OUTPUT],
                         ids=[c[0] for c in NAVIGATE_OUTPUT])
def test_navigate_output_checked_before_work(runs, tmp_path, capsys, argv, made, words):
    src = tmp_path / ("summary.csv" if "{d}" == argv[-1] else "run.h5")
    if src.suffix == ".csv":                           # a recording named like an output
        assert main(["export", str(runs["static"]), "-o", str(src), "-q"]) == 0
    else:
        shutil.copy(runs["static"], src)
    if made == "link":
        (tmp_path / made).symlink_to(tmp_path / "nowhere")
    elif made:
        (tmp_path / made).write_text("keep me\n")
    before = _digest(tmp_path)
    argv = [a.format(d=tmp_path, src=src) for a in argv]
    line = one_line(capsys, ["navigate", str(src), "--align-s", "60", "-q", *argv])
    assert words in line
    assert _digest(tmp_path) == before


STUDY = """
[study]
name = "fuzz_vehicle"
recipe = "vehicle"
[train]
scenario = "static.toml"
window_s = 30
[mission]
scenario = "vehicle.toml"
[[compensator]]
name = "LS cubic T"
inputs = ["T"]
degree = 3
[[compensator]]
name = "LS quadratic T, dT/dt"
inputs = ["T", "dT/dt"]
degree = 2
"""

#: (id, (old, new) replacements of :data:`STUDY`, words of the one line) for ``rlgsim study``;
#: each is refused before anything is simulated
STUDY_CASES = [
    ("name raw", [('"LS cubic T"', '"raw"')], "compensator[0].name: 'raw' not allowed"),
    ("name truth", [('"LS cubic T"', '"truth"')], "compensator[0].name: 'truth'"),
    ("name oracle", [('"LS cubic T"', '"oracle"')], "compensator[0].name: 'oracle'"),
    ("name twice", [('"LS quadratic T, dT/dt"', '"LS cubic T"')],
     "compensator[1].name: 'LS cubic T' not allowed"),
    ("name empty", [('"LS cubic T"', '""')], "compensator[0].name: '' not allowed"),
    ("input twice", [('inputs = ["T"]', 'inputs = ["T", "T"]')],
     "compensator[0].inputs: ['T', 'T'] names an input twice"),
    ("window longer than the train run", [("window_s = 30", "window_s = 1e9")],
     "train.scenario: fuzz_static lasts 180 s, shorter than train.window_s"),
    ("mission shorter than a window", [('"vehicle.toml"', '"vehicle.toml"\nduration_h = 1e-9')],
     "mission.scenario: fuzz_vehicle lasts"),
    ("mission without a trajectory", [('"vehicle.toml"', '"static.toml"')],
     "mission.scenario: 'static.toml' has no [trajectory]"),
    ("mission that does not exist", [('"vehicle.toml"', '"no_such_mission"')],
     "mission.scenario: unknown scenario 'no_such_mission'"),
    ("window of one thermal step", [("window_s = 30", "window_s = 1")],
     "train.window_s: 1 s not allowed; a window holds a whole number"),
    ("window not a whole number of samples", [("window_s = 30", "window_s = 97.35")],
     "train.window_s: 97.35 s not allowed"),
    ("single-gyro train device", [('"static.toml"', '"single.toml"')],
     "train.scenario: fuzz_static's device trplg_001 has gyro axes z, no accelerometers"),
    ("export_models", [('recipe = "vehicle"', 'recipe = "vehicle"\nexport_models = true')],
     "study.export_models: the vehicle recipe does not export its compensators"),
    ("mission route past the gyro range", [('"vehicle.toml"', '"fast_turn.toml"')],
     "trajectory: body rate"),
    ("too few windows for a compensator", [("window_s = 30", "window_s = 60")],
     "train.window_s: 60 s leaves at most 3 powered window(s) in the train run; compensator "
     "'LS cubic T' has 4 coefficients"),
    ("mission sample rate past the limit",
     [('"vehicle.toml"', '"vehicle.toml"\nsample_rate_hz = 1e6')],
     "acquisition.sample_rate_hz: value 1e+06 not allowed"),
]


@pytest.mark.parametrize("changes, words", [c[1:] for c in STUDY_CASES],
                         ids=[c[0] for c in STUDY_CASES])
def test_vehicle_study_refused_before_any_run(tmp_path, capsys, changes, words):
    (tmp_path / "static.toml").write_text(STATIC)
    (tmp_path / "vehicle.toml").write_text(VEHICLE)
    (tmp_path / "single.toml").write_text(STATIC.replace('"rlg_imu_000"', '"trplg_001"'))
    (tmp_path / "fast_turn.toml").write_text(VEHICLE.replace("by_deg = 90.0", "by_deg = 9e4"))
    text = STUDY
    for old, new in changes:
        assert old in text
        text = text.replace(old, new, 1)
    (tmp_path / "s.toml").write_text(text)
    before = _digest(tmp_path)
    line = one_line(capsys, ["study", str(tmp_path / "s.toml"), "-q", "-o",
                             str(tmp_path / "out")])
    assert words in line
    assert _digest(tmp_path) == before                 # no run simulated, nothing written


@pytest.mark.parametrize("kind", ["dataset", "recording"])
def test_window_longer_than_the_run_is_one_line(runs, tmp_path, kind):
    from rlgsim.ground.errors import UserInputError
    from rlgsim.lab.api import window_table
    source = runs["static"]
    if kind == "recording":
        source = tmp_path / "rec.csv"
        assert main(["export", str(runs["static"]), "-o", str(source), "-q"]) == 0
    what = "run" if kind == "dataset" else kind        # one check for both (review item 9)
    with pytest.raises(UserInputError, match=rf"{source.name}: 180 s of data hold no complete "
                                             rf"1000-s window; a window must fit in the {what} "
                                             rf"\(a shorter window or a longer {what}\)$"):
        window_table(source, 1000.0, gyro="x")


#: (id, which run, damage, table format, words) for ``rlgsim export`` of a dataset
EXPORT = [
    ("vehicle run, truth misshapen", "vehicle",
     _replace("trajectory/velocity", lambda v: v[:, :2]), "csv",
     "trajectory/velocity is not one value per IMU sample"),
    ("gyro pulses 1-D", "static", _replace("imu/gyro_pulses", lambda v: v[:, 0]), "csv",
     "imu/gyro_pulses is int32 with 1 dimension(s)"),
    ("accel pulses float", "static", _replace("imu/accel_pulses", lambda v: v.astype(float)),
     "csv", "imu/accel_pulses is float64"),
    ("gyro pulses shorter than accel", "static", _replace("imu/gyro_pulses", lambda v: v[:100]),
     "csv", "gyro and accelerometer of one length"),
]


@pytest.mark.parametrize("run, damage, fmt, words", [c[1:] for c in EXPORT],
                         ids=[c[0] for c in EXPORT])
def test_export_refuses_vehicle_and_damaged_pulses(runs, tmp_path, capsys, run, damage, fmt,
                                                   words):
    path = tmp_path / "bad.h5"
    shutil.copy(runs[run], path)
    if damage is not None:
        with h5py.File(path, "r+") as f:
            damage(f)
    (tmp_path / "bad.toml").write_text("# the user's notes beside the dataset\n")
    before = _digest(tmp_path)
    line = one_line(capsys, ["export", str(path), "--format", fmt, "-q"])
    assert words in line and "bad.h5" in line
    assert _digest(tmp_path) == before                 # no table, no sidecar rewritten


@pytest.mark.parametrize("offset_c, rate_rel, words", [
    (1e6, 0.0, r"an offset of .* K \(from --chamber-offset-c 1e\+06\), which takes the chamber "
               r"to .* °C; it holds -100 to 200 °C"),
    (0.0, 1000.0, r"a rate factor of (inf|0) \(from --chamber-rate-rel 1000\)")])
def test_montecarlo_chamber_spread_past_the_chamber_is_refused(tmp_path, offset_c, rate_rel,
                                                                words):
    """``--chamber-offset-c 1e6`` put a unit's chamber at ~1e5 °C (overflow warnings, exit 0);
    ``--chamber-rate-rel 1000`` an infinite or zero ramp rate factor: the unit is refused (a
    factor of 0 on a ramp given by its duration was a ZeroDivisionError before the check)."""
    from rlgsim.ground.errors import UserInputError
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.unit_variations import ChamberVariation, apply, varied
    hold = 'type = "hold"\nduration_min = 3'
    assert hold in STATIC
    (tmp_path / "static.toml").write_text(
        STATIC.replace(hold, 'type = "ramp"\nto_c = 25.0\nduration_min = 3'))
    sc = load_scenario(str(tmp_path / "static.toml"))
    with varied(ChamberVariation(offset_c=offset_c, rate_rel=rate_rel)):
        with pytest.raises(UserInputError, match=words):
            for unit in range(16):                     # a draw past the limits in 16 units
                apply(dataclasses.replace(sc, unit=unit))
    if rate_rel:                                       # both ends: a factor of 0 and of inf
        with varied(ChamberVariation(offset_c=0.0, rate_rel=rate_rel)):
            factors = set()
            for unit in range(16):                     # any other exception fails the test
                try:
                    apply(dataclasses.replace(sc, unit=unit))
                except UserInputError as e:
                    factors.add(str(e).split("rate factor of ")[1].split(" ")[0])
            assert factors == {"0", "inf"}, factors
    with varied(ChamberVariation(offset_c=2.0, rate_rel=0.1)):
        assert apply(sc).chamber.start_c != sc.chamber.start_c   # a sane spread still runs


#: (id, change of the exported table (a DataFrame), of its sidecar (text), words) for
#: ``rlgsim navigate`` of a recording
RECORDING = [
    ("orientation NaN", None, lambda t: t + "\n[orientation]\nx = [nan, 0.0, 0.0]\n",
     "orientation.x: value [nan, 0.0, 0.0] not allowed"),
    ("orientation of an unknown axis", None, lambda t: t + "\n[orientation]\nw = [1.0, 0, 0]\n",
     "orientation.w: unknown axis"),
    ("two axes along east", None,
     lambda t: t + "\n[orientation]\nx = [1.0, 0, 0]\ny = [1.0, 0, 0]\n",
     "is not a right-handed orthonormal triad"),
    ("left-handed axes", None,
     lambda t: t + "\n[orientation]\nx = [0, 1.0, 0]\ny = [1.0, 0, 0]\n",
     "is not a right-handed orthonormal triad"),
    ("a dropout row", lambda df: df.assign(dropout=(df.index == 500).astype(int)), None,
     "row 501 is a dropout"),
    ("accelerometer pulses past 100 g", lambda df: df.assign(accel_x_pulses=-2 ** 62), None,
     "pulses per sample is over 100 g"),
]


@pytest.mark.parametrize("table, sidecar, words", [c[1:] for c in RECORDING],
                         ids=[c[0] for c in RECORDING])
def test_navigate_bad_recording(runs, tmp_path, capsys, table, sidecar, words):
    import pandas as pd
    src = tmp_path / "rec.csv"
    assert main(["export", str(runs["static"]), "-o", str(src), "-q"]) == 0
    if table is not None:
        table(pd.read_csv(src)).to_csv(src, index=False)
    side = tmp_path / "rec.toml"
    if sidecar is not None:
        side.write_text(sidecar(side.read_text()))
    before = _digest(tmp_path)
    line = one_line(capsys, ["navigate", str(src), "--align-s", "60", "-q",
                             "-o", str(tmp_path / "out")])
    assert words in line
    assert _digest(tmp_path) == before


def test_montecarlo_unreachable_scheduler_leaves_no_folder(tmp_path, capsys):
    pytest.importorskip("distributed")
    (tmp_path / "static.toml").write_text(STATIC)
    (tmp_path / "vehicle.toml").write_text(VEHICLE)
    (tmp_path / "s.toml").write_text(STUDY)
    line = one_line(capsys, ["montecarlo", str(tmp_path / "s.toml"), "--units", "1", "-q",
                             "--scheduler", "tcp://127.0.0.1:1", "-o", str(tmp_path / "mc")])
    assert "--scheduler: cannot connect" in line
    assert not (tmp_path / "mc").exists()


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_exported_drive_is_marked_and_refused_by_fixed_site_readers(runs, tmp_path, capsys,
                                                                     fmt):
    """A drive exports (pulses, and its truth as a table of the same format) with
    ``platform = "vehicle"`` in the sidecar; the readers that take a recording's IMU at a fixed
    site refuse it naming that key (the drive's rotation would read as gyro bias)."""
    import tomllib

    from rlgsim.ground.errors import UserInputError
    from rlgsim.lab.api import window_table
    table = tmp_path / f"drive.{fmt}"
    assert main(["export", str(runs["vehicle"]), "--format", fmt, "-o", str(table), "-q"]) == 0
    side = tomllib.loads((tmp_path / "drive.toml").read_text())["recording"]
    assert side["platform"] == "vehicle" and side["trajectory"] == f"drive_trajectory.{fmt}"
    assert (tmp_path / side["trajectory"]).is_file()
    words = "recording.platform = 'vehicle'"
    for argv in (["navigate", str(table), "-q", "-o", str(tmp_path / "nav")],
                 ["identify", str(table), "--device-template", "rlg_imu_000", "-q", "-o",
                  str(tmp_path / "twin")],
                 ["calibrate", str(table), "--programme", str(tmp_path / "p.csv"), "-q"]):
        assert words in one_line(capsys, argv)
    with pytest.raises(UserInputError, match=words):
        window_table(table, 60.0, gyro="x")
    assert main(["info", str(table)]) == 0
    assert f"platform: vehicle (the IMU moved; its truth: drive_trajectory.{fmt})" in \
        capsys.readouterr().out
    # re-exported (review item 6): the truth table is not copied, so the sidecar names it only
    # where it still lies beside the new table; platform stays either way
    (tmp_path / "other").mkdir()
    for out, kept in ((tmp_path / "other" / "again.csv", False), (tmp_path / "again.csv", True)):
        assert main(["export", str(table), "-o", str(out), "-q"]) == 0
        again = tomllib.loads(out.with_suffix(".toml").read_text())["recording"]
        assert again["platform"] == "vehicle"
        assert again.get("trajectory") == (f"drive_trajectory.{fmt}" if kept else None)


@pytest.mark.parametrize("run", ["static", "vehicle"])
def test_export_plan_opens_the_dataset_once(runs, tmp_path, monkeypatch, run):
    """planned_outputs opened the dataset twice (calibration windows, then the trajectory
    group) before the export opened it again (review item 9): one open answers both."""
    import rlgsim.ground.dataset_format as dataset_format
    from rlgsim.ground.recording_export import planned_outputs
    opened = []
    real = dataset_format.open_dataset
    monkeypatch.setattr(dataset_format, "open_dataset",
                        lambda path, *a, **k: opened.append(path) or real(path, *a, **k))
    outputs = planned_outputs(runs[run], "csv", tmp_path / "r.csv")
    assert len(opened) == 1
    assert ("trajectory" in outputs) == (run == "vehicle")


def _nav(path, **kw):
    """The navigation errors of ``path`` (in-process, no report): 60-s alignment."""
    from rlgsim.lab.navigation import navigate
    ds = navigate(path, align_s=60.0, **kw)
    return {k: np.asarray(ds[k]) for k in ds.data_vars}


def test_recording_columns_are_navigated_by_axis_name(runs, tmp_path):
    """Review item 1: a table listing gyro_z, gyro_y, gyro_x (default mount: the identity) was
    refused as not a right-handed triad, and accelerometers z, y, x beside gyros x, y, z were
    paired by column order (heading error ~57 times the true one). Any column order now
    navigates to exactly the errors of the x, y, z table."""
    import pandas as pd
    src = tmp_path / "rec.csv"
    assert main(["export", str(runs["static"]), "-o", str(src), "-q"]) == 0
    want = _nav(src, span_s=60.0)
    table = pd.read_csv(src)
    g, a = [f"gyro_{x}_pulses" for x in "xyz"], [f"accel_{x}_pulses" for x in "xyz"]
    for order in (g[::-1] + a, a[::-1] + [g[1], g[2], g[0]]):
        table[["time_s", *order]].to_csv(src, index=False)       # the pulses only
        got = _nav(src, span_s=60.0)
        assert [k for k in want if not np.array_equal(got[k], want[k], equal_nan=True)] == [], order


def test_rounded_direction_cosines_are_taken(tmp_path, capsys):
    """Review item 2: a 45° mount written to 4 decimals ([0.7071, 0.7071, 0]) was refused as
    "not a unit vector" by every command, info too. The sidecar normalises each vector (norm
    within 1e-3) and the navigation's body frame is the nearest rotation (to the rounding:
    ~1e-4); a norm 1 % off and a repeated axis are still refused."""
    from rlgsim.ground.errors import UserInputError
    from rlgsim.ground.recording_sidecar import read_sidecar
    from rlgsim.lab.navigation_mount import body_frame
    (tmp_path / "r.csv").write_text("time_s,gyro_x_rate_deg_per_s\n0,0\n0.1,0\n")
    head = '[recording]\nsample_rate_hz = 10\ndata = "r.csv"\n\n[orientation]\n'
    (tmp_path / "r.toml").write_text(head + "x = [0.7071, 0.7071, 0]\n"
                                     "y = [-0.7071, 0.7071, 0]\nz = [0, 0, 1]\n")
    assert main(["info", str(tmp_path / "r.toml")]) == 0, capsys.readouterr().err
    sc = read_sidecar(tmp_path / "r.toml")
    c = body_frame(sc.orientation, ["x", "y", "z"], "r.toml")
    s = np.sqrt(0.5)
    exact = np.array([[s, s, 0], [-s, s, 0], [0, 0, 1]])
    np.testing.assert_allclose(c @ c.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(c, exact, atol=2e-5)       # the 4th decimal's rounding
    assert np.linalg.det(c) > 0
    (tmp_path / "r.toml").write_text(head + "x = [1.01, 0, 0]\n")
    with pytest.raises(UserInputError, match=r"orientation.x: .* must be a unit vector"):
        read_sidecar(tmp_path / "r.toml")
    with pytest.raises(UserInputError, match="not a right-handed orthonormal triad"):
        body_frame({"x": [1.0, 0, 0], "y": [0.9999, 0.0141, 0]}, ["x", "y", "z"], "r.toml")


@pytest.mark.parametrize("kind", ["dataset", "recording"])
def test_a_dropout_after_the_navigated_span_is_no_matter(runs, tmp_path, kind):
    """Review item 3: a lost sample anywhere refused the whole run, even past the span asked
    (a 24-h recording with a dropout at 20 h navigated for 8 h). The static run (3 min, 10 Hz,
    alignment 60 s) loses sample 1500 (150 s): a 60-s span (to 120 s) navigates to exactly the
    errors of the intact run; the rest of the run (to 180 s) is refused naming it."""
    import pandas as pd

    from rlgsim.ground.errors import UserInputError
    if kind == "dataset":
        path = tmp_path / "lost.h5"
        shutil.copy(runs["static"], path)
        want = _nav(path, span_s=60.0)
        with h5py.File(path, "r+") as f:
            f["imu"].create_dataset("sample_valid", data=(np.arange(1800) != 1500)
                                    .astype(np.int8))
        words = r"imu/sample_valid: frame 1500 \(150 s\) was lost .* end the span before 150 s"
    else:
        path = tmp_path / "rec.csv"
        assert main(["export", str(runs["static"]), "-o", str(path), "-q"]) == 0
        want = _nav(path, span_s=60.0)
        table = pd.read_csv(path)
        table.assign(dropout=(table.index == 1500).astype(int)).to_csv(path, index=False)
        words = r"row 1501 is a dropout .* end the span before 150 s"
    got = _nav(path, span_s=60.0)
    assert [k for k in want if not np.array_equal(got[k], want[k], equal_nan=True)] == []
    with pytest.raises(UserInputError, match=words):
        _nav(path)


def test_navigate_advises_the_vehicle_study_for_an_exported_drive(runs, tmp_path, capsys):
    """Review item 4: navigate refused an exported drive saying "give the dataset itself",
    which navigate refuses too; it now says what identify cannot: the vehicle study's aided
    navigator scores a drive (identify and calibrate keep "the dataset itself")."""
    table = tmp_path / "drive.csv"
    assert main(["export", str(runs["vehicle"]), "-o", str(table), "-q"]) == 0
    line = one_line(capsys, ["navigate", str(table), "-q", "-o", str(tmp_path / "nav")])
    assert "recording.platform = 'vehicle'" in line and "dataset itself" not in line
    assert "aided navigator of the vehicle study" in line
    line = one_line(capsys, ["identify", str(table), "--device-template", "rlg_imu_000", "-q",
                             "-o", str(tmp_path / "twin")])
    assert "give the dataset itself" in line


def test_own_axis_names_keep_their_order_and_unit_vectors_their_bits(tmp_path):
    """Final review: axes of the user's own names were sorted (roll, pitch, yaw → pitch, roll,
    yaw), which turned a right-handed mount left-handed and refused it; and a unit vector was
    normalised again, changing its last bits ([0, 0.28, 0.96] has a float norm of 1 − 1e-16)
    and with them every result that reads the mount."""
    from rlgsim.ground.recording_sidecar import read_sidecar
    from rlgsim.lab.navigation_mount import body_axes, body_frame
    names = ["roll", "pitch", "yaw"]
    assert body_axes(names, names[::-1], "w") == names
    mount = {"roll": [0.0, 1.0, 0.0], "pitch": [1.0, 0.0, 0.0], "yaw": [0.0, 0.0, -1.0]}
    assert np.linalg.det(body_frame(mount, names, "w")) > 0
    (tmp_path / "r.csv").write_text("time_s,gyro_x_rate_deg_per_s\n0,0\n0.1,0\n")
    (tmp_path / "r.toml").write_text('[recording]\nsample_rate_hz = 10\ndata = "r.csv"\n\n'
                                     "[orientation]\nx = [0, 0.28, 0.96]\n")
    assert read_sidecar(tmp_path / "r.toml").orientation["x"].tolist() == [0.0, 0.28, 0.96]


def test_a_misspelt_orientation_axis_is_refused_without_axes_lists(tmp_path, capsys):
    """Final review: with no [gyro]/[accelerometer] axes lists the sidecar cannot check its
    [orientation] keys, and a misspelt X was dropped silently (the mount read as the default
    east-north-up); the table's columns check them now. A key of a column's axis still reads."""
    (tmp_path / "r.csv").write_text("time_s,gyro_roll_rate_deg_per_s\n0,0\n0.1,0\n")
    head = '[recording]\nsample_rate_hz = 10\ndata = "r.csv"\n\n[orientation]\n'
    (tmp_path / "r.toml").write_text(head + "X = [0, 1, 0]\n")
    line = one_line(capsys, ["info", str(tmp_path / "r.toml")])
    assert "orientation.X: unknown axis; the table's axes are roll" in line
    (tmp_path / "r.toml").write_text(head + "roll = [0, 1, 0]\n")
    assert main(["info", str(tmp_path / "r.toml")]) == 0, capsys.readouterr().err
