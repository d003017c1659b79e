"""The thermal part of a run: samples the timeline and propagates the unit's thermal network
block by block (:class:`rlgsim.sim.thermal.integrator.ThermalIntegrator`), giving each block's
:class:`rlgsim.sim.stages.base.ThermalTrace` and the ``thermal`` group's rows."""

from __future__ import annotations

from typing import Any

import numpy as np

from rlgsim.ground.dataset_format import THERMAL
from rlgsim.sim.block_steps import step_counts
from rlgsim.sim.rng import generator
from rlgsim.sim.stages.base import ThermalTrace
from rlgsim.sim.thermal.integrator import ThermalIntegrator
from rlgsim.sim.writer.dataset import GroupWriter
from rlgsim.sim.writer.schema import DESCRIPTIONS, declare_thermal, declare_thermal_parts

__all__ = ["ThermalPart", "realised_network", "thermal_summary"]


class ThermalPart:
    """Samples the timeline and propagates the thermal network block by block."""

    group = THERMAL
    description = DESCRIPTIONS[THERMAL]

    def __init__(self, scenario, timeline) -> None:
        self.timeline = timeline
        self.step = timeline.step_s
        self.nominal = scenario.device.thermal.network
        self.network = realised_network(scenario)
        self.integrator = ThermalIntegrator(self.network, self.step, scenario.chamber.air_tau_s,
                                            controller=scenario.chamber.controller)
        #: the chamber loop's noise streams (docs/thermal.md §1.4): (seed, unit) of the run
        loop = self.integrator.chamber_loop
        self.chamber_noise = ((scenario.seed, scenario.unit)
                              if loop is not None and getattr(loop, "noise_channels", 0)
                              else None)
        #: a vehicle's bay (sim/thermal/vehicle_bay.py) and its route: the airflow scales the
        #: ambient conductances with the ground speed (None: still air, as in a chamber)
        self.bay = None
        if getattr(scenario, "vehicle_bay", None) is not None:
            self.bay = (scenario.vehicle_bay,
                        scenario.trajectory.build(float(timeline.duration_s)))
            self._check_bay_before_the_run(float(timeline.duration_s), scenario.source)

    def _check_bay_before_the_run(self, duration_s: float, source: Any) -> None:
        """Refuse an airflow too strong for the thermal step before the first block: where an
        upper bound of the route's speed (each body leg's channels lie between their start and
        end values: linear or the monotone quintic) could be refused, the speeds of every
        thermal step's start are checked now — the steps :meth:`block` holds the film over, so
        no block checks them again."""
        bay, route = self.bay
        net = self.network
        still = float(np.max(-np.expm1(       # the ambient's weight a step in still air
            -net.ambient_conductance_w_per_k * self.step / net.capacitance_j_per_k)))
        top = 0.0
        for leg, t0 in zip(route.legs, route.leg_starts):
            if t0 > duration_s:
                break
            if leg.frame != "body":                        # a table of positions: no bound
                top = np.inf
                break
            ends = np.abs(np.stack([leg.coef[3:, 0], leg.end()[3:]]))
            top = max(top, float(np.linalg.norm(np.max(ends, axis=0))))
        if (bay.factor(np.array([top]))[0] - 1.0) * still < 1.0:
            return
        steps = max(1, int(round(duration_s / self.step)))
        for lo in range(0, steps, 100_000):
            t = np.arange(lo, min(steps, lo + 100_000)) * self.step
            speed = np.linalg.norm(route.states(t).v_n, axis=1)
            bay.check_step(bay.factor(speed) - 1.0, speed, still, source, self.step)

    @property
    def node_names(self) -> tuple[str, ...]:
        return tuple(self.network.node_names)

    def declare(self, g: GroupWriter) -> None:
        declare_thermal(g, self.nominal, self.network)
        declare_thermal_parts(g, self.network)   # heaters, boundaries: only when it has them

    def initial_state(self) -> Any:
        ambient = float(self.timeline.setpoint(np.array([0.0]))[0])
        powered = bool(self.timeline.power(np.array([0.0]))[0])
        return self.integrator.initial_state(ambient, powered)      # keeps its modal state

    def block(self, state: Any, b: int, k0: int, m: int) -> tuple[ThermalTrace, Any]:
        k = step_counts(m + 1) + k0             # = arange(k0, k0 + m + 1): no GIL hand-off
        t = k * self.step
        setpoint = np.asarray(self.timeline.setpoint(t), dtype=float)
        power = np.asarray(self.timeline.power(t[:-1]), dtype=float)
        film = None
        if self.bay is not None:             # φ − 1 at each step's start (held over the step)
            bay, route = self.bay
            film = bay.factor(np.linalg.norm(route.states(t[:-1]).v_n, axis=1)) - 1.0
        noise = None
        if self.chamber_noise is not None:   # one stream per 600-s block: chunking-invariant
            loop = self.integrator.chamber_loop
            noise = generator(*self.chamber_noise, "chamber_loop", "", b).standard_normal(
                (m * loop.n_sub, loop.noise_channels))
        states, new_state = self.integrator.propagate(state, setpoint, power, film_factor=film,
                                                      chamber_noise=noise)
        self._extra_rows = self.integrator.extra_rows()
        trace = ThermalTrace(t_s=t[1:], step_s=self.step, setpoint_c=setpoint[1:],
                             air_c=np.asarray(states[:, 0]), power=power,
                             nodes_c=np.asarray(states[:, 1:]), start_c=np.asarray(state[1:]))
        return trace, new_state

    def rows(self, trace: ThermalTrace) -> dict[str, dict[str, np.ndarray]]:
        return {"time": {"time": trace.t_s, "chamber_setpoint": trace.setpoint_c,
                         "chamber_air": trace.air_c, "power_on": trace.power.astype(np.int8),
                         "node_temperature": trace.nodes_c,
                         **getattr(self, "_extra_rows", {})}}


def realised_network(scenario):
    """The thermal network of the simulated unit.

    Monte Carlo units ``unit >= 1`` draw their network from the preset's tolerances with
    ``generator(realisation_seed, unit, "realisation", "thermal", 0)``
    (:meth:`rlgsim.sim.thermal.network.ThermalNetwork.realise`). Unit 0 — every plain ``rlgsim run`` and a
    study's own run — simulates the *nominal* design: the presets' bias-stability figures were
    tuned against papers 000-003 on it (tests/test_imu.py), and a drawn network breaks the
    left/right symmetry of the gyro block, which switches on the anode-arm Langmuir term (on
    paper 003's random test the raw stability of drawn units spreads from 0.009 to 0.068 °/h
    against the paper's 0.028). docs/montecarlo.md discusses the choice."""
    network = scenario.device.thermal.network
    if scenario.unit == 0:
        return network
    return network.realise(generator(scenario.realisation_seed, scenario.unit, "realisation",
                                     "thermal", 0))


def thermal_summary(network) -> dict[str, float]:
    """A few numbers that characterise a (realised) network, for Monte Carlo unit tables:
    longest time constant [s], total heat [W], total conductance to the air [W/K] and the mean
    steady-state self-heating of the nodes when powered [K]."""
    rise = network.steady_state(0.0, True) - network.steady_state(0.0, False)
    return {"thermal.tau_max_s": float(network.time_constants_s()[0]),
            "thermal.power_w": float(network.power_w.sum()),
            "thermal.ambient_conductance_w_per_k":
                float(network.ambient_conductance_w_per_k.sum()),
            "thermal.self_heating_mean_k": float(np.mean(rise))}
