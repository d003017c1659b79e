"""Quartz-flexure accelerometer error model with pulse output (paper 000 §3.3, eqs. 20–22).

Measurement equation (paper 000 eq. 20, per accelerometer i, per sample interval Δt = 1/f):

    u_i = D_i(θ)·Δt + E_i(θ)·Δv + n_i                                           [m/s]
    N_i = K_i^±(θ) · u_i,    K^+ if u_i ≥ 0 else K^−                              [pulses]

Δv = ∫f^b dt the exact velocity increment in body axes (:mod:`rlgsim.sim.motion.kinematics`), D_i the bias
[m/s²], E_i the installation row (1 on the own axis, two misalignment angles [rad]), n_i the
velocity-random-walk increment VRW·√Δt·z [m/s], and K^+/K^− the separate positive and negative
scale factors [pulses/(m/s)] — paper 000 splits them because a quartz-flexure accelerometer's
torquer and current-to-frequency converter respond differently to the two signs of the input.
The pulses are counted with the remainder carried (:mod:`rlgsim.sim.sensors.pulses`).

Temperature dependence (paper 000 §2(2): the torque coil's magnet and the pendulum's thermal
imbalance move bias and scale factor): bias law in µg, K^± = K_0·(1 + 10⁻⁶·law_±) with separate
ppm laws for the two signs, misalignment law in arcsec (all :mod:`rlgsim.sim.sensors.temperature_laws`,
local node the accelerometer's own thermal node by default). Typical navigation-grade
quartz-flexure figures: bias temperature coefficient tens of µg/°C, scale factor tens of ppm/°C
(docs/design.md). Bias instability (flicker) and acceleration random walk join the true bias
(:class:`rlgsim.sim.sensors.noise.SlowNoise`).

Evaluation order (float64; the stored truth reproduces the pulses in this order):
``u = ((E_x·Δv_x + E_y·Δv_y) + E_z·Δv_z) + D·Δt``, ``u = u + σ·z``, ``inc = K^±·u`` with
K^+ where u ≥ 0. Zero while unpowered. The equation, the per-axis bookkeeping and the preset
parsing are shared with the gyros (:mod:`rlgsim.sim.sensors.sensor_triad`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from rlgsim.ground import units
from rlgsim.sim.config import Ctx, check_known_keys, get_float
from rlgsim.sim.sensors.sensor_triad import (SensorTriad, SensorTriadModel, axis_indices, law_context,
                                     law_spec, parse_sensor_sites)
from rlgsim.sim.sensors.sensor_triad import phase_increments as _triad_increments
from rlgsim.sim.sensors.temperature_laws import Law, LawSpec

_ACCEL_KEYS = ("axes", "nodes", "scale_factor_pulses_per_s_per_g", "node", "t_ref_c", "bias",
               "scale_factor_pos", "scale_factor_neg", "misalignment")


@dataclass(frozen=True)
class AccelerometerModel(SensorTriadModel):
    """Nominal accelerometer triad + tolerances: the ``[accelerometer]`` preset table.

    ``axes`` body axes, ``nodes`` each accelerometer's thermal node (its "block"), ``k0``
    nominal scale factor [pulses/(m/s)], laws ``bias`` (µg), ``scale_factor_pos`` /
    ``scale_factor_neg`` (ppm), ``misalignment`` (arcsec, two per accelerometer).
    """

    LAWS = ("bias", "scale_factor_pos", "scale_factor_neg", "misalignment")

    axes: tuple[str, ...]
    nodes: tuple[str, ...]
    k0: float
    bias: LawSpec
    scale_factor_pos: LawSpec
    scale_factor_neg: LawSpec
    misalignment: LawSpec

    @classmethod
    def from_config(cls, table: Mapping, ctx: Ctx) -> "AccelerometerModel":
        """Validate ``[accelerometer]``: ``axes`` (default x, y, z), ``nodes`` (default
        ["ax", "ay", "az"]), ``scale_factor_pulses_per_s_per_g`` (pulses per second at 1 g0,
        default 5000), ``node`` (default "self": the accelerometer's own node), ``t_ref_c`` and
        the law tables ``[accelerometer.bias]`` (µg), ``scale_factor_pos``/``scale_factor_neg``
        (ppm), ``misalignment`` (arcsec)."""
        check_known_keys(table, _ACCEL_KEYS, ctx)
        axes, nodes = parse_sensor_sites(table, ctx, "nodes", "node",
                                         lambda axes: [f"a{a}" for a in axes])
        k = get_float(table, "scale_factor_pulses_per_s_per_g", ctx, 5000.0, min=0.0,
                      min_exclusive=True)
        common = law_context(table, ctx, "self")
        n = len(axes)

        def law(key: str, unit: str, to_si: float, count: int) -> LawSpec:
            return law_spec(table, ctx, key, "accel", unit, to_si, count, common)
        return cls(axes=axes, nodes=nodes, k0=k / units.G0,
                   bias=law("bias", "ug", units.MICRO_G, n),
                   scale_factor_pos=law("scale_factor_pos", "ppm", 1e-6, n),
                   scale_factor_neg=law("scale_factor_neg", "ppm", 1e-6, n),
                   misalignment=law("misalignment", "arcsec", units.ARCSEC, 2 * n))

    def realise(self, draw) -> "Accelerometers":
        """Draw one unit (``draw(name, shape)`` → standard normals, keyed by name)."""
        return Accelerometers(axes=self.axes, nodes=self.nodes,
                              axis_idx=axis_indices(self.axes, Ctx()), k0=self.k0,
                              **self.realised_laws(draw))


@dataclass
class AccelParameters:
    """True accelerometer parameters on the thermal grid (SI): ``bias`` (m, C) [m/s²] total,
    ``bias_random`` its flicker + random-walk part, ``scale_factor_pos``/``_neg`` (m, C)
    [pulses/(m/s)], ``installation`` (m, C, 3)."""

    bias: np.ndarray
    bias_random: np.ndarray
    scale_factor_pos: np.ndarray
    scale_factor_neg: np.ndarray
    installation: np.ndarray


@dataclass
class Accelerometers(SensorTriad):
    """One unit's accelerometers: realised laws and the measurement equation. A law's node
    "self" is the accelerometer's own node."""

    LAWS = AccelerometerModel.LAWS

    axes: tuple[str, ...]
    nodes: tuple[str, ...]
    axis_idx: np.ndarray
    k0: float
    bias: Law
    scale_factor_pos: Law
    scale_factor_neg: Law
    misalignment: Law

    @property
    def sites(self) -> tuple[str, ...]:
        return self.nodes

    def parameters(self, nodes_c: np.ndarray, start_c: np.ndarray, dt: float,
                   bias_random: np.ndarray) -> AccelParameters:
        """Evaluate the laws on the thermal grid (see the module docstring)."""
        bias = self.bias.evaluate(nodes_c, start_c, dt) + bias_random
        return AccelParameters(
            bias=bias, bias_random=bias_random,
            scale_factor_pos=self.scale_factor_of(self.scale_factor_pos, nodes_c, start_c, dt),
            scale_factor_neg=self.scale_factor_of(self.scale_factor_neg, nodes_c, start_c, dt),
            installation=self.installation(nodes_c, start_c, dt))


def phase_increments(kpos: np.ndarray, kneg: np.ndarray, bias: np.ndarray,
                     installation: np.ndarray, dv_t: np.ndarray, z: np.ndarray | None,
                     sigma: np.ndarray, sample_dt: float, idx: np.ndarray | int,
                     power: np.ndarray | None = None,
                     own_axis: np.ndarray | None = None) -> np.ndarray:
    """Phase increments [pulses] (C, n) of eq. 20 for one block, float64.

    ``kpos``/``kneg`` (m, C) [pulses/(m/s)], ``bias`` (m, C) [m/s²], ``installation``
    (m, C, 3), ``dv_t`` (3, n) [m/s], ``z`` (C, n) float32 standard normals or None, ``sigma``
    (C,) [m/s], ``own_axis`` as in :func:`rlgsim.sim.sensors.sensor_triad.phase_increments`. Per
    sample, in this order: ``u = ((E_x·Δv_x + E_y·Δv_y) + E_z·Δv_z) + D·Δt``,
    ``u = u + σ·z``, ``inc = (K⁺ if u ≥ 0 else K⁻)·u``.
    """
    return _triad_increments(kpos, bias, installation, dv_t, z, sigma, sample_dt, idx, power,
                             own_axis, scale_factor_neg=kneg)
