"""Hostile inputs and outputs of the command line (issue 15): every one is a single line
``rlgsim: error: ...`` naming the file/key, exit code 2, no traceback, nothing at the final
path — non-regular inputs (FIFO, /dev/zero, directories), deep TOML, a BOM, absurd preset
coefficients, runs that cannot finish (motions, memory per block, disk), output paths (devices,
symlinks, an input as output, names escaping the working folder, over-long names), and a
hypothesis fuzz of scenario and TOML text."""

from __future__ import annotations

import os
import pathlib
import re

import pytest
from hypothesis import example, given, HealthCheck, settings
from hypothesis import strategies as st

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.main import main

ROOT = pathlib.Path(__file__).resolve().parents[1]
QUICK = (ROOT / "scenarios" / "quickstart.toml").read_text()
DEMO_STUDY = (ROOT / "scenarios" / "studies" / "demo.toml").read_text()
DEVICE = (ROOT / "scenarios" / "devices" / "rlg8_003.toml").read_text()


def short(text: str = QUICK, duration: str = "duration_s = 600", **subs: str) -> str:
    text = text.replace("duration_h = 2.0", duration)
    for old, new in subs.items():
        text = text.replace(old, new)
    return text


def one_error(capsys, argv: list[str], *needles: str) -> str:
    """Run the CLI; assert exit 2 and exactly one error line holding every needle."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rlgsim: error: "), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.fixture
def here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def no_output(folder: pathlib.Path, name: str) -> None:
    assert not (folder / name).exists()
    assert not [p for p in folder.iterdir() if ".tmp" in p.name], list(folder.iterdir())


# ---------------------------------------------------------------- non-regular inputs (6, 11)


def test_fifo_and_devices_as_scenario_or_device_are_refused(here, capsys):
    os.mkfifo(here / "pipe.toml")
    one_error(capsys, ["run", "./pipe.toml"], "pipe.toml", "FIFO")
    one_error(capsys, ["run", "/dev/zero"], "/dev/zero", "character device")
    (here / "devzero.toml").write_text(short(**{'device = "rlg8_003"': 'device = "/dev/zero"'}))
    one_error(capsys, ["run", "devzero.toml"], "devzero.toml: device: /dev/zero", "character")
    (here / "pipe_dev.toml").write_text(short(**{'device = "rlg8_003"': 'device = "pipe.toml"'}))
    one_error(capsys, ["run", "pipe_dev.toml"], "pipe_dev.toml: device:", "FIFO")
    (here / "folder").mkdir()
    (here / "dirdev.toml").write_text(short(**{'device = "rlg8_003"': 'device = "folder/"'}))
    one_error(capsys, ["run", "dirdev.toml"], "dirdev.toml: device:", "directory")
    one_error(capsys, ["info", "pipe.toml"], "pipe.toml", "FIFO")
    one_error(capsys, ["info", "/dev/zero"], "character device")
    one_error(capsys, ["calibrate", "pipe.toml"], "FIFO")
    (here / "data.h5").write_bytes(b"x")
    one_error(capsys, ["calibrate", "data.h5", "--programme", "pipe.toml"], "pipe.toml", "FIFO")
    one_error(capsys, ["study", "./pipe.toml"], "FIFO")
    one_error(capsys, ["montecarlo", "./pipe.toml", "--units", "1"], "FIFO")


def test_text_inputs_are_capped(here, capsys):
    with open(here / "huge.toml", "wb") as fh:
        fh.truncate(9 << 20)
    one_error(capsys, ["run", "huge.toml"], "huge.toml", "larger than 8 MiB")


@pytest.mark.parametrize("text", [
    "a = " + "[" * 500 + "]" * 500,
    "a = " + "{b = " * 500 + "1" + "}" * 500,
    ".".join(["a"] * 500) + " = 1",
])
def test_deep_toml_is_one_line(here, capsys, text):
    (here / "deep.toml").write_text(text)
    one_error(capsys, ["run", "deep.toml"], "deep.toml", "nested too deeply")


def test_utf8_bom_is_accepted():
    from rlgsim.sim import presets
    from rlgsim.sim.run.scenario import parse_scenario
    assert presets.parse_toml("\ufeffa = 1", "bom.toml") == {"a": 1}
    sc = parse_scenario("\ufeff" + short(), "bom.toml")
    assert sc.name == "quickstart" and sc.duration_s == 600


def test_bom_file_runs(here, capsys):
    (here / "bom.toml").write_bytes(b"\xef\xbb\xbf" + short().encode())
    assert main(["run", "bom.toml", "-o", "bom.h5", "-q"]) == 0, capsys.readouterr().err
    assert (here / "bom.h5").is_file()


@pytest.mark.parametrize("old,new", [
    ("value_deg_per_h = 0.0", "value_deg_per_h = 3e9"),
    ("scale_factor_pulses_per_arcsec = 10.0", "scale_factor_pulses_per_arcsec = 3e9"),
])
def test_absurd_preset_coefficient_is_refused_by_the_pulse_counter(here, capsys, old, new):
    assert old in DEVICE
    (here / "dev.toml").write_text(DEVICE.replace(old, new))
    (here / "sc.toml").write_text(short(**{'device = "rlg8_003"': 'device = "dev.toml"'}))
    one_error(capsys, ["run", "sc.toml", "-o", "out.h5", "-q"], "pulse counter")
    no_output(here, "out.h5")


def test_pulse_counter_bounds():
    import numpy as np

    from rlgsim.sim.sensors import pulses
    ok = np.full(10, 1e3)
    pulses.check_range(ok)
    for bad in (np.array([np.nan]), np.array([np.inf]), np.array([3e9]),
                np.full(10, 1e9)):
        with pytest.raises(UserInputError, match="pulse counter"):
            pulses.check_range(bad)


# ---------------------------------------------------------------- runs that cannot finish (3)

TABLE = """
[turntable]
program = "custom"
continuous = true
[[turntable.motions]]
type = "hold"
duration_s = {d}
"""


def test_continuous_microsecond_hold_is_refused(here, capsys):
    (here / "tt.toml").write_text(short() + TABLE.format(d="1e-6"))
    one_error(capsys, ["run", "tt.toml", "-q"], "tt.toml", "duration_s", ">= 0.001")
    (here / "tt2.toml").write_text(short(duration="duration_s = 600")
                                   + TABLE.format(d="0.0025"))
    one_error(capsys, ["run", "tt2.toml", "-o", "tt2.h5", "-q"], "tt2.toml: turntable",
              "motion segments")
    no_output(here, "tt2.h5")


def test_block_that_cannot_fit_memory_names_the_key(here, capsys):
    (here / "step.toml").write_text(short(**{"thermal_step_s = 1\n": "thermal_step_s = 1e-6\n"}))
    one_error(capsys, ["run", "step.toml", "-o", "s.h5", "-q"], "step.toml",
              "thermal_step_s = 1e-06", "memory")
    (here / "rate.toml").write_text(short(**{"sample_rate_hz = 100\n":
                                              "sample_rate_hz = 100000\n"}))
    one_error(capsys, ["run", "rate.toml", "-o", "r.h5", "-q"], "rate.toml",
              "sample_rate_hz = 100000", "memory")
    no_output(here, "s.h5")
    no_output(here, "r.h5")


def test_subnormal_thermal_step_is_one_line(here, capsys):
    # hypothesis found it: 600 s / 2.2e-313 overflows to inf, whose round() raised OverflowError
    (here / "sub.toml").write_text(short(**{"thermal_step_s = 1\n": "thermal_step_s = 2.2e-313\n"}))
    one_error(capsys, ["run", "sub.toml", "-o", "sub.h5", "-q"], "sub.toml", "thermal_step_s",
              "must divide")
    no_output(here, "sub.h5")


def test_output_larger_than_the_free_disk_is_refused_under_quiet(here, capsys, monkeypatch):
    import collections

    from rlgsim.sim.run import run_budget
    usage = collections.namedtuple("usage", "total used free")
    monkeypatch.setattr(run_budget.shutil, "disk_usage", lambda p: usage(10**7, 0, 10**5))
    (here / "q.toml").write_text(short())
    line = one_error(capsys, ["run", "q.toml", "-o", "q.h5", "-q"], "q.h5", "free")
    assert re.search(r"about [\d.]+ [kM]B", line), line
    no_output(here, "q.h5")


def test_long_runs_print_their_estimate(here, capsys, monkeypatch):
    from rlgsim.sim.run import run_budget
    monkeypatch.setattr(run_budget, "LONG_RUN_S", 0.0)
    checked, counted = run_budget.check_budget, []

    def check(f, *args, row_bytes=None, **kwargs):
        counted.append(row_bytes)
        return checked(f, *args, row_bytes=row_bytes, **kwargs)
    monkeypatch.setattr(run_budget, "check_budget", check)
    (here / "q.toml").write_text(short())
    assert main(["run", "q.toml", "-o", "q.h5"]) == 0
    err = capsys.readouterr().err
    assert "rlgsim: estimate for quickstart: about" in err and "memory per block" in err
    assert main(["run", "q.toml", "-o", "q2.h5", "-q"]) == 0
    assert "estimate" not in capsys.readouterr().err
    import h5py
    files = [here / "q.h5", here / "q2.h5"]   # one check per run, in the order of the runs
    assert len(counted) == len(files), counted
    for row_bytes, path in zip(counted, files):   # the writers' counts are each run's file's
        with h5py.File(path) as f:                # (the file is laid out after the check)
            assert row_bytes == run_budget._row_bytes(f) and row_bytes[1] > 0, path


def test_estimate_is_close_to_the_real_size(here, capsys):
    import h5py

    from rlgsim.sim.run.run_budget import estimate
    from rlgsim.sim.run.scenario import parse_scenario
    (here / "q.toml").write_text(short(duration="duration_h = 1"))
    assert main(["run", "q.toml", "-o", "q.h5", "-q"]) == 0
    sc = parse_scenario((here / "q.toml").read_text(), "q.toml")
    with h5py.File(here / "q.h5") as f:
        est = estimate(f, sc, n_steps=3600, steps_per_block=600, buffered_blocks=6,
                       block_s=600.0)
        stored = sum(ds.id.get_storage_size() for ds in _datasets(f))
    # an upper bound on the raw rows (pulses are stored packed), within a factor of 3
    assert stored / 3 < est.output_bytes < stored * 3


def _datasets(f):
    import h5py
    out = []
    f.visititems(lambda n, o: out.append(o) if isinstance(o, h5py.Dataset) else None)
    return out


# ---------------------------------------------------------------- output paths (5)


def test_output_onto_a_device_a_symlink_or_an_input_is_refused(here, capsys):
    (here / "q.toml").write_text(short())
    one_error(capsys, ["run", "q.toml", "-o", "/dev/null", "-q"], "/dev/null",
              "character device")
    assert pathlib.Path("/dev/null").is_char_device()
    (here / "target.h5").write_bytes(b"keep")
    (here / "link.h5").symlink_to("target.h5")
    one_error(capsys, ["run", "q.toml", "-o", "link.h5", "-q"], "link.h5", "symbolic link")
    assert (here / "link.h5").is_symlink() and (here / "target.h5").read_bytes() == b"keep"
    before = (here / "q.toml").read_bytes()
    one_error(capsys, ["run", "q.toml", "-o", "q.toml", "-q"], "q.toml", "input")
    assert (here / "q.toml").read_bytes() == before
    os.mkfifo(here / "fifo.h5")
    one_error(capsys, ["run", "q.toml", "-o", "fifo.h5", "-q"], "fifo.h5", "FIFO")
    (here / "table.csv").mkdir()
    one_error(capsys, ["run", "q.toml", "-o", "table.csv", "-q"], "directory")


def test_calibrate_output_equal_to_its_dataset_or_a_device(here, capsys):
    (here / "data.h5").write_bytes(b"not even hdf5")
    one_error(capsys, ["calibrate", "data.h5", "-o", "data.h5"], "data.h5", "input")
    one_error(capsys, ["calibrate", "data.h5", "-o", "/dev/null"], "character device")
    assert (here / "data.h5").read_bytes() == b"not even hdf5"


def test_names_cannot_escape_the_working_folder(here, capsys):
    (here / "sub").mkdir()
    os.chdir(here / "sub")
    (here / "sub" / "esc.toml").write_text(short(**{'name = "quickstart"':
                                                    'name = "../escaped"'}))
    one_error(capsys, ["run", "esc.toml", "-q"], "esc.toml: name", "../escaped", "-o")
    study = DEMO_STUDY.replace('name = "demo"', 'name = "../escaped"', 1)
    (here / "sub" / "st.toml").write_text(study)
    one_error(capsys, ["study", "st.toml", "-q"], "st.toml: study.name", "-o")
    one_error(capsys, ["montecarlo", "st.toml", "--units", "1", "-q"], "st.toml: study.name")
    assert sorted(p.name for p in here.iterdir()) == ["sub"]
    # with -o the same name is fine
    assert main(["run", "esc.toml", "-o", "fine.h5", "-q"]) == 0
    assert (here / "sub" / "fine.h5").is_file()


def test_300_character_names_are_one_line(here, capsys):
    long = "x" * 300
    (here / "q.toml").write_text(short())
    one_error(capsys, ["run", "q.toml", "-o", f"{long}.h5", "-q"], "too long")
    one_error(capsys, ["info", f"{long}.h5"], "too long")
    one_error(capsys, ["calibrate", f"{long}.h5"], "too long")
    one_error(capsys, ["study", "demo", "-o", long, "-q"], "too long")
    one_error(capsys, ["montecarlo", "demo", "--units", "1", "-o", long, "-q"], "too long")
    (here / "named.toml").write_text(short(**{'name = "quickstart"': f'name = "{long}"'}))
    one_error(capsys, ["run", "named.toml", "-q"], "named.toml: name", "-o")


# ---------------------------------------------------------------- fuzz


KEYS = ["duration_h", "seed", "sample_rate_hz", "thermal_step_s", "start_c", "to_c",
        "rate_c_per_min", "duration_min", "on_at_s", "device", "name", "type"]
VALUES = st.one_of(
    st.integers(min_value=-2**70, max_value=2**70).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(
        lambda x: "nan" if x != x else ("inf" if x == float("inf") else
                                        "-inf" if x == float("-inf") else repr(x))),
    st.sampled_from(['""', '"/dev/zero"', '"../x"', '"."', "[]", "{}", "[[1]]", "true",
                     '"\\u0000"', "1979-05-27", '"' + "a" * 300 + '"', "0", "-0.0", "1e-300",
                     "1e308"]))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS), value=VALUES, which=st.integers(0, 3))
@example(key="duration_h", value="1e308", which=0)     # overflowed in SI (OverflowError)
def test_fuzzed_scenario_values_are_user_errors_or_valid(key, value, which):
    from rlgsim.sim.run.scenario import parse_scenario
    lines = QUICK.splitlines()
    hits = [i for i, line in enumerate(lines) if line.split("=")[0].strip() == key]
    if hits:
        lines[hits[which % len(hits)]] = f"{key} = {value}"
    else:
        lines.insert(0, f"{key} = {value}")
    try:
        parse_scenario("\n".join(lines), "fuzz.toml")
    except UserInputError as exc:
        assert "\n" not in str(exc).strip()


@settings(max_examples=80, deadline=None)
@given(st.binary(max_size=200))
def test_fuzzed_toml_bytes_are_user_errors_or_tables(data):
    from rlgsim.sim import presets
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return
    try:
        assert isinstance(presets.parse_toml(text, "fuzz.toml"), dict)
    except UserInputError:
        pass


@pytest.mark.parametrize("continuous", [True, False])
def test_motion_bound_is_never_below_the_count(continuous):
    """check_motions' shortcut (an upper bound from one repetition's steps) against the count
    of the motions themselves, over random programmes (zero-length turns, repeats, lead-ins)."""
    import random
    from rlgsim.sim.motion.turntable import Hold, Repeat, Rotate, TurntableProgram
    from rlgsim.sim.run.run_budget import _motions_bound
    rng = random.Random(7 + continuous)
    for _ in range(40):
        steps = [Hold(rng.choice([0.37, 5.0, 60.0]))]
        for _ in range(rng.randrange(4)):
            steps.append(Rotate("outer", rng.choice([0.0, 360.0, -360.0]), 10.0))
            steps.append(Repeat(rng.randrange(3), (Hold(1.5), Rotate("inner", 360.0, 20.0))))
        prog = TurntableProgram(steps, continuous=continuous,
                                lead_in_s=rng.choice([0.0, 0.5, 100.0]))
        duration = rng.choice([0.2, 7.0, 100.0, 601.5])
        count = sum(1 for _ in prog.motions(until_s=duration))
        assert count <= _motions_bound(prog, duration)
