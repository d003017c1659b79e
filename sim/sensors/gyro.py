"""Ring-laser-gyro error model: temperature-driven scale factor, bias and misalignment, noise,
and pulse output (paper 000 §3.3, eqs. 17–19; IEEE Std 647 style).

Measurement equation (paper 000 eq. 17, per gyro i, per sample interval Δt = 1/f):

    N_i = K_i(θ) · ( D_i(θ)·Δt + E_i(θ)·Δθ + n_i )                             [pulses]

with Δθ = ∫ω_ib^b dt the exact angle increment in body axes (:mod:`rlgsim.sim.motion.kinematics`), K_i the
scale factor [pulses/rad] (nominal 2.14 pulses/arcsec, paper 000 §4.1), D_i the bias [rad/s], E_i
the i-th row of the installation matrix (1 on the gyro's own body axis, the two misalignment angles
[rad] towards the other two body axes) and n_i the angle-random-walk increment
N·√Δt·z [rad] (:func:`rlgsim.sim.sensors.noise.white_increments`). The pulses are counted from the
accumulated phase with the fractional remainder carried (:mod:`rlgsim.sim.sensors.pulses`).

Thermal state θ → parameters (one value per thermal step, held over the step's samples):

* D_i = law_D(θ) + b_flicker + b_rrw: the bias law (:mod:`rlgsim.sim.sensors.temperature_laws`;
  polynomial in the local block temperature, knee and step terms a cubic cannot follow,
  temperature rate, the Langmuir-flow anode-arm term T_D − T_E, multi-point gradients, and the
  discharge excitation U − U_0 tracked by UHFO, :mod:`rlgsim.sim.sensors.uhfo`) plus the slow noise of
  bias instability and rate random walk (:class:`rlgsim.sim.sensors.noise.SlowNoise`), which are part of
  the *true* bias;
* K_i = K_0·(1 + 10⁻⁶·law_K(θ)) with the scale-factor law in ppm;
* E_i off-diagonals = law_E(θ) in arcsec (two components per gyro).

Evaluation order (the truth in the dataset reproduces the pulses bit for bit when recomputed in
this order, float64), with E, D and K the values of the sample's thermal step:
``u = ((E_x·Δθ_x + E_y·Δθ_y) + E_z·Δθ_z) + D·Δt``, ``u = u + σ·z`` (σ·z in float64 from the
float32 normal z), ``inc = K·u``, then :mod:`rlgsim.sim.sensors.pulses` counts. While the device is
unpowered the increments are zero (no pulses). The equation, the per-axis bookkeeping and the
preset parsing are shared with the accelerometers (:mod:`rlgsim.sim.sensors.sensor_triad`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from rlgsim.ground import units
from rlgsim.sim.config import Ctx, check_known_keys, get_float
from rlgsim.sim.sensors.sensor_triad import (BODY_AXES, SensorTriad, SensorTriadModel, axis_indices,
                                     law_context, law_spec, parse_sensor_sites)
from rlgsim.sim.sensors.sensor_triad import phase_increments as _triad_increments
from rlgsim.sim.sensors.sensor_triad import sample_step_index
from rlgsim.sim.sensors.temperature_laws import Law, LawSpec

__all__ = ["BODY_AXES", "GyroModel", "GyroParameters", "Gyros", "phase_increments",
           "sample_step_index"]

#: Langmuir-flow bias per mA of leg-current imbalance [°/h/mA] (docs/design.md, after Aronowitz &
#: Lim 1979) and the default imbalance per kelvin of anode-arm difference [mA/K]
#: (rlgsim.sim.sensors.temperature_laws).
LANGMUIR_DEG_PER_H_PER_MA = 0.0066
LEG_IMBALANCE_MA_PER_K = 0.033

#: pulse weight of a device file without ``scale_factor_pulses_per_arcsec`` [pulses/arcsec]
DEFAULT_PULSES_PER_ARCSEC = 2.14


def pulses_per_arcsec(device: dict) -> float:
    """The nominal scale factor [pulses/arcsec] of a device file's parsed TOML ``device`` (its
    ``[gyro]`` table's key, :data:`DEFAULT_PULSES_PER_ARCSEC` without one), for readers of a
    dataset's ``device_text`` and of device templates."""
    return float((device.get("gyro") or {}).get("scale_factor_pulses_per_arcsec",
                                                 DEFAULT_PULSES_PER_ARCSEC))


_GYRO_KEYS = ("axes", "blocks", "scale_factor_pulses_per_arcsec", "node", "t_ref_c", "bias",
              "scale_factor", "misalignment")


@dataclass(frozen=True)
class GyroModel(SensorTriadModel):
    """Nominal gyro triad (or single gyro) + tolerances: the ``[gyro]`` preset table.

    ``axes`` body axes of the gyros, ``blocks`` their thermal-network blocks (node prefix,
    e.g. "gx" → "gx.A"), ``k0`` nominal scale factor [pulses/rad], laws ``bias`` (°/h),
    ``scale_factor`` (ppm), ``misalignment`` (arcsec, two per gyro).
    """

    LAWS = ("bias", "scale_factor", "misalignment")

    axes: tuple[str, ...]
    blocks: tuple[str, ...]
    k0: float
    bias: LawSpec
    scale_factor: LawSpec
    misalignment: LawSpec

    @classmethod
    def from_config(cls, table: Mapping, ctx: Ctx) -> "GyroModel":
        """Validate ``[gyro]``: ``axes`` (default ["x", "y", "z"]), ``blocks`` (default
        ["gx", "gy", "gz"], or ["g"] for one gyro), ``scale_factor_pulses_per_arcsec``
        (default 2.14), ``node`` (default "A": the cathode area, paper 003), ``t_ref_c``
        (default 20) and the law tables ``[gyro.bias]`` (°/h), ``[gyro.scale_factor]`` (ppm),
        ``[gyro.misalignment]`` (arcsec) — see :mod:`rlgsim.sim.sensors.temperature_laws`."""
        check_known_keys(table, _GYRO_KEYS, ctx)
        axes, blocks = parse_sensor_sites(
            table, ctx, "blocks", "block",
            lambda axes: ["g"] if len(axes) == 1 else [f"g{a}" for a in axes])
        k = get_float(table, "scale_factor_pulses_per_arcsec", ctx, DEFAULT_PULSES_PER_ARCSEC,
                      min=0.0, min_exclusive=True)
        common = law_context(table, ctx, "A")
        n = len(axes)
        return cls(
            axes=axes, blocks=blocks, k0=k / units.ARCSEC,
            bias=law_spec(table, ctx, "bias", "gyro", "deg_per_h",
                          units.deg_per_h_to_rad_per_s(1.0), n, common, langmuir=True,
                          default_langmuir=LANGMUIR_DEG_PER_H_PER_MA,
                          default_imbalance=LEG_IMBALANCE_MA_PER_K),
            scale_factor=law_spec(table, ctx, "scale_factor", "gyro", "ppm", 1e-6, n, common),
            misalignment=law_spec(table, ctx, "misalignment", "gyro", "arcsec", units.ARCSEC,
                                  2 * n, common))

    def realise(self, draw) -> "Gyros":
        """Draw one unit (``draw(name, shape)`` → standard normals, keyed by name)."""
        return Gyros(axes=self.axes, blocks=self.blocks,
                     axis_idx=axis_indices(self.axes, Ctx()), k0=self.k0,
                     **self.realised_laws(draw))


@dataclass
class GyroParameters:
    """True gyro parameters on the thermal grid of one block (SI).

    ``bias`` (m, C) [rad/s] total true bias D, ``bias_random`` (m, C) its flicker + random-walk
    part, ``scale_factor`` (m, C) [pulses/rad] K, ``installation`` (m, C, 3) rows of E.
    """

    bias: np.ndarray
    bias_random: np.ndarray
    scale_factor: np.ndarray
    installation: np.ndarray


@dataclass
class Gyros(SensorTriad):
    """One unit's gyros: realised laws and the measurement equation."""

    LAWS = GyroModel.LAWS

    axes: tuple[str, ...]
    blocks: tuple[str, ...]
    axis_idx: np.ndarray
    k0: float
    bias: Law
    scale_factor: Law
    misalignment: Law

    @property
    def sites(self) -> tuple[str, ...]:
        return self.blocks

    def parameters(self, nodes_c: np.ndarray, start_c: np.ndarray, dt: float,
                   bias_random: np.ndarray, uhfo_dev_v: np.ndarray | None) -> GyroParameters:
        """Evaluate the laws on the thermal grid (see the module docstring)."""
        bias = self.bias.evaluate(nodes_c, start_c, dt, uhfo_dev_v) + bias_random
        return GyroParameters(bias=bias, bias_random=bias_random,
                              scale_factor=self.scale_factor_of(self.scale_factor, nodes_c,
                                                                start_c, dt),
                              installation=self.installation(nodes_c, start_c, dt))


def phase_increments(scale_factor: np.ndarray, bias: np.ndarray, installation: np.ndarray,
                     dtheta_t: np.ndarray, z: np.ndarray | None, sigma: np.ndarray,
                     sample_dt: float, idx: np.ndarray | int,
                     power: np.ndarray | None = None,
                     own_axis: np.ndarray | None = None) -> np.ndarray:
    """Phase increments [pulses] (C, n) of eq. 17 for one block, float64.

    ``scale_factor`` (m, C) [pulses/rad], ``bias`` (m, C) [rad/s], ``installation`` (m, C, 3),
    ``dtheta_t`` (3, n) [rad] (body x, y, z rows), ``z`` (C, n) float32 standard normals or
    None, ``sigma`` (C,) white-noise standard deviation per sample [rad], ``sample_dt`` = 1/f
    [s], ``idx`` from :func:`~rlgsim.sim.sensors.sensor_triad.sample_step_index`, ``power`` (m,) 0/1
    or None (= on), ``own_axis`` (C,) each gyro's body axis (see
    :func:`rlgsim.sim.sensors.sensor_triad.phase_increments`).

    Per sample, in this order (float64): ``u = ((E_x·Δθ_x + E_y·Δθ_y) + E_z·Δθ_z) + D·Δt``,
    ``u = u + σ·z``, ``inc = K·u`` — with E, D·Δt and K the values of the sample's thermal step.
    """
    return _triad_increments(scale_factor, bias, installation, dtheta_t, z, sigma, sample_dt,
                             idx, power, own_axis)
