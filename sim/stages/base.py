"""The stage interface of the simulator's block loop (:func:`rlgsim.sim.run.simulate.simulate`).

The run advances in blocks of :data:`rlgsim.sim.rng.BLOCK_S`. For block ``b`` the thermal part
(:class:`rlgsim.sim.stages.thermal.ThermalPart`) gives a :class:`ThermalTrace`; then every stage
of :data:`rlgsim.sim.stages.registry.STAGES` turns the trace into its rows:
``stage.block(state, b, trace, motion) -> (rows, state)``.

A stage is the one place where a model (``sim/thermal``, ``sim/sensors``: physics only, no
dataset names) meets the dataset schema (:mod:`rlgsim.sim.writer.schema`: groups, names, units,
descriptions). Adding a stage — write a class in a new file of this package with

* ``group`` (dataset group name), ``description`` and ``needs_motion`` (True to receive the
  turntable kinematics, a :class:`rlgsim.sim.motion.kinematics.Motion` —
  ``motion.increments(t0_s, n, rate_hz)`` gives the exact angle/velocity increments of ``n``
  samples);
* ``declare(group_writer)`` — create coordinates/variables through the schema (see
  :mod:`rlgsim.sim.writer.dataset`); the growing dimension is usually ``time``
  (``coordinate("time", growing=True, ...)``; a group may declare more than one growing
  dimension);
* ``initial_state()`` — the state before block 0 (or ``None`` and build it from the first
  block's ``trace.start_c``, as the probes do);
* ``block(state, b, trace, motion) -> (rows, state)`` — ``rows`` maps each growing dimension to
  ``{variable: array}`` holding every variable along it (the coordinate included), for this
  block only: block ``b`` covers ``[b·BLOCK_S, b·BLOCK_S + len(trace.t_s)·trace.step_s)``;
  random draws from ``generator(seed, scenario.unit, purpose, channel, b)``;
* optionally ``close()`` — stop the stage's worker threads (called whatever ends the run);

and a factory ``create(scenario, timeline) -> stage | None`` added to
:data:`rlgsim.sim.stages.registry.STAGES` (one line). Its group is declared in
:mod:`rlgsim.sim.writer.schema`, its names in :data:`rlgsim.ground.dataset_format.VARIABLES`
(or :data:`~rlgsim.ground.dataset_format.OPTIONAL_VARIABLES` for a part a scenario switches on)
and its prose in docs/dataset.md. :class:`rlgsim.sim.stages.probes.ProbeStage` is the worked
example. A stage that writes several groups (the IMU: ``imu``, ``turntable``, ``truth``) sets
``groups = {name: description}`` instead of ``group``/``description``; its ``declare`` then
receives ``{name: group_writer}`` and its ``block`` returns ``{name: rows}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.sim.writer.dataset import GroupWriter

__all__ = ["ThermalTrace", "Stage"]


@dataclass(frozen=True)
class ThermalTrace:
    """The thermal state over one block, on the thermal grid.

    Row ``j`` belongs to the step ``[t_s[j] - step_s, t_s[j])``: temperatures are the values at
    its end, ``power`` the state held over it.
    """

    t_s: np.ndarray          # (m,) end of each step [s]
    step_s: float
    setpoint_c: np.ndarray   # (m,) rate-limited chamber setpoint [°C]
    air_c: np.ndarray        # (m,) chamber air [°C]
    power: np.ndarray        # (m,) 0/1
    nodes_c: np.ndarray      # (m, n) true node temperatures [°C]
    start_c: np.ndarray      # (n,) node temperatures at the block start (row -1)


class Stage:
    """Interface of a simulation stage (see the module docstring)."""

    group: str
    description: str
    needs_motion: bool = False     # True: block() receives a rlgsim.sim.motion.kinematics.Motion (else None)

    def declare(self, g: GroupWriter) -> None:
        raise NotImplementedError

    def initial_state(self) -> Any:
        raise NotImplementedError

    def block(self, state: Any, b: int, trace: ThermalTrace, motion: Any
              ) -> tuple[dict[str, dict[str, np.ndarray]], Any]:
        raise NotImplementedError
