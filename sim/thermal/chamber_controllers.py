"""The chamber controllers by ``kind``: the registry a scenario's ``[chamber.controller]`` table
is read through (``kind = "pid"`` when not given; docs/thermal.md §1.4).

A controller kind is one file with one class of the shape :class:`ChamberControllerKind`, plus
one line of :data:`CONTROLLERS`:

* ``kind`` — the name a scenario gives (``[chamber.controller] kind = "..."``);
* ``from_config(table, ctx)`` — its parameters from the table (``kind`` taken out), every key
  checked (:class:`~rlgsim.ground.errors.UserInputError` naming file, key and value);
* ``loop(step_s)`` — the controller on a thermal grid of ``step_s`` [s], an object with
  ``initial_state(setpoint_c) -> state`` (a tuple of floats whose first entry is the chamber
  air [°C]: the loop at rest at that set point) and ``run(state, setpoint_c) -> (air_c,
  state)`` (the rate-limited set point at the ``m + 1`` grid points of a block in, the air at
  its ``m`` step ends out; blocks chained through the state bit for bit).

:class:`rlgsim.sim.thermal.integrator.ThermalIntegrator` drives the network with the loop's air
and knows no kind.
"""

from __future__ import annotations

from typing import Any, ClassVar, Mapping, Protocol

import numpy as np

from rlgsim.sim.config import Ctx, get_str
from rlgsim.sim.thermal.chamber_controller import ChamberController

__all__ = ["CONTROLLERS", "DEFAULT_KIND", "ChamberControllerKind", "ChamberLoopLike",
           "controller_from_config"]


class ChamberLoopLike(Protocol):
    """A controller discretised on the thermal grid (see the module docstring)."""

    def initial_state(self, setpoint_c: float) -> tuple[float, ...]: ...

    def run(self, state: tuple[float, ...], setpoint_c: np.ndarray
            ) -> tuple[np.ndarray, tuple[float, ...]]: ...


class ChamberControllerKind(Protocol):
    """A chamber controller's parameters (see the module docstring)."""

    kind: ClassVar[str]

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "ChamberControllerKind": ...

    def loop(self, step_s: float) -> ChamberLoopLike: ...


#: kind -> controller class; a new controller is one new file and one line here.
CONTROLLERS: dict[str, type] = {
    ChamberController.kind: ChamberController,     # "pid": digital PID on a lagged air sensor
}
#: The kind of a ``[chamber.controller]`` table without ``kind``.
DEFAULT_KIND = ChamberController.kind


def controller_from_config(table: Mapping[str, Any], ctx: Ctx) -> ChamberControllerKind:
    """The controller of a ``[chamber.controller]`` table: its ``kind`` (default
    :data:`DEFAULT_KIND`) chosen from :data:`CONTROLLERS`, the rest read by that kind."""
    kind = get_str(table, "kind", ctx, DEFAULT_KIND, choices=sorted(CONTROLLERS))
    rest = {key: value for key, value in table.items() if key != "kind"}
    return CONTROLLERS[kind].from_config(rest, ctx)
