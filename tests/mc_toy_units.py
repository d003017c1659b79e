"""Small unit functions for testing the Monte Carlo engine (importable by worker processes)."""

from __future__ import annotations

import os
import time

import numpy as np

from rlgsim.sim.rng import generator


def toy_unit(payload: dict, unit: int) -> dict:
    """A unit whose result depends only on (payload, unit): a drawn 'drift' and two fits."""
    rng = generator(payload["seed"], unit, "toy", "params")
    drift = float(rng.normal(0.0, 1.0))
    noise = rng.normal(0.0, 0.1 + abs(drift), size=200)
    if payload.get("sleep_s"):
        time.sleep(payload["sleep_s"])
    if unit in payload.get("fail_units", ()):
        raise RuntimeError(f"unit {unit} broke on purpose")
    if unit in payload.get("kill_units", ()) and not os.path.exists(payload["kill_marker"]):
        open(payload["kill_marker"], "w").close()
        os._exit(1)                      # a worker dying mid-campaign, once
    raw = float(np.std(noise + drift * np.linspace(0, 1, 200)))
    comp = float(np.std(noise))
    return {"rows": [("raw", "bias_stability", raw), ("fit", "bias_stability", comp)],
            "params": {"drift": drift}}
