"""The probe stage: thermometer readings of the network's nodes (group ``probes``)."""

from __future__ import annotations

from typing import Any

from rlgsim.ground.dataset_format import PROBES
from rlgsim.sim.rng import generator
from rlgsim.sim.sensors.anomalies import AnomalyRun
from rlgsim.sim.stages.base import Stage
from rlgsim.sim.writer.dataset import GroupWriter
from rlgsim.sim.writer.schema import DESCRIPTIONS, declare_probes

__all__ = ["ProbeStage"]


class ProbeStage(Stage):
    """Thermometer probes on the network nodes (lag, noise, resolution): what the compensators
    see. Random draws: ``generator(seed, unit, "probes", "noise", b)``."""

    group = PROBES
    description = DESCRIPTIONS[PROBES]

    def __init__(self, scenario, timeline) -> None:
        self.probes = scenario.device.thermal.probes
        self.network = scenario.device.thermal.network
        self.seed = scenario.seed
        self.unit = scenario.unit
        self.step = timeline.step_s
        self.anomalies = AnomalyRun.of(scenario, timeline)     # None unless [anomalies]

    @classmethod
    def create(cls, scenario, timeline) -> "ProbeStage | None":
        if not scenario.device.thermal.probes.n_probes:
            return None
        return cls(scenario, timeline)

    def declare(self, g: GroupWriter) -> None:
        declare_probes(g, self.probes, self.network)

    def initial_state(self) -> Any:
        return None          # built from the first block's start temperatures

    def block(self, state, b, trace, motion):
        if state is None:
            state = self.probes.initial_state(trace.start_c)
        rng = generator(self.seed, self.unit, "probes", "noise", b)
        readings, state = self.probes.read(state, trace.nodes_c, trace.step_s, rng)
        if self.anomalies is not None:                         # glitches, stuck, dropouts
            readings = self.anomalies.probe_readings(b, trace, readings)
        return {"time": {"time": trace.t_s, "temperature": readings}}, state
