"""Sensor noise: white (angle / velocity random walk), flicker bias instability, rate random walk.

Conventions — IEEE Std 952-1997 (R2008), Annex C, whose power spectral densities are
*two-sided*; σ_A(τ) is the Allan deviation of the rate (allantools ``oadev`` with
``data_type="freq"`` on rate samples):

=====================  ===========================  ===============================  ==========
term                   PSD of the rate S(f)          Allan deviation σ_A(τ)            read at
=====================  ===========================  ===============================  ==========
white rate (ARW/VRW)   N²                            N / √τ                            τ = 1 s
flicker (bias instab.) B² / (2π f)                   B · √(2 ln2 / π) = 0.664 B        the floor
rate random walk       K² / (2π f)²                  K · √(τ / 3)                      τ = 3 s
=====================  ===========================  ===============================  ==========

so N is in rad/√s (°/√h in presets), B in rad/s (°/h), K in rad/s/√s (°/h/√h); the
accelerometer analogues are velocity random walk (m/s/√s; µg/√Hz in presets), bias instability
(m/s²; µg) and acceleration random walk (m/s²/√s; µg/√s).

Generators (all vectorised, all with carried state, all drawing their block's random numbers
from a generator keyed by the block index, so that splitting a run into blocks never changes a
byte):

* :func:`white_increments` — white rate noise integrated over each sample interval Δt: the
  angle (velocity) increment noise, N(0, N²·Δt) per sample; no state.
* :class:`FlickerBank` — bias instability as a bank of first-order Gauss–Markov processes with
  correlation times spaced evenly in log τ over [τ_min, τ_max] (``per_decade`` per decade). A
  Gauss–Markov process of variance q² and correlation time τ has the one-sided PSD
  4q²τ / (1 + (2πfτ)²); a continuum of them with equal q² and density 1/Δ in ln τ sums to
  q² / (Δ f) between 1/(2πτ_max) and 1/(2πτ_min). Matching the one-sided flicker PSD
  2·B²/(2πf) = B²/(πf) gives q² = B²·Δ/π with Δ the spacing in ln τ, ≈ ln(10)/per_decade,
  the two end processes carrying half (Keshner, "1/f noise",
  Proc. IEEE 70(3), 1982; the same construction is used by Kasdin's review, Proc. IEEE 83(5),
  1995, §IV). Each process is propagated exactly at the step Δt:
  x_k = φ x_{k−1} + q√(1−φ²) w_k, φ = exp(−Δt/τ), with :func:`scipy.signal.lfilter` and its
  carried initial condition ``zi``; the initial state is drawn from the stationary law, so the
  process is stationary from t = 0.
* :class:`RandomWalk` — rate random walk b_k = b_{k−1} + K√Δt·w_k (cumulative sum with the
  carried last value; starts at 0, the unit's turn-on bias belongs to the deterministic model).

Why a hand-written bank: it is a handful of first-order filters (scipy's ``lfilter`` does the
work); Kasdin's fractional-difference generator (as in ``allantools.noise``) needs the whole
past as state, which cannot be carried across blocks in bounded memory.

:class:`NoiseModel` holds a device's noise levels (the ``[noise]`` preset table).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.signal import lfilter

from rlgsim.ground import units
from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_int
from rlgsim.sim.rng import block_seed_words, generator, word

#: Allan-deviation floor of flicker noise per unit bias instability, √(2 ln2/π) (IEEE 952 C.4).
FLICKER_FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)


def white_increments(rng: np.random.Generator, n: int, channels: int, density: np.ndarray,
                     dt: float) -> np.ndarray:
    """Integrated white rate noise over ``n`` sample intervals of ``dt`` s: (n, channels).

    ``density`` N per channel (rad/√s for angles, m/s/√s for velocities); each sample is
    N·√dt·z with z standard normal drawn as float32 (``rng.standard_normal(..., float32)``) and
    widened to float64 before scaling — this exact recipe is what the dataset's truth documents
    so the pulses can be recomputed. Returns float64.
    """
    z = rng.standard_normal((n, channels), dtype=np.float32)
    return z * (np.asarray(density, dtype=float) * math.sqrt(dt))


@dataclass
class FlickerBank:
    """Flicker (1/f) rate noise of bias instability ``b`` (per channel) at step ``dt``.

    ``b`` (C,) bias instability B in SI (rad/s or m/s²); ``tau_min_s``/``tau_max_s`` the span of
    correlation times, ``per_decade`` processes per decade. Attributes: ``tau_s`` (J,),
    ``phi`` (J,), ``q`` (J, C) the stationary standard deviation of each process.
    """

    b: np.ndarray
    dt: float
    tau_min_s: float = 2.0
    tau_max_s: float = 1.0e5
    per_decade: int = 2
    tau_s: np.ndarray = field(init=False)
    phi: np.ndarray = field(init=False)
    q: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.b = np.atleast_1d(np.asarray(self.b, dtype=float))
        if not (0 < self.tau_min_s < self.tau_max_s):
            raise ValueError(f"need 0 < tau_min_s < tau_max_s, got {self.tau_min_s}, "
                             f"{self.tau_max_s}")
        decades = math.log10(self.tau_max_s / self.tau_min_s)
        j = max(2, int(round(decades * self.per_decade)) + 1)
        self.tau_s = np.geomspace(self.tau_min_s, self.tau_max_s, j)
        delta = math.log(self.tau_s[1] / self.tau_s[0])
        self.phi = np.exp(-self.dt / self.tau_s)
        # q² = B² Δ / π for the interior; the two end processes carry half the weight
        # (trapezoidal rule over ln τ), which keeps the floor flat up to the band edges.
        w = np.ones(j)
        w[0] = w[-1] = 0.5
        self.q = np.sqrt(w[:, None] * delta / math.pi) * self.b[None, :]

    @property
    def channels(self) -> int:
        return self.b.size

    def initial_state(self, rng: np.random.Generator) -> np.ndarray:
        """A stationary draw of every process, (J, C)."""
        return self.q * rng.standard_normal(self.q.shape)

    def block(self, state: np.ndarray, rng: np.random.Generator, m: int
              ) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``m`` steps: the summed flicker rate (m, C) at the step ends, new state."""
        j, c = self.q.shape
        return self.block_from(state, rng.standard_normal((j, c, m)))

    def block_from(self, state: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance by the standard-normal drive ``w`` (J, C, m); see :meth:`block`."""
        j, c, m = w.shape
        out = np.zeros((c, m))
        new = np.empty_like(state)
        for i in range(j):
            phi = self.phi[i]
            drive = self.q[i] * math.sqrt(1.0 - phi * phi)            # (C,)
            x, _ = lfilter([1.0], [1.0, -phi], w[i] * drive[:, None], axis=-1,
                           zi=(phi * state[i])[:, None])
            out += x
            new[i] = x[:, -1]
        return out.T, new


@dataclass
class RandomWalk:
    """Rate random walk of coefficient ``k`` (per channel, SI: rad/s/√s or m/s²/√s) at ``dt``."""

    k: np.ndarray
    dt: float

    def __post_init__(self) -> None:
        self.k = np.atleast_1d(np.asarray(self.k, dtype=float))

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.k.size)

    def block(self, state: np.ndarray, rng: np.random.Generator, m: int
              ) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``m`` steps: the walk (m, C) at the step ends, new state (C,)."""
        return self.block_from(state, rng.standard_normal((m, self.k.size)))

    def block_from(self, state: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance by the standard-normal drive ``w`` (m, C); see :meth:`block`."""
        w = w * (self.k * math.sqrt(self.dt))
        w[0] += state
        x = np.cumsum(w, axis=0)
        return x, x[-1].copy()


_EMPTY3 = np.zeros((0, 0, 0))
_EMPTY2 = np.zeros((0, 0))


def _compiled_slow_block():
    """:func:`rlgsim.sim.sensors._noise_kernel.slow_block` once numba is loaded in this process (the
    rule of the compiled pulse counter: a short run never imports numba for this), else
    None: the NumPy path, the same numbers bit for bit."""
    if "numba" not in sys.modules:
        return None
    try:
        from rlgsim.sim.sensors._noise_kernel import slow_block
    except ImportError:                     # pragma: no cover - numba present but unusable
        return None
    return slow_block


# --------------------------------------------------------------------------- preset table

_NOISE_KEYS = {
    # key: (SI conversion, description)
    "gyro_arw_deg_per_sqrt_h": (units.deg_per_sqrt_h_to_rad_per_sqrt_s, "gyro angle random walk"),
    "gyro_bias_instability_deg_per_h": (units.deg_per_h_to_rad_per_s, "gyro bias instability"),
    "gyro_rrw_deg_per_h_per_sqrt_h": (units.deg_per_h_per_sqrt_h_to_rad_per_s_per_sqrt_s,
                                      "gyro rate random walk"),
    "accel_vrw_ug_per_sqrt_hz": (units.ug_per_sqrt_hz_to_m_per_s2_per_sqrt_hz,
                                 "accelerometer velocity random walk"),
    "accel_bias_instability_ug": (units.ug_to_m_per_s2, "accelerometer bias instability"),
    "accel_rrw_ug_per_sqrt_s": (units.ug_to_m_per_s2, "accelerometer acceleration random walk"),
}


@dataclass(frozen=True)
class NoiseModel:
    """Noise levels of a device (the ``[noise]`` preset table), in SI.

    ``gyro_arw`` N [rad/√s], ``gyro_bi`` B [rad/s], ``gyro_rrw`` K [rad/s/√s];
    ``accel_vrw`` [m/s/√s], ``accel_bi`` [m/s²], ``accel_rrw`` [m/s²/√s]; the flicker bank's
    span ``flicker_tau_min_s`` .. ``flicker_tau_max_s`` and ``flicker_per_decade``.
    """

    gyro_arw: float = 0.0
    gyro_bi: float = 0.0
    gyro_rrw: float = 0.0
    accel_vrw: float = 0.0
    accel_bi: float = 0.0
    accel_rrw: float = 0.0
    flicker_tau_min_s: float = 2.0
    flicker_tau_max_s: float = 1.0e5
    flicker_per_decade: int = 2

    @classmethod
    def from_config(cls, table: Mapping, ctx: Ctx) -> "NoiseModel":
        """Validate a ``[noise]`` table (keys in :data:`_NOISE_KEYS` plus the flicker span)."""
        check_known_keys(table, (*_NOISE_KEYS, "flicker_tau_min_s", "flicker_tau_max_s",
                                 "flicker_per_decade"), ctx)
        vals = {key: conv(get_float(table, key, ctx, 0.0, min=0.0))
                for key, (conv, _) in _NOISE_KEYS.items()}
        tmin = get_float(table, "flicker_tau_min_s", ctx, 2.0, min=0.0, min_exclusive=True)
        tmax = get_float(table, "flicker_tau_max_s", ctx, 1.0e5, min=0.0, min_exclusive=True)
        if tmax <= tmin:
            raise ctx.error("flicker_tau_max_s", f"value {tmax:g} not allowed; must be > "
                                                 f"flicker_tau_min_s ({tmin:g})")
        return cls(gyro_arw=vals["gyro_arw_deg_per_sqrt_h"],
                   gyro_bi=vals["gyro_bias_instability_deg_per_h"],
                   gyro_rrw=vals["gyro_rrw_deg_per_h_per_sqrt_h"],
                   accel_vrw=vals["accel_vrw_ug_per_sqrt_hz"],
                   accel_bi=vals["accel_bias_instability_ug"],
                   accel_rrw=vals["accel_rrw_ug_per_sqrt_s"],
                   flicker_tau_min_s=tmin, flicker_tau_max_s=tmax,
                   flicker_per_decade=get_int(table, "flicker_per_decade", ctx, 2, min=1,
                                              max=20))

    def scaled(self, factors: Mapping[str, float]) -> "NoiseModel":
        """A copy with levels multiplied by ``factors`` (field name → factor), for realisations."""
        return replace(self, **{k: getattr(self, k) * float(v) for k, v in factors.items()})


#: NoiseModel fields that are noise levels (drawn with a relative tolerance per unit).
NOISE_LEVELS = ("gyro_arw", "gyro_bi", "gyro_rrw", "accel_vrw", "accel_bi", "accel_rrw")


class SlowNoise:
    """Flicker + random walk of sensor channels on the thermal grid, with carried state.

    ``bi`` (C,) bias instabilities and ``rrw`` (C,) random-walk coefficients in SI; ``axes``
    names the channels and ``purpose`` their sensor ("gyro", "accel"; one name for all or one
    per channel). Draws: block ``b`` uses ``generator(seed, unit, f"{purpose}.flicker", axis,
    b)`` and ``generator(seed, unit, f"{purpose}.rrw", axis, b)`` per channel; the flicker bank's
    stationary start uses ``generator(seed, unit, f"{purpose}.flicker_start", axis, 0)``. One
    :class:`FlickerBank` serves all channels (gyros and accelerometers together), so each of
    its ``lfilter`` calls runs every channel at once.
    """

    def __init__(self, bi: np.ndarray, rrw: np.ndarray, dt: float, model: NoiseModel,
                 axes: Sequence[str], seed: int, unit: int,
                 purpose: str | Sequence[str]) -> None:
        self._gen = generator
        self.axes = tuple(axes)
        self.seed, self.unit = seed, unit
        self.purposes = ((purpose,) * len(self.axes) if isinstance(purpose, str)
                         else tuple(purpose))
        self.bi = np.asarray(bi, float).reshape(len(self.axes))
        self.rrw = np.asarray(rrw, float).reshape(len(self.axes))
        self.flicker = FlickerBank(self.bi, dt, model.flicker_tau_min_s,
                                   model.flicker_tau_max_s, model.flicker_per_decade)
        self.walk = RandomWalk(self.rrw, dt)
        self.has_flicker = bool(np.any(self.bi > 0))
        self.has_walk = bool(np.any(self.rrw > 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        fs = np.zeros(self.flicker.q.shape)
        if self.has_flicker:
            for c, (p, a) in enumerate(zip(self.purposes, self.axes)):
                rng = self._gen(self.seed, self.unit, f"{p}.flicker_start", a, 0)
                fs[:, c] = self.flicker.q[:, c] * rng.standard_normal(fs.shape[0])
        return fs, self.walk.initial_state()

    def draws(self, b: int, m: int, fill: Any = None
              ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The standard-normal drives of block ``b`` (``m`` steps): flicker (J, C, m) and
        random walk (m, C), None when the term is off. Independent of any state, so they may be
        drawn ahead (in another thread). ``fill``
        (:func:`rlgsim.sim.sensors._normal_kernel.fill_streams`) draws them all in one compiled
        call from the streams' seed words — numpy's numbers; None: numpy's call per channel."""
        j, n_ch = self.flicker.q.shape[0], len(self.axes)
        n_f = j * n_ch * m if self.has_flicker else 0
        base = np.empty(n_f + (m * n_ch if self.has_walk else 0))
        wf = base[:n_f].reshape(j, n_ch, m) if self.has_flicker else None
        wr = base[n_f:].reshape(m, n_ch) if self.has_walk else None
        if fill is not None:
            keys, views = self._streams(m)
            fill(block_seed_words(self.seed, self.unit, keys, b), base, views)
            return wf, wr
        for c, (p, a) in enumerate(zip(self.purposes, self.axes)):
            if wf is not None:
                g = self._gen(self.seed, self.unit, f"{p}.flicker", a, b)
                wf[:, c, :] = g.standard_normal((j, m))
            if wr is not None:
                wr[:, c] = self._gen(self.seed, self.unit, f"{p}.rrw", a, b).standard_normal(m)
        return wf, wr

    def _streams(self, m: int) -> tuple[list[tuple[int, int]], np.ndarray]:
        """The drives' streams of a block of ``m`` steps: their (purpose, channel) words and
        where each one's draws go in :meth:`draws`' base array — (offset, n0, s0, n1, s1), the
        layouts of ``wf[:, c, :]`` and ``wr[:, c]`` (kept per ``m``)."""
        cache = self.__dict__.setdefault("_stream_cache", {})
        if m not in cache:
            j, n_ch = self.flicker.q.shape[0], len(self.axes)
            n_f = j * n_ch * m if self.has_flicker else 0
            keys, views = [], []
            for c, (p, a) in enumerate(zip(self.purposes, self.axes)):
                if self.has_flicker:
                    keys.append((word(f"{p}.flicker"), word(a)))
                    views.append((c * m, j, n_ch * m, m, 1))
                if self.has_walk:
                    keys.append((word(f"{p}.rrw"), word(a)))
                    views.append((n_f + c, 1, 0, m, n_ch))
            cache[m] = (keys, np.array(views, dtype=np.int64).reshape(-1, 5))
        return cache[m]

    def block(self, state: tuple[np.ndarray, np.ndarray], b: int, m: int,
              draws: tuple[np.ndarray | None, np.ndarray | None] | None = None
              ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The slow noise (m, C) in SI at the step ends of block ``b`` and the new state
        (``draws``: :meth:`draws` of this block, drawn now when None)."""
        fs, ws = state
        wf, wr = draws if draws is not None else self.draws(b, m)
        kernel = _compiled_slow_block() if m > 0 else None
        if kernel is not None:              # the same operations in one compiled call
            out = np.empty((m, len(self.axes)))
            new_fs, new_ws = np.empty_like(fs), np.empty_like(ws)
            f = self.flicker
            kernel(wf if wf is not None else _EMPTY3, f.phi, f.q, fs,
                   wr if wr is not None else _EMPTY2, self.walk.k * math.sqrt(self.walk.dt),
                   ws, wf is not None, wr is not None, out, new_fs, new_ws)
            return out, (new_fs if wf is not None else fs, new_ws if wr is not None else ws)
        out = np.zeros((m, len(self.axes)))
        if wf is not None:
            x, fs = self.flicker.block_from(fs, wf)
            out += x
        if wr is not None:
            x, ws = self.walk.block_from(ws, wr)
            out += x
        return out, (fs, ws)
