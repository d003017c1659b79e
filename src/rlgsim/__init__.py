"""rlgsim: a ring-laser-gyro IMU in a temperature chamber on a two-axis turntable, simulated with
its ground truth, and the temperature compensators to validate against it.

One import namespace for the three source folders of the repository::

    rlgsim.ground       the vocabulary both sides share (units, Earth, frames, dataset format)
    rlgsim.sim          everything that generates data (thermal network, sensors, simulator, CLI)
    rlgsim.estimators   everything that estimates from data (calibration, compensators, metrics)
    rlgsim.scenarios    the shipped TOML presets, scenarios and studies

The public entry points below are imported lazily, so ``import rlgsim`` (and every
``rlgsim.estimators`` module, which imports ``rlgsim.ground``) stays light and never pulls in
the simulator.
"""

from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, version as _dist_version

try:
    __version__: str = _dist_version("rlgsim")
except PackageNotFoundError:          # run from a source tree that was never installed
    __version__ = "0+unknown"

#: public name -> "module:attribute" it is imported from on first use
_PUBLIC = {
    "load_scenario": "rlgsim.sim.run.scenario:load_scenario",
    "parse_scenario": "rlgsim.sim.run.scenario:parse_scenario",
    "Scenario": "rlgsim.sim.run.scenario:Scenario",
    "simulate": "rlgsim.sim.run.simulate:simulate",
    "open_dataset": "rlgsim.ground.dataset_format:open_dataset",
    "load_study": "rlgsim.lab.study:load_study",
    "run_study": "rlgsim.lab.study:run_study",
    "UserInputError": "rlgsim.ground.errors:UserInputError",
    # the notebook API (docs/api.md; rlgsim.api, a facade over rlgsim.lab.api)
    "with_changes": "rlgsim.lab.api:with_changes",
    "run": "rlgsim.lab.api:run",
    "open_tree": "rlgsim.lab.api:open_tree",
    "window_table": "rlgsim.lab.api:window_table",
    "score": "rlgsim.lab.api:score",
    "calibrate": "rlgsim.lab.api:calibrate",
    "navigate": "rlgsim.lab.api:navigate",
    # recordings (docs/recordings.md)
    "load_recording": "rlgsim.ground.recording:load_recording",
    "export": "rlgsim.ground.recording_export:export",
    # the digital twin (docs/identify.md)
    "identify": "rlgsim.lab.identify:identify",
}

__all__ = ["__version__", *_PUBLIC]


#: subpackages reachable as attributes of the root without their own import (``rlgsim.api.run``
#: after a plain ``import rlgsim``, as docs/api.md writes it), imported on first use
_SUBPACKAGES = ("api", "ground", "sim", "estimators", "lab", "scenarios")


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        return importlib.import_module(f"rlgsim.{name}")
    try:
        module, attr = _PUBLIC[name].split(":")
    except KeyError:
        raise AttributeError(f"module 'rlgsim' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
