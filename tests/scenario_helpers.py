"""Helpers for tests that build scenarios: TOML text of a dict (tomlkit, through
:mod:`rlgsim.ground.toml_text`), the quickstart as a dict, small scenarios and studies shared
by the CLI-level tests, and the check of a command's one-line error (:func:`one_line`)."""

from __future__ import annotations

import copy
import pathlib
import tomllib

from rlgsim.sim.run.scenario import Scenario, parse_scenario
from rlgsim.ground.toml_text import dumps, value_text

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
QUICKSTART_PATH = SCENARIOS / "quickstart.toml"


def toml_value(v) -> str:
    """One TOML value (tables and arrays inline)."""
    return value_text(v)


def to_toml(d: dict) -> str:
    """A TOML document of ``d`` (sub-tables as tables, lists of tables as arrays of tables)."""
    return dumps(d)


def quickstart() -> dict:
    """The shipped quickstart scenario as a (fresh) dict."""
    return copy.deepcopy(tomllib.loads(QUICKSTART_PATH.read_text()))


def scenario(d: dict, source: str = "test.toml") -> Scenario:
    """Parse a scenario dict (device names resolve against the shipped presets)."""
    return parse_scenario(to_toml(d), source, base_dir=SCENARIOS)


# Small scenarios and a study shared by the CLI-level tests (Monte Carlo, kill -9, damaged data).

#: A 942 s turntable calibration (19 positions) of the IMU preset during a 0.5 °C/min ramp.
CAL_SCENARIO = """
name = "cal"
device = "rlg_imu_000"
seed = 3
duration_s = 942
[acquisition]
sample_rate_hz = 100
[chamber]
start_c = 20.0
[[chamber.segments]]
type = "ramp"
to_c = 30.0
rate_c_per_min = 0.5
[turntable]
program = "calibration19"
dwell_s = 20.0
first_dwell_s = 30.0
"""

#: A short temperature cycle of the paper-001 gyro (about 1 s per unit); the middle hold lasts
#: ``HOLD`` minutes (:func:`tiny_cycle`).
_TINY_CYCLE = """
name = "tiny_cycle"
device = "trplg_001"
seed = 11
[acquisition]
sample_rate_hz = 1
thermal_step_s = 5
[chamber]
start_c = 20.0
[[chamber.segments]]
type = "hold"
duration_min = 20
[[chamber.segments]]
type = "ramp"
to_c = 40.0
rate_c_per_min = 1.0
[[chamber.segments]]
type = "hold"
duration_min = HOLD
[[chamber.segments]]
type = "ramp"
to_c = 20.0
rate_c_per_min = 1.0
"""


def tiny_cycle(hold_min: float = 40) -> str:
    """The short cycle with a middle hold of ``hold_min`` minutes (scenario ``tiny_cycle``)."""
    return _TINY_CYCLE.replace("HOLD", f"{hold_min:g}")


TINY_SCENARIO = tiny_cycle()
#: A study with the real recipe on the short cycle (train seed 21, test seed 22, one LS fit).
TINY_STUDY = """
[study]
name = "tiny"
recipe = "bias_compensation"
device_seed = 5
[data]
train = [{ scenario = "tiny_cycle.toml", seed = 21 }]
test = [{ scenario = "tiny_cycle.toml", seed = 22 }]
window_s = 100
[features]
temperature = "g.A"
uhfo = true
[[compensator]]
name = "LS quadratic T, U"
kind = "polynomial"
inputs = ["T", "U"]
params = { degree = 2 }
[metrics]
cluster_s = 100
baseline = "raw"
"""


def tiny_study(folder: pathlib.Path) -> pathlib.Path:
    """:data:`TINY_STUDY` with its cycle (:data:`TINY_SCENARIO`) written into ``folder``
    (made if missing); returns the study file's path (``folder/tiny.toml``)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tiny_cycle.toml").write_text(TINY_SCENARIO)
    path = folder / "tiny.toml"
    path.write_text(TINY_STUDY)
    return path


def demo_on_tiny_cycle(folder: pathlib.Path) -> pathlib.Path:
    """The shipped demo study — its device, features and every compensator (the stochastic
    LSSVM tuning included) — on the 100-min tiny cycle (1 Hz, 60 windows) instead of its two
    8-h runs at 10 Hz: the same code paths at a fraction of the cost (the suite's time, issue
    30). Writes the study file (and the cycle beside it) into ``folder``; returns its path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tiny_cycle.toml").write_text(TINY_SCENARIO)
    text = (SCENARIOS / "studies" / "demo.toml").read_text()
    for role, seed in (("train", 7001), ("test", 7002)):
        line = f'{role} = [{{ scenario = "demo_cycle", seed = {seed} }}]'
        assert line in text, line
        text = text.replace(line, f'{role} = [{{ scenario = "tiny_cycle.toml", seed = {seed} }}]')
    path = folder / "demo_tiny.toml"
    path.write_text(text)
    return path


def one_line(capture, argv: list[str]) -> str:
    """``rlgsim ARGV`` through the command's entry point in this process, for a user mistake:
    exit status 2 and one line on stderr starting ``rlgsim: error: ``, no traceback. Returns
    that line. ``capture``: pytest's ``capsys`` or ``capfd`` (whose stderr is read)."""
    from rlgsim.lab.cli.main import main
    code = main(argv)
    err = capture.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rlgsim: error: "), err
    return lines[0]
