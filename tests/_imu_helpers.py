"""Shared helpers of the sensor tests: synthetic thermal traces, motions, a block runner."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rlgsim.sim.motion.site import Site
from rlgsim.sim.sensors.imu import ImuSimulator
from rlgsim.sim.sensors.imu_model import ImuModel
from rlgsim.sim.motion.kinematics import Motion, segments_from_program
from rlgsim.sim.rng import generator

#: Node names of a three-gyro IMU (the thermal preset's naming) and of a single gyro block.
BLOCK_NODES = [*"ABCDEFGH", "discharge", "preamp", "ballast_D", "ballast_E"]
IMU_NODES = ([f"g{a}.{n}" for a in "xyz" for n in BLOCK_NODES]
             + ["ax", "ay", "az", "base", "housing_air"])
SINGLE_NODES = [f"g.{n}" for n in BLOCK_NODES] + ["base", "housing_air"]

SITE = Site(34.0, 0.0)


@dataclass
class Trace:
    """Stand-in for rlgsim.sim.stages.base.ThermalTrace (the fields the sensor stage reads)."""

    t_s: np.ndarray
    step_s: float
    power: np.ndarray
    nodes_c: np.ndarray
    start_c: np.ndarray


def temperatures(t_s: np.ndarray, names, f=None) -> np.ndarray:
    """Node temperatures (len(t), len(names)): ``f(t, j)`` or a constant 20 °C."""
    t = np.asarray(t_s, float)
    if f is None:
        return np.full((t.size, len(names)), 20.0)
    return np.stack([f(t, j) for j in range(len(names))], axis=1)


def make_sim(tables: dict, names=IMU_NODES, *, program, duration_s: float, rate_hz=100.0,
             step_s=1.0, seed=1, unit=0, truth_samples=False) -> ImuSimulator:
    model = ImuModel.from_tables(tables, "test.toml")
    real = model.realise(generator(seed, unit, "realisation", "imu", 0))
    motion = Motion(segments_from_program(program, duration_s + 600.0), SITE)
    return ImuSimulator(real, names, seed=seed, unit=unit, rate_hz=rate_hz, step_s=step_s,
                        motion=motion, truth_samples=truth_samples)


def run(sim: ImuSimulator, n_blocks: int, names=IMU_NODES, temp_f=None, power_f=None,
        block_s: float = 600.0):
    """Run ``n_blocks`` blocks; returns the list of row dicts and the final state."""
    state = sim.initial_state()
    m = int(round(block_s / sim.step_s))
    out = []
    for b in range(n_blocks):
        t = (b * m + np.arange(1, m + 1)) * sim.step_s
        nodes = temperatures(t, names, temp_f)
        start = temperatures(np.array([b * m * sim.step_s]), names, temp_f)[0]
        power = np.ones(m) if power_f is None else power_f(t - sim.step_s)
        rows, state = sim.block(state, b, Trace(t, sim.step_s, power, nodes, start))
        out.append(rows)
    return out, state


def cat(rows: list, group: str, dim: str, var: str) -> np.ndarray:
    return np.concatenate([r[group][dim][var] for r in rows])
