"""Quartz-flexure accelerometer error model with pulse output (paper 000 §3.3, eqs. 20–22).

Measurement equation (paper 000 eq. 20, per accelerometer i, per sample interval Δt = 1/f):

    u_i = D_i(θ)·Δt + E_i(θ)·Δv + n_i                                           [m/s]
    N_i = K_i^±(θ) · u_i,    K^+ if u_i ≥ 0 else K^−                              [pulses]

Δv = ∫f^b dt the exact velocity increment in body axes (:mod:`rlgsim.sim.motion`), D_i the bias
[m/s²], E_i the installation row (1 on the own axis, two misalignment angles [rad]), n_i the
velocity-random-walk increment VRW·√Δt·z [m/s], and K^+/K^− the separate positive and negative
scale factors [pulses/(m/s)] — paper 000 splits them because a quartz-flexure accelerometer's
torquer and current-to-frequency converter respond differently to the two signs of the input.
The pulses are counted with the remainder carried (:mod:`rlgsim.sim.pulses`).

Temperature dependence (paper 000 §2(2): the torque coil's magnet and the pendulum's thermal
imbalance move bias and scale factor): bias law in µg, K^± = K_0·(1 + 10⁻⁶·law_±) with separate
ppm laws for the two signs, misalignment law in arcsec (all :mod:`rlgsim.sim.temperature_laws`, local node the
accelerometer's own thermal node by default). Typical navigation-grade quartz-flexure figures:
bias temperature coefficient tens of µg/°C, scale factor tens of ppm/°C (DESIGN.md). Bias
instability (flicker) and acceleration random walk join the true bias
(:class:`rlgsim.sim.noise.SlowNoise`).

Evaluation order (float64; the stored truth reproduces the pulses in this order):
``u = ((E_x·Δv_x + E_y·Δv_y) + E_z·Δv_z) + D·Δt``, ``u = u + σ·z``, ``inc = K^±·u`` with
K^+ where u ≥ 0. Zero while unpowered.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from rlgsim.ground import units
from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_list, get_str, get_table
from rlgsim.sim.gyro import row_times, axis_indices, expand, installation_rows
from rlgsim.sim.temperature_laws import Law, LawSpec

_ACCEL_KEYS = ("axes", "nodes", "scale_factor_pulses_per_s_per_g", "node", "t_ref_c", "bias",
               "scale_factor_pos", "scale_factor_neg", "misalignment")


@dataclass(frozen=True)
class AccelerometerModel:
    """Nominal accelerometer triad + tolerances: the ``[accelerometer]`` preset table.

    ``axes`` body axes, ``nodes`` each accelerometer's thermal node (its "block"), ``k0``
    nominal scale factor [pulses/(m/s)], laws ``bias`` (µg), ``scale_factor_pos`` /
    ``scale_factor_neg`` (ppm), ``misalignment`` (arcsec, two per accelerometer).
    """

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
        axes = tuple(str(a) for a in get_list(table, "axes", ctx, ["x", "y", "z"], min_len=1))
        axis_indices(axes, ctx)
        nodes = tuple(str(v) for v in get_list(table, "nodes", ctx, [f"a{a}" for a in axes]))
        if len(nodes) != len(axes):
            raise ctx.error("nodes", f"expected {len(axes)} node names (one per axis), got "
                                     f"{len(nodes)}")
        k = get_float(table, "scale_factor_pulses_per_s_per_g", ctx, 5000.0, min=0.0,
                      min_exclusive=True)
        common = dict(node=get_str(table, "node", ctx, "self"),
                      t_ref_c=get_float(table, "t_ref_c", ctx, 20.0, min=-100.0, max=200.0))
        n = len(axes)

        def law(key: str, name: str, unit: str, to_si: float, count: int) -> LawSpec:
            return LawSpec.from_config(get_table(table, key, ctx, {}), ctx.child(key),
                                       name=f"accel.{name}", unit=unit, to_si=to_si, n=count,
                                       **common)
        return cls(axes=axes, nodes=nodes, k0=k / units.G0,
                   bias=law("bias", "bias", "ug", units.MICRO_G, n),
                   scale_factor_pos=law("scale_factor_pos", "scale_factor_pos", "ppm", 1e-6, n),
                   scale_factor_neg=law("scale_factor_neg", "scale_factor_neg", "ppm", 1e-6, n),
                   misalignment=law("misalignment", "misalignment", "arcsec", units.ARCSEC,
                                    2 * n))

    def with_tolerance(self, table: Mapping | None, ctx: Ctx) -> "AccelerometerModel":
        """Add ``[tolerance.accelerometer]``: sub-tables per law (1σ per law key)."""
        if not table:
            return self
        names = ("bias", "scale_factor_pos", "scale_factor_neg", "misalignment")
        check_known_keys(table, names, ctx)
        return replace(self, **{k: getattr(self, k).with_tolerance(get_table(table, k, ctx, {}),
                                                                   ctx.child(k))
                                for k in names})

    def realise(self, draw) -> "Accelerometers":
        return Accelerometers(axes=self.axes, nodes=self.nodes,
                              axis_idx=axis_indices(self.axes, Ctx()), k0=self.k0,
                              bias=self.bias.realise(draw),
                              scale_factor_pos=self.scale_factor_pos.realise(draw),
                              scale_factor_neg=self.scale_factor_neg.realise(draw),
                              misalignment=self.misalignment.realise(draw))


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
class Accelerometers:
    """One unit's accelerometers: realised laws and the measurement equation."""

    axes: tuple[str, ...]
    nodes: tuple[str, ...]
    axis_idx: np.ndarray
    k0: float
    bias: Law
    scale_factor_pos: Law
    scale_factor_neg: Law
    misalignment: Law

    @property
    def n(self) -> int:
        return len(self.axes)

    def laws(self) -> tuple[Law, ...]:
        return (self.bias, self.scale_factor_pos, self.scale_factor_neg, self.misalignment)

    def bind(self, node_names: Sequence[str]) -> None:
        """Resolve the laws' nodes; the node "self" is the accelerometer's own node."""
        for law in (self.bias, self.scale_factor_pos, self.scale_factor_neg):
            law.bind(self.nodes, node_names)
        self.misalignment.bind(tuple(v for v in self.nodes for _ in range(2)), node_names)

    def parameters(self, nodes_c: np.ndarray, start_c: np.ndarray, dt: float,
                   bias_random: np.ndarray) -> AccelParameters:
        bias = self.bias.evaluate(nodes_c, start_c, dt) + bias_random
        kp = self.k0 * (1.0 + self.scale_factor_pos.evaluate(nodes_c, start_c, dt))
        kn = self.k0 * (1.0 + self.scale_factor_neg.evaluate(nodes_c, start_c, dt))
        mis = self.misalignment.evaluate(nodes_c, start_c, dt)
        return AccelParameters(bias=bias, bias_random=bias_random, scale_factor_pos=kp,
                               scale_factor_neg=kn,
                               installation=installation_rows(mis, self.axis_idx))


def phase_increments(kpos: np.ndarray, kneg: np.ndarray, bias: np.ndarray,
                     installation: np.ndarray, dv_t: np.ndarray, z: np.ndarray | None,
                     sigma: np.ndarray, sample_dt: float, idx: np.ndarray | int,
                     power: np.ndarray | None = None,
                     own_axis: np.ndarray | None = None) -> np.ndarray:
    """Phase increments [pulses] (C, n) of eq. 20 for one block, float64.

    ``kpos``/``kneg`` (m, C) [pulses/(m/s)], ``bias`` (m, C) [m/s²], ``installation``
    (m, C, 3), ``dv_t`` (3, n) [m/s], ``z`` (C, n) float32 standard normals or None, ``sigma``
    (C,) [m/s], ``own_axis`` as in :func:`rlgsim.sim.gyro.phase_increments`. Per sample, in this
    order: ``u = ((E_x·Δv_x + E_y·Δv_y) + E_z·Δv_z) + D·Δt``,
    ``u = u + σ·z``, ``inc = (K⁺ if u ≥ 0 else K⁻)·u``.
    """
    a = bias * sample_dt
    n = dv_t.shape[1]
    c = bias.shape[1]
    own = np.full(c, -1) if own_axis is None else np.asarray(own_axis)
    out = np.empty((c, n))
    tmp = np.empty(n)
    for s in range(c):
        u = out[s]
        row_times(u, tmp, installation[:, s], dv_t, own[s], idx)
        u += expand(a[:, s], idx)
        if z is not None:
            np.multiply(z[s], sigma[s], out=tmp, dtype=np.float64)
            u += tmp
        u *= np.where(u >= 0, expand(kpos[:, s], idx), expand(kneg[:, s], idx))
    if power is not None and not np.all(power > 0):
        out[:, expand(power, idx) <= 0] = 0.0
    return out
