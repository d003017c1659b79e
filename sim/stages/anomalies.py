"""The anomaly stage: the event record of the sensor anomalies (group ``anomalies``; only with
an active ``[anomalies]`` table; :mod:`rlgsim.sim.sensors.anomalies` is the model)."""

from __future__ import annotations

import numpy as np

from rlgsim.ground.dataset_format import ANOMALIES
from rlgsim.sim.sensors.anomalies import AnomalyRun
from rlgsim.sim.stages.base import Stage
from rlgsim.sim.writer.schema import DESCRIPTIONS, declare_anomalies

__all__ = ["AnomalyStage"]


class AnomalyStage(Stage):
    """Writes the event record (group ``anomalies``); the last stage of a block, so it sees
    every event the probe and IMU stages produced in that block. Dimension ``event``: time of
    the event [s], end [s], channel, kind, size and its units (docs/sensors.md)."""

    group = ANOMALIES
    description = DESCRIPTIONS[ANOMALIES]
    needs_motion = False

    def __init__(self, run: AnomalyRun) -> None:
        self.run = run

    @classmethod
    def create(cls, scenario, timeline) -> "AnomalyStage | None":
        run = AnomalyRun.of(scenario, timeline)
        return None if run is None else cls(run)

    def declare(self, g) -> None:
        declare_anomalies(g)                      # the schema room (sim/writer/schema.py)

    def initial_state(self) -> int:
        return 0                                  # events written so far

    def block(self, state: int, b: int, trace, motion) -> tuple[dict, int]:
        ev = self.run.take_events().arrays()
        n = len(ev["time_s"])
        if n == 0:
            return {}, state
        rows = {"event": {"event": np.arange(state, state + n, dtype=np.int64),
                          "time": ev["time_s"], "end": ev["end_s"],
                          "channel": np.asarray(ev["channel"], dtype=object),
                          "kind": np.asarray(ev["kind"], dtype=object), "size": ev["size"],
                          "size_units": np.asarray(ev["units"], dtype=object)}}
        return rows, state + n
