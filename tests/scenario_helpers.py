"""Helpers for tests that build scenarios: a small TOML writer and the quickstart as a dict."""

from __future__ import annotations

import copy
import json
import math
import pathlib
import tomllib

from rlgsim.sim.scenario import Scenario, parse_scenario

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
QUICKSTART_PATH = SCENARIOS / "quickstart.toml"


def toml_value(v) -> str:
    """One TOML value (tables and arrays inline)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_value(str(k))} = {toml_value(x)}"
                               for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(d: dict) -> str:
    """A TOML document with every key at the top level (sub-tables inline)."""
    return "".join(f"{toml_value(str(k))} = {toml_value(v)}\n" for k, v in d.items())


def quickstart() -> dict:
    """The shipped quickstart scenario as a (fresh) dict."""
    return copy.deepcopy(tomllib.loads(QUICKSTART_PATH.read_text()))


def scenario(d: dict, source: str = "test.toml") -> Scenario:
    """Parse a scenario dict (device names resolve against the shipped presets)."""
    return parse_scenario(to_toml(d), source, base_dir=SCENARIOS)
