"""The sensor stage: the IMU's pulses and UHFO (group ``imu``), the table's angles and
motions (group ``turntable``) and the ground truth (group ``truth``) of one drawn unit — the
model :class:`rlgsim.sim.sensors.imu.ImuSimulator` joined to the schema
(:func:`rlgsim.sim.writer.schema.declare_imu` and the others)."""

from __future__ import annotations

from typing import Any, Mapping

from rlgsim.ground.dataset_format import IMU, TRAJECTORY, TRUTH, TURNTABLE
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.motion.kinematics import Motion
from rlgsim.sim.rng import generator
from rlgsim.sim.sensors.anomalies import AnomalyRun
from rlgsim.sim.sensors.imu import ImuSimulator, ImuState
from rlgsim.sim.sensors.imu_model import ImuModel
from rlgsim.sim.stages.base import Stage
from rlgsim.sim.writer.schema import (DESCRIPTIONS, declare_imu, declare_sample_valid,
                                       declare_trajectory, declare_truth, declare_turntable,
                                       trajectory_rows)

__all__ = ["ImuStage"]


class ImuStage(Stage):
    """The sensor stage of :func:`rlgsim.sim.run.simulate.simulate`: groups ``imu`` (pulses, UHFO),
    ``turntable`` (table angles, motion labels) and ``truth`` (true parameters, inputs and the
    drawn unit). docs/dataset.md describes every variable."""

    needs_motion = True

    groups = {name: DESCRIPTIONS[name] for name in (IMU, TURNTABLE, TRUTH)}

    def __init__(self, scenario, timeline, model: ImuModel, *, unit: int = 0) -> None:
        network = scenario.device.thermal.network
        if network is None:
            raise UserInputError(f"{scenario.device.source}: the device has sensor tables but "
                                 f"no thermal network; sensors need node temperatures")
        self.scenario = scenario
        self.timeline = timeline
        self.model = model
        self.unit = int(unit)
        self.realisation = model.realise(generator(scenario.realisation_seed, self.unit,
                                                   "realisation", "imu", 0))
        self.turntable_segments = [s for s in timeline.segments if s.track == "turntable"]
        #: a vehicle's route (rlgsim.sim.motion.trajectory_config.TrajectoryProgram) or None
        self.trajectory = getattr(scenario, "trajectory", None)
        if self.trajectory is not None:
            self.groups = {**type(self).groups, TRAJECTORY: DESCRIPTIONS[TRAJECTORY]}
        self.truth_samples = bool(getattr(scenario.acquisition, "truth_samples", False))
        self.sim = ImuSimulator(self.realisation, network.node_names, seed=scenario.seed,
                                unit=self.unit, rate_hz=scenario.acquisition.sample_rate_hz,
                                step_s=timeline.step_s, motion=None,
                                truth_samples=self.truth_samples,
                                source=scenario.device.source, n_steps=timeline.n_steps)
        self.sim.anomalies = AnomalyRun.of(scenario, timeline)   # None unless [anomalies]

    @classmethod
    def create(cls, scenario, timeline) -> "ImuStage | None":
        """The stage for ``scenario`` (None when its device has no ``[gyro]`` table)."""
        model = ImuModel.from_device(scenario.device)
        if model is None:
            return None
        return cls(scenario, timeline, model, unit=scenario.unit)

    # ---- dataset layout -------------------------------------------------------------------
    def declare(self, writers: Mapping[str, Any]) -> None:
        """Declare the three groups' dimensions and variables (:mod:`rlgsim.sim.writer.schema`,
        docs/dataset.md)."""
        r, sim = self.realisation, self.sim
        declare_imu(writers[IMU], r, rate_hz=sim.rate_hz, step_s=sim.step_s)
        if sim.anomalies is not None and sim.anomalies.model.imu_dropout_rate_per_h > 0:
            declare_sample_valid(writers[IMU])           # frame dropouts on
        declare_turntable(writers[TURNTABLE], self.turntable_segments)
        if self.trajectory is not None:
            declare_trajectory(writers[TRAJECTORY],
                               self.trajectory.build(float(self.timeline.duration_s)))
        declare_truth(writers[TRUTH], r, seed=self.scenario.seed, unit=self.unit,
                      rate_hz=sim.rate_hz, step_s=sim.step_s,
                      gyro_white_sigma=sim.gyro_white_sigma,
                      accel_white_sigma=sim.accel_white_sigma, truth_samples=self.truth_samples)

    # ---- running --------------------------------------------------------------------------
    def initial_state(self) -> ImuState:
        return self.sim.initial_state()

    def close(self) -> None:
        """Stop the simulator's worker thread (:meth:`ImuSimulator.close`)."""
        self.sim.close()

    def start(self, motion) -> None:
        """Adopt the run's kinematics ``motion`` (the stage's own when None) before the first
        block: a vehicle's increments and ``trajectory`` rows then start in the simulator's
        worker thread (:meth:`ImuSimulator.start`) while the caller lays out the file."""
        if motion is None and self.trajectory is not None:
            motion = self.trajectory.build(float(self.timeline.duration_s))
        motion = motion if motion is not None else Motion(self.turntable_segments,
                                                          self.scenario.site)
        if getattr(motion, "kind", "turntable") == "trajectory":
            # rows from states already computed, or made by the compiled kernel in one pass
            self.sim.motion_rows = lambda t_s, states: (
                motion.truth_rows(t_s) if states is None
                else trajectory_rows(motion, t_s, states))
        self.sim.start(motion)

    def block(self, state: ImuState, b: int, trace, motion) -> tuple[dict, ImuState]:
        """Rows ``{group: {dim: {variable: array}}}`` of block ``b``; ``motion`` the run's
        :class:`rlgsim.sim.motion.kinematics.Motion` (the stage's own when None)."""
        if self.sim.motion is None:                 # first block: adopt the run's kinematics
            self.start(motion)
        rows, state = self.sim.block(state, b, trace)
        if getattr(self.sim.motion, "kind", "turntable") == "trajectory":   # a vehicle's states
            mb = self.sim.last_motion_block
            made = getattr(mb, "rows", None)        # made with the kinematics (worker thread)
            rows[TRAJECTORY] = {"sample": made if made is not None else
                                trajectory_rows(self.sim.motion, mb.t_s, mb.states)}
        return rows, state
