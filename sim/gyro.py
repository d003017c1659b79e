"""Ring-laser-gyro error model: temperature-driven scale factor, bias and misalignment, noise,
and pulse output (paper 000 §3.3, eqs. 17–19; IEEE Std 647 style).

Measurement equation (paper 000 eq. 17, per gyro i, per sample interval Δt = 1/f):

    N_i = K_i(θ) · ( D_i(θ)·Δt + E_i(θ)·Δθ + n_i )                             [pulses]

with Δθ = ∫ω_ib^b dt the exact angle increment in body axes (:mod:`rlgsim.sim.motion`), K_i the scale
factor [pulses/rad] (nominal 2.14 pulses/arcsec, paper 000 §4.1), D_i the bias [rad/s], E_i the
i-th row of the installation matrix (1 on the gyro's own body axis, the two misalignment angles
[rad] towards the other two body axes) and n_i the angle-random-walk increment
N·√Δt·z [rad] (:func:`rlgsim.sim.noise.white_increments`). The pulses are counted from the
accumulated phase with the fractional remainder carried (:mod:`rlgsim.sim.pulses`).

Thermal state θ → parameters (one value per thermal step, held over the step's samples):

* D_i = law_D(θ) + b_flicker + b_rrw: the bias law (:mod:`rlgsim.sim.temperature_laws`; polynomial in the local
  block temperature, knee and step terms a cubic cannot follow, temperature rate, the
  Langmuir-flow anode-arm term T_D − T_E, multi-point gradients, and the discharge excitation
  U − U_0 tracked by UHFO, :mod:`rlgsim.sim.uhfo`) plus the slow noise of bias instability and rate
  random walk (:class:`rlgsim.sim.noise.SlowNoise`), which are part of the *true* bias;
* K_i = K_0·(1 + 10⁻⁶·law_K(θ)) with the scale-factor law in ppm;
* E_i off-diagonals = law_E(θ) in arcsec (two components per gyro).

Evaluation order (the truth in the dataset reproduces the pulses bit for bit when recomputed in
this order, float64), with E, D and K the values of the sample's thermal step:
``u = ((E_x·Δθ_x + E_y·Δθ_y) + E_z·Δθ_z) + D·Δt``, ``u = u + σ·z`` (σ·z in float64 from the
float32 normal z), ``inc = K·u``, then :mod:`rlgsim.sim.pulses` counts. While the device is unpowered
the increments are zero (no pulses).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from rlgsim.ground import units
from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_list, get_str, get_table
from rlgsim.sim.temperature_laws import Law, LawSpec

BODY_AXES = ("x", "y", "z")

#: Langmuir-flow bias per mA of leg-current imbalance [°/h/mA] (DESIGN.md, after Aronowitz &
#: Lim 1979) and the default imbalance per kelvin of anode-arm difference [mA/K] (rlgsim.sim.temperature_laws).
LANGMUIR_DEG_PER_H_PER_MA = 0.0066
LEG_IMBALANCE_MA_PER_K = 0.033

_GYRO_KEYS = ("axes", "blocks", "scale_factor_pulses_per_arcsec", "node", "t_ref_c", "bias",
              "scale_factor", "misalignment")


def axis_indices(axes: Sequence[str], ctx: Ctx, key: str = "axes") -> np.ndarray:
    """Body-axis indices (0..2) of sensor axes named x/y/z; distinct."""
    out = []
    for a in axes:
        if a not in BODY_AXES:
            raise ctx.error(key, f"value {a!r} not allowed; axes are named x, y or z")
        out.append(BODY_AXES.index(a))
    if len(set(out)) != len(out):
        raise ctx.error(key, f"value {list(axes)!r} not allowed; axes must be distinct")
    return np.array(out)


def installation_rows(mis: np.ndarray, axis_idx: np.ndarray) -> np.ndarray:
    """Installation-matrix rows (…, C, 3) from misalignments (…, 2C) [rad]: 1 on each sensor's
    own body axis, its two angles towards the other two axes (in x, y, z order)."""
    c = axis_idx.size
    out = np.zeros(mis.shape[:-1] + (c, 3))
    for s, a in enumerate(axis_idx):
        others = [j for j in range(3) if j != a]
        out[..., s, a] = 1.0
        out[..., s, others[0]] = mis[..., 2 * s]
        out[..., s, others[1]] = mis[..., 2 * s + 1]
    return out


def sample_step_index(n: int, m: int, rate_hz: float, step_s: float) -> np.ndarray | int:
    """For each of ``n`` samples of a block, the thermal step (0..m−1) holding its mid-point;
    an int ``r`` when every step holds exactly ``r`` samples (then sample j → step j // r)."""
    r = rate_hz * step_s
    if abs(r - round(r)) < 1e-9 and round(r) >= 1 and n == m * round(r):
        return int(round(r))
    k = np.floor((np.arange(n) + 0.5) / r).astype(np.int64)
    return np.minimum(k, m - 1)


def expand(values: np.ndarray, idx: np.ndarray | int) -> np.ndarray:
    """Per-step ``values`` (m, …) held over their samples: (n, …) (:func:`sample_step_index`)."""
    if isinstance(idx, int):
        return np.repeat(values, idx, axis=0)
    return values[idx]


@dataclass(frozen=True)
class GyroModel:
    """Nominal gyro triad (or single gyro) + tolerances: the ``[gyro]`` preset table.

    ``axes`` body axes of the gyros, ``blocks`` their thermal-network blocks (node prefix,
    e.g. "gx" → "gx.A"), ``k0`` nominal scale factor [pulses/rad], laws ``bias`` (°/h),
    ``scale_factor`` (ppm), ``misalignment`` (arcsec, two per gyro).
    """

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
        ``[gyro.misalignment]`` (arcsec) — see :mod:`rlgsim.sim.temperature_laws`."""
        check_known_keys(table, _GYRO_KEYS, ctx)
        axes = tuple(str(a) for a in get_list(table, "axes", ctx, ["x", "y", "z"], min_len=1))
        axis_indices(axes, ctx)
        default_blocks = ["g"] if len(axes) == 1 else [f"g{a}" for a in axes]
        blocks = tuple(str(b) for b in get_list(table, "blocks", ctx, default_blocks))
        if len(blocks) != len(axes):
            raise ctx.error("blocks", f"expected {len(axes)} block names (one per axis), got "
                                      f"{len(blocks)}")
        k = get_float(table, "scale_factor_pulses_per_arcsec", ctx, 2.14, min=0.0,
                      min_exclusive=True)
        node = get_str(table, "node", ctx, "A")
        t_ref = get_float(table, "t_ref_c", ctx, 20.0, min=-100.0, max=200.0)
        n = len(axes)
        common = dict(node=node, t_ref_c=t_ref)
        return cls(
            axes=axes, blocks=blocks, k0=k / units.ARCSEC,
            bias=LawSpec.from_config(get_table(table, "bias", ctx, {}), ctx.child("bias"),
                                     name="gyro.bias", unit="deg_per_h",
                                     to_si=units.deg_per_h_to_rad_per_s(1.0), n=n,
                                     langmuir=True,
                                     default_langmuir=LANGMUIR_DEG_PER_H_PER_MA,
                                     default_imbalance=LEG_IMBALANCE_MA_PER_K, **common),
            scale_factor=LawSpec.from_config(get_table(table, "scale_factor", ctx, {}),
                                             ctx.child("scale_factor"), name="gyro.scale_factor",
                                             unit="ppm", to_si=1e-6, n=n, **common),
            misalignment=LawSpec.from_config(get_table(table, "misalignment", ctx, {}),
                                             ctx.child("misalignment"),
                                             name="gyro.misalignment", unit="arcsec",
                                             to_si=units.ARCSEC, n=2 * n, **common))

    def with_tolerance(self, table: Mapping | None, ctx: Ctx) -> "GyroModel":
        """Add ``[tolerance.gyro]``: sub-tables ``bias``, ``scale_factor``, ``misalignment``
        (1σ per law key)."""
        if not table:
            return self
        check_known_keys(table, ("bias", "scale_factor", "misalignment"), ctx)
        return replace(
            self,
            bias=self.bias.with_tolerance(get_table(table, "bias", ctx, {}), ctx.child("bias")),
            scale_factor=self.scale_factor.with_tolerance(get_table(table, "scale_factor", ctx,
                                                                    {}),
                                                          ctx.child("scale_factor")),
            misalignment=self.misalignment.with_tolerance(get_table(table, "misalignment", ctx,
                                                                    {}),
                                                          ctx.child("misalignment")))

    def realise(self, draw) -> "Gyros":
        """Draw one unit (``draw(name, shape)`` → standard normals, keyed by name)."""
        return Gyros(axes=self.axes, blocks=self.blocks,
                     axis_idx=axis_indices(self.axes, Ctx()), k0=self.k0,
                     bias=self.bias.realise(draw), scale_factor=self.scale_factor.realise(draw),
                     misalignment=self.misalignment.realise(draw))


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
class Gyros:
    """One unit's gyros: realised laws and the measurement equation."""

    axes: tuple[str, ...]
    blocks: tuple[str, ...]
    axis_idx: np.ndarray
    k0: float
    bias: Law
    scale_factor: Law
    misalignment: Law

    @property
    def n(self) -> int:
        return len(self.axes)

    def laws(self) -> tuple[Law, ...]:
        return (self.bias, self.scale_factor, self.misalignment)

    def bind(self, node_names: Sequence[str]) -> None:
        """Resolve every law's nodes in the thermal network (KeyError names a missing node)."""
        self.bias.bind(self.blocks, node_names)
        self.scale_factor.bind(self.blocks, node_names)
        self.misalignment.bind(tuple(b for b in self.blocks for _ in range(2)), node_names)

    def parameters(self, nodes_c: np.ndarray, start_c: np.ndarray, dt: float,
                   bias_random: np.ndarray, uhfo_dev_v: np.ndarray | None) -> GyroParameters:
        """Evaluate the laws on the thermal grid (see the module docstring)."""
        bias = self.bias.evaluate(nodes_c, start_c, dt, uhfo_dev_v) + bias_random
        sf = self.k0 * (1.0 + self.scale_factor.evaluate(nodes_c, start_c, dt))
        mis = self.misalignment.evaluate(nodes_c, start_c, dt)
        return GyroParameters(bias=bias, bias_random=bias_random, scale_factor=sf,
                              installation=installation_rows(mis, self.axis_idx))


def row_times(u: np.ndarray, tmp: np.ndarray, row: np.ndarray, x_t: np.ndarray, own: int,
               idx: np.ndarray | int) -> None:
    """u = (row_x·x_x + row_y·x_y) + row_z·x_z per sample, the row (m, 3) held over each step.

    Column ``own`` (the sensor's own axis, −1: none) is exactly 1 (:func:`installation_rows`),
    so its product is the input itself — the same float64 result without the multiplication."""
    for j in range(3):
        dst = u if j == 0 else tmp
        if j == own:
            np.copyto(dst, x_t[j])
        else:
            np.multiply(expand(row[:, j], idx), x_t[j], out=dst)
        if j:
            u += tmp


def phase_increments(scale_factor: np.ndarray, bias: np.ndarray, installation: np.ndarray,
                     dtheta_t: np.ndarray, z: np.ndarray | None, sigma: np.ndarray,
                     sample_dt: float, idx: np.ndarray | int,
                     power: np.ndarray | None = None,
                     own_axis: np.ndarray | None = None) -> np.ndarray:
    """Phase increments [pulses] (C, n) of eq. 17 for one block, float64.

    ``scale_factor`` (m, C) [pulses/rad], ``bias`` (m, C) [rad/s], ``installation`` (m, C, 3),
    ``dtheta_t`` (3, n) [rad] (body x, y, z rows), ``z`` (C, n) float32 standard normals or
    None, ``sigma`` (C,) white-noise standard deviation per sample [rad], ``sample_dt`` = 1/f
    [s], ``idx`` from :func:`sample_step_index`, ``power`` (m,) 0/1 or None (= on),
    ``own_axis`` (C,) each gyro's body axis, whose installation entry is exactly 1 (skips that
    multiplication; same result).

    Per sample, in this order (float64): ``u = ((E_x·Δθ_x + E_y·Δθ_y) + E_z·Δθ_z) + D·Δt``,
    ``u = u + σ·z``, ``inc = K·u`` — with E, D·Δt and K the values of the sample's thermal step.
    """
    a = bias * sample_dt
    n = dtheta_t.shape[1]
    c = bias.shape[1]
    own = np.full(c, -1) if own_axis is None else np.asarray(own_axis)
    out = np.empty((c, n))
    tmp = np.empty(n)
    for s in range(c):
        u = out[s]
        row_times(u, tmp, installation[:, s], dtheta_t, own[s], idx)
        u += expand(a[:, s], idx)
        if z is not None:
            np.multiply(z[s], sigma[s], out=tmp, dtype=np.float64)
            u += tmp
        u *= expand(scale_factor[:, s], idx)
    if power is not None and not np.all(power > 0):
        out[:, expand(power, idx) <= 0] = 0.0
    return out
