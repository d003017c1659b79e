"""The high-frequency-oscillator voltage UHFO of a laser gyro's light-intensity loop.

Paper 001 §2.1 (Figures 1 and 3): the gain medium of the total-reflection-prism laser gyro is
excited by a 150 MHz oscillator whose supply voltage UHFO is set by the light-intensity control
loop so that the DC light intensity stays constant. Whatever changes the gain or the losses of
the cavity — the temperature of the discharge, the prisms and the gas, and slow changes of the
discharge itself — therefore shows up in UHFO, and the same excitation changes the gyro bias
(Langmuir flow, dispersion): Table 1 finds corr(bias, UHFO) ≈ −0.82, stronger than
corr(bias, T) ≈ 0.71. The model:

    U_true(t) = law(T_discharge, dT/dt, …) + w(t)           [V]   (the loop's true voltage)
    UHFO(t)   = LSB · round((U_true + e) / LSB)              [V]   (what the test software logs)

``law`` is a :class:`rlgsim.sim.sensors.temperature_laws.LawSpec` in volts on the discharge node (default
``<block>.discharge``), one law per gyro (each number a scalar for every gyro or an array with one
value per gyro, as in the gyro's own law tables), ``w`` a first-order Gauss–Markov wander of the discharge
(standard deviation ``wander_v``, correlation time ``wander_tau_s``) — the part of the
excitation that no thermometer sees and that makes UHFO a better regressor than temperature —
``e`` white read-out noise (``noise_v`` per thermal sample) and ``LSB`` the ADC step
(``lsb_v``, 0 = none). The gyro bias law's ``uhfo_<u>_per_v`` term multiplies U_true − U_0 with
U_0 = the law's ``value_v``. When the device is unpowered the oscillator is off: UHFO = 0 and
U_true − U_0 = 0. UHFO is sampled on the thermal grid (it is logged with the temperatures).

Random draws: wander ``generator(seed, unit, "uhfo.wander", axis, b)`` (start:
``"uhfo.wander_start"``, block 0), read-out ``generator(seed, unit, "uhfo.readout", axis, b)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.signal import lfilter

from rlgsim.sim.config import Ctx, check_known_keys, get_float
from rlgsim.sim.rng import block_seed_words, generator, word
from rlgsim.sim.sensors.temperature_laws import Law, LawSpec

#: Keys of ``[uhfo]`` besides the law keys.
OWN_KEYS = ("wander_v", "wander_tau_s", "noise_v", "lsb_v")


@dataclass(frozen=True)
class UhfoModel:
    """Nominal UHFO law + noise (the ``[uhfo]`` preset table). The law is sized per gyro when
    the IMU model is assembled (:meth:`for_axes`); ``*_rel`` are relative 1σ unit spreads."""

    table: Mapping[str, Any]
    ctx: Ctx
    wander_v: float
    wander_tau_s: float
    noise_v: float
    lsb_v: float
    law: LawSpec
    wander_rel: float = 0.0
    noise_rel: float = 0.0

    @classmethod
    def from_config(cls, table: Mapping, ctx: Ctx) -> "UhfoModel":
        """Validate ``[uhfo]``: law keys (unit ``v``: ``value_v``, ``c1_v_per_k`` …, default
        node ``discharge``) plus ``wander_v``, ``wander_tau_s``, ``noise_v``, ``lsb_v``."""
        return cls(table=dict(table), ctx=ctx,
                   wander_v=get_float(table, "wander_v", ctx, 0.0, min=0.0),
                   wander_tau_s=get_float(table, "wander_tau_s", ctx, 3600.0, min=0.0,
                                          min_exclusive=True),
                   noise_v=get_float(table, "noise_v", ctx, 0.0, min=0.0),
                   lsb_v=get_float(table, "lsb_v", ctx, 0.0, min=0.0),
                   law=_law(table, ctx, _components(table)))

    def for_axes(self, n: int) -> "UhfoModel":
        """The model with its law sized for ``n`` gyros."""
        return replace(self, law=_law(self.table, self.ctx, n))

    def with_tolerance(self, table: Mapping | None, ctx: Ctx) -> "UhfoModel":
        """Add a ``[tolerance.uhfo]`` table: law keys (1σ, volts) plus ``wander_rel`` and
        ``noise_rel`` (relative 1σ of the wander and read-out noise)."""
        if not table:
            return self
        check_known_keys(table, [*self.law.tolerance_keys(), "wander_rel", "noise_rel"], ctx)
        law_tol = {k: v for k, v in table.items() if k not in ("wander_rel", "noise_rel")}
        return replace(self, law=self.law.with_tolerance(law_tol, ctx),
                       wander_rel=get_float(table, "wander_rel", ctx, 0.0, min=0.0),
                       noise_rel=get_float(table, "noise_rel", ctx, 0.0, min=0.0))

    def realise(self, draw, axes: Sequence[str], blocks: Sequence[str]) -> "Uhfo":
        """Draw one unit's UHFO channels (``draw`` as in :meth:`LawSpec.realise`)."""
        n = len(axes)
        wander = self.wander_v * np.abs(1.0 + self.wander_rel * draw("uhfo.wander_v", (n,)))
        noise = self.noise_v * np.abs(1.0 + self.noise_rel * draw("uhfo.noise_v", (n,)))
        return Uhfo(law=self.law.realise(draw), axes=tuple(axes), blocks=tuple(blocks),
                    wander_v=wander, wander_tau_s=self.wander_tau_s, noise_v=noise,
                    lsb_v=self.lsb_v)


def _components(table: Mapping) -> int:
    """How many gyros the law's arrays give (1 when every number is a scalar): the table is
    checked on its own here, and against the device's gyro count by :meth:`UhfoModel.for_axes`
    (a law key with another count is then one error naming it)."""
    sizes = [len(v) for k, v in table.items() if k not in OWN_KEYS and isinstance(v, list)
             and k != "gradients"]
    sizes += [len(c) for g in table.get("gradients", []) if isinstance(g, Mapping)
              for c in g.values() if isinstance(c, list)]
    return sizes[0] if sizes else 1


def _law(table: Mapping, ctx: Ctx, n: int) -> LawSpec:
    return LawSpec.from_config(table, ctx, name="uhfo", unit="v", to_si=1.0, n=n,
                               node="discharge", extra_keys=OWN_KEYS)


@dataclass
class Uhfo:
    """One unit's UHFO channels (one per gyro)."""

    law: Law
    axes: tuple[str, ...]
    blocks: tuple[str, ...]
    wander_v: np.ndarray         # (C,) [V]
    wander_tau_s: float
    noise_v: np.ndarray          # (C,) [V]
    lsb_v: float

    @property
    def u0(self) -> np.ndarray:
        """U_0 [V] per gyro: the law's constant term (the deviation the bias law multiplies)."""
        return self.law.coef["value"]

    def bind(self, node_names: Sequence[str]) -> None:
        self.law.bind(self.blocks, node_names)

    def initial_state(self, seed: int, unit: int) -> np.ndarray:
        """Stationary start of the wander (C,) [V]."""
        return np.array([self.wander_v[c] * generator(seed, unit, "uhfo.wander_start", a,
                                                      0).standard_normal()
                         for c, a in enumerate(self.axes)])

    def draws(self, seed: int, unit: int, b: int, m: int, fill: Any = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """Standard-normal drives of block ``b``: wander (C, m) and read-out (C, m); ``fill``
        as :meth:`rlgsim.sim.sensors.noise.SlowNoise.draws`' (one compiled call)."""
        n_ch = len(self.axes)
        base = np.empty((2, n_ch, m))
        if fill is not None:
            keys, views = self._streams(m)
            fill(block_seed_words(seed, unit, keys, b), base, views)
            return base[0], base[1]
        for i, purpose in enumerate(("uhfo.wander", "uhfo.readout")):
            for c, a in enumerate(self.axes):
                base[i, c] = generator(seed, unit, purpose, a, b).standard_normal(m)
        return base[0], base[1]

    def _streams(self, m: int) -> tuple[list[tuple[int, int]], np.ndarray]:
        """The drives' streams of a block of ``m`` steps: their (purpose, channel) words and
        where each one's draws go in :meth:`draws`' base array (offset, n0, s0, n1, s1: row
        ``k`` of the (2·C, m) base), kept per ``m`` as
        :meth:`rlgsim.sim.sensors.noise.SlowNoise._streams` keeps its own."""
        cache = self.__dict__.setdefault("_stream_cache", {})
        if m not in cache:
            keys = [(word(purpose), word(a)) for purpose in ("uhfo.wander", "uhfo.readout")
                    for a in self.axes]
            views = np.array([(k * m, 1, 0, m, 1) for k in range(len(keys))],
                             dtype=np.int64).reshape(-1, 5)
            cache[m] = (keys, views)
        return cache[m]

    def block(self, state: np.ndarray, seed: int, unit: int, b: int, nodes_c: np.ndarray,
              start_c: np.ndarray, dt: float, power: np.ndarray,
              draws: tuple[np.ndarray, np.ndarray] | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(U_true (m, C) [V], UHFO reading (m, C) [V] float32, new wander state (C,));
        ``draws`` from :meth:`draws` (drawn now when None)."""
        m = nodes_c.shape[0]
        w_all, e_all = draws if draws is not None else self.draws(seed, unit, b, m)
        u = self.law.evaluate(nodes_c, start_c, dt)
        phi = math.exp(-dt / self.wander_tau_s)
        new = np.array(state, dtype=float, copy=True)
        if np.any(self.wander_v > 0):            # one recursion for every gyro's wander
            drive = w_all * (self.wander_v * math.sqrt(1.0 - phi * phi))[:, None]
            x, _ = lfilter([1.0], [1.0, -phi], drive, axis=-1, zi=(phi * new)[:, None])
            u += x.T
            new = x[:, -1].copy()
        read = u + (e_all * self.noise_v[:, None]).T
        if self.lsb_v > 0:
            read = np.round(read / self.lsb_v) * self.lsb_v
        on = power[:, None] > 0
        u = np.where(on, u, self.u0[None, :])
        read = np.where(on, read, 0.0)
        return u, read.astype(np.float32), new
