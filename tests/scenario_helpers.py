"""Helpers for tests that build scenarios: TOML text of a dict (tomlkit, through
:mod:`rlgsim.ground.toml_text`) and the quickstart as a dict."""

from __future__ import annotations

import copy
import pathlib
import tomllib

from rlgsim.sim.scenario import Scenario, parse_scenario
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
