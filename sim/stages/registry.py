"""The stages of a run, in the order :func:`rlgsim.sim.run.simulate.simulate` runs them in every
block (:mod:`rlgsim.sim.stages.base` describes a stage). A new stage is one new file in this
package plus one line here; the thermal part (:class:`rlgsim.sim.stages.thermal.ThermalPart`)
runs before them all and is not listed."""

from __future__ import annotations

from typing import Any, Callable

from rlgsim.sim.stages.anomalies import AnomalyStage
from rlgsim.sim.stages.base import Stage
from rlgsim.sim.stages.imu import ImuStage
from rlgsim.sim.stages.probes import ProbeStage

__all__ = ["STAGES"]

#: Stage factories, in order: ``f(scenario, timeline) -> Stage | None`` (``timeline`` a
#: :class:`rlgsim.sim.run.schedule.Timeline`; None: the scenario
#: does not have the part). The anomaly stage is last: it writes the events the stages before
#: it produced in the block.
STAGES: list[Callable[[Any, Any], Stage | None]] = [
    ProbeStage.create,      # probes: thermometer readings
    ImuStage.create,        # imu, turntable, truth: pulses, UHFO, table angles, ground truth
    AnomalyStage.create,    # anomalies: the event record (only with [anomalies])
]
