"""What the gyro and accelerometer models share: sensors on body axes with temperature laws, an
installation matrix and a pulse output (paper 000 §3.3, eqs. 17 and 20).

Both sensor kinds are a set of C sensors (a triad, or one gyro) on distinct body axes x/y/z,
each on a thermal site of the network (a gyro block such as "gx", or an accelerometer's own
node such as "ax"). Each has a nominal scale factor ``k0``, a bias law, one or two scale-factor
laws in ppm and a misalignment law with two angles per sensor (:mod:`rlgsim.sim.sensors.temperature_laws`).
Their measurement equation differs only in the last step (one scale factor for a gyro, K⁺/K⁻ by
the sign of the input for a quartz-flexure accelerometer):

    u_i = ((E_x·x_x + E_y·x_y) + E_z·x_z) + D_i·Δt,   u_i = u_i + σ_i·z,   N_i = K_i·u_i

with ``x`` the exact angle (gyro) or velocity (accelerometer) increment of the sample in body
axes, ``E`` the sensor's installation row, ``D`` its bias and ``K`` its scale factor, each the
value of the sample's thermal step (:func:`sample_step_index`). This module holds that
equation (:func:`phase_increments`), the per-axis bookkeeping (:func:`axis_indices`,
:func:`installation_rows`), the preset-table parsing both ``from_config`` share
(:func:`parse_sensor_sites`, :func:`law_spec`) and the two base classes
:class:`SensorTriadModel` (the nominal laws + tolerances: ``with_tolerance``, ``realise``) and
:class:`SensorTriad` (one unit's realised laws: ``bind``, evaluation on the thermal grid).

Why this file is over 400 lines: it holds the one measurement equation the gyros and the
accelerometers share — the preset parsing of a triad, its realisation, and the pulse count with
its NumPy path beside the compiled one (_pulse_kernel.py) — so both instruments read one
definition, and the NumPy reference sits next to the call that may replace it.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_list, get_str, get_table
from rlgsim.sim.sensors.temperature_laws import Law, LawSpec

BODY_AXES = ("x", "y", "z")


# --------------------------------------------------------------------------- per-axis helpers

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


# --------------------------------------------------------------------------- preset tables

def parse_sensor_sites(table: Mapping, ctx: Ctx, site_key: str, noun: str,
                       default_sites: Callable[[tuple[str, ...]], list[str]]
                       ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """``axes`` (default ["x", "y", "z"], distinct) and one thermal site per axis under
    ``site_key`` (default ``default_sites(axes)``); ``noun`` names a site in the message."""
    axes = tuple(str(a) for a in get_list(table, "axes", ctx, ["x", "y", "z"], min_len=1))
    axis_indices(axes, ctx)
    sites = tuple(str(b) for b in get_list(table, site_key, ctx, default_sites(axes)))
    if len(sites) != len(axes):
        raise ctx.error(site_key, f"expected {len(axes)} {noun} names (one per axis), got "
                                  f"{len(sites)}")
    return axes, sites


def law_context(table: Mapping, ctx: Ctx, default_node: str) -> dict[str, Any]:
    """The keys every law of a sensor table shares: its local ``node`` and ``t_ref_c``."""
    return dict(node=get_str(table, "node", ctx, default_node),
                t_ref_c=get_float(table, "t_ref_c", ctx, 20.0, min=-100.0, max=200.0))


def law_spec(table: Mapping, ctx: Ctx, key: str, prefix: str, unit: str, to_si: float,
             n: int, common: Mapping[str, Any], **extra: Any) -> LawSpec:
    """The law of sub-table ``[<prefix>.<key>]`` (absent: all zero) for ``n`` components."""
    return LawSpec.from_config(get_table(table, key, ctx, {}), ctx.child(key),
                               name=f"{prefix}.{key}", unit=unit, to_si=to_si, n=n,
                               **common, **extra)


# --------------------------------------------------------------------------- base classes

class SensorTriadModel:
    """Nominal sensors + tolerances (a frozen dataclass with ``axes``, ``k0`` and one
    :class:`~rlgsim.sim.sensors.temperature_laws.LawSpec` field per name in ``LAWS``)."""

    #: Law fields, bias first and misalignment (two components per sensor) last.
    LAWS: ClassVar[tuple[str, ...]]
    axes: tuple[str, ...]

    def with_tolerance(self, table: Mapping | None, ctx: Ctx) -> Any:
        """Add ``[tolerance.<sensor>]``: one sub-table per law (1σ per law key)."""
        if not table:
            return self
        check_known_keys(table, self.LAWS, ctx)
        return replace(self, **{k: getattr(self, k).with_tolerance(get_table(table, k, ctx, {}),
                                                                   ctx.child(k))
                                for k in self.LAWS})

    def realised_laws(self, draw) -> dict[str, Law]:
        """Every law drawn for one unit (``draw(name, shape)`` → standard normals, keyed by
        name), by field name."""
        return {k: getattr(self, k).realise(draw) for k in self.LAWS}


class SensorTriad:
    """One unit's sensors: realised laws (fields named in ``LAWS``), their thermal ``sites``,
    ``axes``, ``axis_idx`` and nominal scale factor ``k0``."""

    LAWS: ClassVar[tuple[str, ...]]
    axes: tuple[str, ...]
    axis_idx: np.ndarray
    k0: float
    misalignment: Law

    @property
    def sites(self) -> tuple[str, ...]:
        """Each sensor's thermal site (gyro block or accelerometer node)."""
        raise NotImplementedError

    @property
    def n(self) -> int:
        return len(self.axes)

    def laws(self) -> tuple[Law, ...]:
        return tuple(getattr(self, k) for k in self.LAWS)

    def bind(self, node_names: Sequence[str]) -> None:
        """Resolve every law's nodes in the thermal network (KeyError names a missing node);
        the misalignment law has two components per sensor, on that sensor's site."""
        for law in self.laws()[:-1]:
            law.bind(self.sites, node_names)
        self.misalignment.bind(tuple(s for s in self.sites for _ in range(2)), node_names)

    def scale_factor_of(self, law: Law, nodes_c: np.ndarray, start_c: np.ndarray,
                        dt: float) -> np.ndarray:
        """``K = k0·(1 + law)`` on the thermal grid (m, C) [pulses per unit of input]."""
        return self.k0 * (1.0 + law.evaluate(nodes_c, start_c, dt))

    def installation(self, nodes_c: np.ndarray, start_c: np.ndarray, dt: float) -> np.ndarray:
        """Installation rows (m, C, 3) from the misalignment law on the thermal grid."""
        return installation_rows(self.misalignment.evaluate(nodes_c, start_c, dt),
                                 self.axis_idx)


# --------------------------------------------------------------------------- the equation

def _by_step(x: np.ndarray, idx: np.ndarray | int) -> np.ndarray:
    """A per-sample array (n,) viewed as (m, r) when every step holds ``r = idx`` samples, so a
    per-step value broadcasts over its samples without a repeated copy (:func:`_held`)."""
    return x.reshape(-1, idx) if isinstance(idx, int) else x


def _held(values: np.ndarray, idx: np.ndarray | int) -> np.ndarray:
    """Per-step ``values`` (m,) in the shape that meets :func:`_by_step` of a sample array."""
    return values[:, None] if isinstance(idx, int) else values[idx]


def row_times(u: np.ndarray, tmp: np.ndarray, row: np.ndarray, x_t: np.ndarray, own: int,
              idx: np.ndarray | int) -> None:
    """u = (row_x·x_x + row_y·x_y) + row_z·x_z per sample, the row (m, 3) held over each step.

    Column ``own`` (the sensor's own axis, −1: none) is exactly 1 (:func:`installation_rows`),
    so its product is the input itself — the same float64 result without the multiplication."""
    ub, tb = _by_step(u, idx), _by_step(tmp, idx)
    for j in range(3):
        dst = ub if j == 0 else tb
        if j == own:
            np.copyto(dst, _by_step(x_t[j], idx))
        else:
            np.multiply(_held(row[:, j], idx), _by_step(x_t[j], idx), out=dst)
        if j:
            u += tmp


def step_inputs(x_t: np.ndarray, m: int, idx: np.ndarray | int, *,
                compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """For the increments ``x_t`` (3, n) of a block of ``m`` steps: which steps hold the same
    increment (bit for bit, all three axes) in every sample — the turntable at rest: a static
    sample's increment depends only on the position — and each step's first sample (3, m).
    None unless every step holds ``idx`` samples. :func:`count_pulses` evaluates the
    measurement equation of such steps once per step: the same operations on the same
    numbers, so the same result for every sample.

    ``compiled``: compare in compiled code (:func:`rlgsim.sim.sensors._pulse_kernel.steps_at_rest`,
    one pass without temporaries, the GIL released) or with NumPy — the same arrays; None
    (default): compiled when the compiled counter is already loaded in this process (a
    long run, :mod:`rlgsim.sim.sensors.imu`), so a short run never imports numba for it."""
    if not isinstance(idx, int) or x_t.shape[1] != m * idx:
        return None
    if compiled is None:
        compiled = "rlgsim.sim.sensors._pulse_kernel" in sys.modules
    if compiled and m > 0:
        from rlgsim.sim.sensors._pulse_kernel import steps_at_rest
        uniform = np.empty(m, dtype=np.bool_)
        first = np.empty((3, m))
        steps_at_rest(np.ascontiguousarray(x_t, dtype=np.float64), idx, uniform, first)
        return uniform, first
    xs = x_t.reshape(3, m, idx)
    first = np.ascontiguousarray(xs[:, :, 0])
    bits = xs.view(np.int64)                      # bit patterns: ±0 and NaN compared exactly
    uniform = (bits == first.view(np.int64)[:, :, None]).all(axis=2).all(axis=0)
    return uniform, first


def _channel(u: np.ndarray, tmp: np.ndarray, s: int, scale_factor: np.ndarray, a: np.ndarray,
             installation: np.ndarray, x_t: np.ndarray, z: np.ndarray | None,
             sigma: np.ndarray, idx: np.ndarray | int, own: int,
             scale_factor_neg: np.ndarray | None, off: np.ndarray | None,
             scale: float, steps: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Channel ``s``'s increments × ``scale`` into ``u`` (n,) (see :func:`phase_increments`;
    ``a`` = D·Δt, ``off`` the samples while unpowered or None). ``scale`` a power of two
    multiplies the scale factor first: K·2^k is exact and so is every product with it.
    ``steps`` (:func:`step_inputs`): the row products and the bias of a step whose samples
    share one increment are computed once for the step, and only the noise per sample."""
    if steps is not None:
        uniform, first = steps
        m = first.shape[1]
        base = np.empty(m)
        row_times(base, np.empty(m), installation[:, s], first, own, 1)
        base += a[:, s]
        ub = u.reshape(m, idx)
        if z is not None:
            np.multiply(z[s], sigma[s], out=tmp, dtype=np.float64)
            np.add(tmp.reshape(m, idx), base[:, None], out=ub)
        else:
            ub[...] = base[:, None]
        moving = np.flatnonzero(~uniform)
        if moving.size:                         # steps whose samples differ: sample by sample
            k = moving.size * idx
            x_m = x_t.reshape(3, m, idx)[:, moving].reshape(3, k)
            um, tm = np.empty(k), np.empty(k)
            row_times(um, tm, installation[moving, s], x_m, own, idx)
            _by_step(um, idx)[...] += a[moving, s][:, None]
            if z is not None:
                um += tmp.reshape(m, idx)[moving].reshape(k)
            ub[moving] = um.reshape(-1, idx)
    else:
        row_times(u, tmp, installation[:, s], x_t, own, idx)
        ub = _by_step(u, idx)
        ub += _held(a[:, s], idx)
        if z is not None:
            np.multiply(z[s], sigma[s], out=tmp, dtype=np.float64)
            u += tmp
    k = scale_factor[:, s] * scale if scale != 1.0 else scale_factor[:, s]
    if scale_factor_neg is None:
        ub *= _held(k, idx)
    else:
        kn = scale_factor_neg[:, s] * scale if scale != 1.0 else scale_factor_neg[:, s]
        ub *= np.where(ub >= 0, _held(k, idx), _held(kn, idx))
    if off is not None:
        u[off] = 0.0


def _unpowered(power: np.ndarray | None, idx: np.ndarray | int) -> np.ndarray | None:
    """Samples taken while the device is off (their increments are zero), or None."""
    if power is None or np.all(power > 0):
        return None
    return expand(power, idx) <= 0


def phase_increments(scale_factor: np.ndarray, bias: np.ndarray, installation: np.ndarray,
                     x_t: np.ndarray, z: np.ndarray | None, sigma: np.ndarray,
                     sample_dt: float, idx: np.ndarray | int,
                     power: np.ndarray | None = None, own_axis: np.ndarray | None = None,
                     scale_factor_neg: np.ndarray | None = None) -> np.ndarray:
    """Phase increments [pulses] (C, n) of one block, float64 (module docstring).

    ``scale_factor`` (m, C) [pulses per unit of x], ``bias`` (m, C) [unit of x per s],
    ``installation`` (m, C, 3), ``x_t`` (3, n) the increments of the sample in body x, y, z
    rows, ``z`` (C, n) float32 standard normals or None, ``sigma`` (C,) white-noise standard
    deviation per sample [unit of x], ``sample_dt`` = 1/f [s], ``idx`` from
    :func:`sample_step_index`, ``power`` (m,) 0/1 or None (= on; zero increments while off),
    ``own_axis`` (C,) each sensor's body axis, whose installation entry is exactly 1 (skips
    that multiplication; same result). With ``scale_factor_neg`` (m, C) the scale factor is
    ``scale_factor`` where ``u ≥ 0`` and ``scale_factor_neg`` where ``u < 0``.

    Per sample, in this order (float64): ``u = ((E_x·x_x + E_y·x_y) + E_z·x_z) + D·Δt``,
    ``u = u + σ·z`` (σ·z in float64 from the float32 z), ``inc = K·u``.
    """
    return _increments(scale_factor, bias, installation, x_t, z, sigma, sample_dt, idx, power,
                       own_axis, scale_factor_neg, 1.0)


def _increments(scale_factor, bias, installation, x_t, z, sigma, sample_dt, idx, power,
                own_axis, scale_factor_neg, scale, channel_done=None, steps=None
                ) -> np.ndarray:
    a = bias * sample_dt
    n = x_t.shape[1]
    c = bias.shape[1]
    own = np.full(c, -1) if own_axis is None else np.asarray(own_axis)
    off = _unpowered(power, idx)
    out = np.empty((c, n)) if channel_done is None else np.empty((1, n))
    tmp = np.empty(n)
    for s in range(c):
        u = out[s] if channel_done is None else out[0]
        _channel(u, tmp, s, scale_factor, a, installation, x_t, z, sigma, idx, own[s],
                 scale_factor_neg, off, scale, steps)
        if channel_done is not None:
            channel_done(s, u)
    return out


def count_pulses(remainder: np.ndarray, scale_factor: np.ndarray, bias: np.ndarray,
                 installation: np.ndarray, x_t: np.ndarray, z: np.ndarray | None,
                 sigma: np.ndarray, sample_dt: float, idx: np.ndarray | int,
                 power: np.ndarray | None = None, own_axis: np.ndarray | None = None,
                 scale_factor_neg: np.ndarray | None = None,
                 steps: tuple[np.ndarray, np.ndarray] | None = None, *,
                 compiled: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Pulses (n, C) int32 and the new remainders (C,) int64 of one block: the increments of
    :func:`phase_increments` counted by :mod:`rlgsim.sim.sensors.pulses` with the carried
    ``remainder`` (C,) — bit for bit ``pulses.count_fixed(pulses.quantise(inc), r)`` per
    channel, with the fixed-point factor 2^30 folded into the scale factor (exact: a power of
    two). ``steps``: :func:`step_inputs` of ``x_t`` (steps at rest evaluated once per step),
    or None.

    ``compiled`` (default): every channel in one call of compiled code
    (:func:`rlgsim.sim.sensors._pulse_kernel.count_block`, the same operations in the same order);
    False: the NumPy reference path (:func:`_count_pulses_numpy`), which the tests compare it
    with and which also raises the counter's range error for a channel out of range."""
    if not compiled or x_t.shape[1] == 0:
        return _count_pulses_numpy(remainder, scale_factor, bias, installation, x_t, z, sigma,
                                   sample_dt, idx, power, own_axis, scale_factor_neg, steps)
    from rlgsim.sim.sensors import pulses as counter
    from rlgsim.sim.sensors._pulse_kernel import count_block
    n, c = x_t.shape[1], bias.shape[1]
    one = float(counter.ONE)
    out = np.empty((n, c), dtype=np.int32)
    new = np.empty(c, dtype=np.int64)
    peak_bits = np.empty(c, dtype=np.int64)
    own = (np.full(c, -1, dtype=np.int64) if own_axis is None
           else np.ascontiguousarray(own_axis, dtype=np.int64))
    r, step_of = (idx, _NO_INT) if isinstance(idx, int) else (0, np.ascontiguousarray(idx,
                                                                                     np.int64))
    uniform, first = ((_NO_BOOL, _NO_FIRST) if steps is None
                      else (np.ascontiguousarray(steps[0]), np.ascontiguousarray(steps[1])))
    count_block(np.ascontiguousarray(x_t, dtype=np.float64),
                np.ascontiguousarray(installation, dtype=np.float64),
                np.ascontiguousarray(bias, dtype=np.float64), float(sample_dt),
                _NO_Z if z is None else np.ascontiguousarray(z, dtype=np.float32),
                np.ascontiguousarray(sigma, dtype=np.float64),
                np.ascontiguousarray(scale_factor, dtype=np.float64),
                (_NO_K if scale_factor_neg is None
                 else np.ascontiguousarray(scale_factor_neg, dtype=np.float64)),
                one, r, step_of, uniform, first, own,
                _NO_FLOAT if power is None else np.ascontiguousarray(power, dtype=np.float64),
                np.ascontiguousarray(remainder, dtype=np.int64), out, new, peak_bits)
    peak = peak_bits.view(np.float64)                # NaN: the test below fails
    bad = ~((peak <= counter.MAX_SAMPLE_PULSES * one)
            & (peak * n <= counter.MAX_BLOCK_PULSES * one))
    if bad.any():
        # out of the fast test's range: the NumPy path decides (and raises the range error)
        a = bias * sample_dt
        off = _unpowered(power, idx)
        for s in np.flatnonzero(bad):
            u, tmp = np.empty(n), np.empty(n)
            _channel(u, tmp, s, scale_factor, a, installation, x_t, z, sigma, idx, int(own[s]),
                     scale_factor_neg, off, one, steps)
            _, new[s] = counter.count_scaled(u, int(remainder[s]), out[:, s])
    return out, new


_NO_BOOL = np.zeros(0, dtype=np.bool_)
_NO_INT = np.zeros(0, dtype=np.int64)
_NO_FLOAT = np.zeros(0)
_NO_K = np.zeros((0, 0))
_NO_Z = np.zeros((1, 0), dtype=np.float32)
_NO_FIRST = np.zeros((3, 0))


def _count_pulses_numpy(remainder, scale_factor, bias, installation, x_t, z, sigma, sample_dt,
                        idx, power=None, own_axis=None, scale_factor_neg=None, steps=None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`count_pulses` in NumPy, computed one channel at a time in one reused buffer
    (the reference path of the compiled kernel)."""
    from rlgsim.sim.sensors import pulses as counter
    n, c = x_t.shape[1], bias.shape[1]
    out = np.empty((n, c), dtype=np.int32)
    new = np.zeros(c, dtype=np.int64)

    def done(s: int, u: np.ndarray) -> None:
        _, new[s] = counter.count_scaled(u, int(remainder[s]), out[:, s])
    _increments(scale_factor, bias, installation, x_t, z, sigma, sample_dt, idx, power,
                own_axis, scale_factor_neg, float(counter.ONE), done, steps)
    return out, new
