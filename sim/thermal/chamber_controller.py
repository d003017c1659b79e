"""A real temperature chamber: digital PID on a lagged air sensor, heater/cooler limits, ripple.

Optional part of a scenario (``[chamber.controller]``; docs/thermal.md §1.4). Without it the
chamber air is the rate-limited setpoint through a first-order lag (``air_tau_s``). With it the
air is the output of a closed loop, as in a climatic chamber:

* **Working-space air** (air, fins and liner lumped; a loss to the laboratory through the
  insulation)::

      dT_a/dt = q(t) + d(t) − (T_a − T_lab)/τ_loss                                     (C1)

  ``q`` [K/s] the net conditioning (heater > 0, refrigeration < 0) expressed as the rate it
  gives the empty working space, limited to ``[−q_cool(T_a), +q_heat]``
  (``max_cooling_c_per_min``, ``max_heating_c_per_min``). The refrigeration capacity falls
  as the evaporating temperature drops, taken linear in the air temperature:
  ``q_cool(T_a) = q_cool · clip((T_a − T_0)/(T_lab − T_0), 0, 1)`` (full capacity at and above
  the laboratory temperature), with ``T_0`` such that at the lowest temperature the chamber
  can hold, ``min_temperature_c`` (its datasheet range: about −40 … −55 °C for single-stage,
  −70 °C for cascade refrigeration), the remaining capacity just balances the insulation
  loss. The rate the chamber can really reach is therefore ``q_heat − (T_a − T_lab)/τ_loss``
  heating and ``q_cool(T_a) + (T_a − T_lab)/τ_loss`` cooling — lower near the hot and cold
  extremes, and zero at ``min_temperature_c``.
* **Refrigeration cycling** ``d(t) = D sin(2π t/P)`` [K/s]: the periodic part of the
  conditioning that the controller cannot reject (compressor / hot-gas-bypass / expansion-valve
  cycling). ``D`` is not a user key: it is computed so that the closed loop's air fluctuation at
  a constant setpoint has the peak amplitude ``ripple_amplitude_c`` at period
  ``ripple_period_s`` — the figure chamber datasheets give ("temperature fluctuation", defined
  as the variation over time at one point of the working space once stable; IEC 60068-3-5
  guidance; vendors quote ±0.1 … ±0.5 K).
* **Control sensor** (Pt100 in the air stream, first-order lag; IEC 60068-3-5 measurement
  guidance asks for 10–40 s 50 % response in air)::

      τ_s dT_s/dt = T_a − T_s                                                           (C2)

  The controller reads it as ``y_k = Q(T_s(t_k) + σ_y w_k)``: white read-out noise
  ``sensor_noise_c`` (1σ per sample) and the reading's quantisation ``Q`` to multiples of
  ``sensor_resolution_c`` (round to nearest). Both default to 0 (off).
* **The loop's own noise**: the conditioning delivered over a sample is the commanded one plus
  ``σ_q w'_k`` (``conditioning_noise_c_per_min``, 1σ, held over the sample) — the irregular
  part of heater and refrigeration output (relay/valve timing, airflow), which the controller
  must reject like any disturbance. Default 0 (off). ``w``, ``w'`` are standard normal draws
  of the run's random tree, keyed by the 600-s block, so splitting a run never changes them.
  With either noise on, the air at a constant setpoint hunts around the sinusoid instead of
  repeating it.

* **Digital PID** with sample period ``h_c`` (``sample_s``, rounded so that a whole number of
  periods fits in a thermal step), output held between samples (zero-order hold), derivative
  on the measurement with a first-order filter (``N = 10``) and back-calculation anti-windup
  (Åström & Hägglund, *Advanced PID Control*, ISA 2006, §3.4–3.5)::

      e_k = r_k − y_k,   y_k = T_s(t_k),   r_k = rate-limited setpoint at t_k
      D_k = Td/(Td + N h_c) · D_{k−1} − Kp Td N/(Td + N h_c) · (y_k − y_{k−1})
      v_k = Kp e_k + I_k + D_k,          u_k = clip(v_k, −q_cool, q_heat)
      I_{k+1} = I_k + Kp h_c/Ti · e_k + h_c/Tt · (u_k − v_k),   Tt = Ti              (C3)

  Default gains: the SIMC rules for an integrating process with effective delay
  ``θ = τ_s + h_c/2`` (the sensor lag taken as delay; Skogestad, J. Process Control 13 (2003)
  291, Table 1 with τ_c = θ): ``Kp = 1/(2θ)`` [1/s], ``Ti = 8θ``, ``Td = 0``. With an
  integrating plant and integral action the loop tracks a ramp without steady error, so the
  integral term holds the ramp rate and **overshoots at the end of every ramp**; a ramp faster
  than the heater/cooler allows **saturates** and falls behind; the refrigeration cycling gives
  the **ripple** at constant setpoint.

Integration. Between controller samples ``q`` is constant and ``d`` a sinusoid, so (C1)–(C2)
form a linear system with an exactly known input: it is advanced with the matrix exponential of
the augmented system ``[T_a, T_s, cos, sin, q, T_lab]`` (Van Loan), computed once. The only
nonlinearity, the clip in (C3), acts at the samples. The result is therefore exact for the
sampled-data loop (tested against ``scipy.integrate.solve_ivp``). The loop is a scalar
recurrence (each sample depends on the clip of the previous), run in plain Python floats: about
2–3 µs per controller sample. The carried state is
``[T_a, T_s, I, D, y_prev, cos, sin]``; the chamber air is not heated by the device (a few W
against the chamber's kW).

Why this file is over 400 lines: the controller's keys, its discretisation and its two recurrences (the
plain one and the noisy copy kept apart so that the plain loop's speed is unchanged) are one
model; split, each would read the other's coefficients.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

import numpy as np
import scipy.linalg

from rlgsim.sim.config import Ctx, check_known_keys, get_float

#: Derivative filter factor N of the PID (Åström & Hägglund 2006: 8–20).
DERIVATIVE_FILTER_N = 10.0

KEYS = ("sensor_tau_s", "sample_s", "kp_per_s", "ti_s", "td_s", "max_heating_c_per_min",
        "max_cooling_c_per_min", "loss_tau_s", "lab_c", "ripple_amplitude_c",
        "ripple_period_s", "min_temperature_c", "sensor_noise_c", "sensor_resolution_c",
        "conditioning_noise_c_per_min")

#: Defaults (docs/thermal.md §1.4 says where each comes from).
DEFAULTS = {
    "sensor_tau_s": 15.0,            # Pt100 in the air stream (10–40 s 50 % response)
    "sample_s": 1.0,                 # controller period of a climatic-chamber controller
    "max_heating_c_per_min": 6.0,    # heater authority (empty working space)
    "max_cooling_c_per_min": 5.0,    # refrigeration authority (empty working space)
    "loss_tau_s": 3600.0,            # insulation: working space to laboratory
    "lab_c": 23.0,                   # laboratory temperature
    "ripple_amplitude_c": 0.3,       # datasheet "temperature fluctuation" ±0.1…±0.5 K
    "ripple_period_s": 600.0,        # refrigeration cycling period (assumed)
    "min_temperature_c": -70.0,      # lowest temperature of a cascade refrigeration system
    "sensor_noise_c": 0.0,           # control reading's white noise, 1σ per sample (off)
    "sensor_resolution_c": 0.0,      # control reading's quantisation step (off)
    "conditioning_noise_c_per_min": 0.0,   # irregular heater/refrigeration output, 1σ (off)
}


@dataclass(frozen=True)
class ChamberController:
    """Parameters of the chamber's air loop (SI inside; see the module docstring): the
    controller ``kind = "pid"`` of :data:`rlgsim.sim.thermal.chamber_controllers.CONTROLLERS`."""

    kind: ClassVar[str] = "pid"

    sensor_tau_s: float = DEFAULTS["sensor_tau_s"]
    sample_s: float = DEFAULTS["sample_s"]
    kp_per_s: float | None = None
    ti_s: float | None = None
    td_s: float = 0.0
    max_heating_c_per_min: float = DEFAULTS["max_heating_c_per_min"]
    max_cooling_c_per_min: float = DEFAULTS["max_cooling_c_per_min"]
    loss_tau_s: float = DEFAULTS["loss_tau_s"]
    lab_c: float = DEFAULTS["lab_c"]
    ripple_amplitude_c: float = DEFAULTS["ripple_amplitude_c"]
    ripple_period_s: float = DEFAULTS["ripple_period_s"]
    min_temperature_c: float = DEFAULTS["min_temperature_c"]
    sensor_noise_c: float = DEFAULTS["sensor_noise_c"]
    sensor_resolution_c: float = DEFAULTS["sensor_resolution_c"]
    conditioning_noise_c_per_min: float = DEFAULTS["conditioning_noise_c_per_min"]

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "ChamberController":
        """Build from a ``[chamber.controller]`` table (every key optional)."""
        check_known_keys(table, KEYS, ctx)
        kw: dict[str, Any] = {}
        kw["sensor_tau_s"] = get_float(table, "sensor_tau_s", ctx, DEFAULTS["sensor_tau_s"],
                                       min=0.1, max=3600.0)
        kw["sample_s"] = get_float(table, "sample_s", ctx, DEFAULTS["sample_s"], min=0.01,
                                   max=600.0)
        kw["kp_per_s"] = get_float(table, "kp_per_s", ctx, None, min=0.0, min_exclusive=True,
                                   max=100.0)
        kw["ti_s"] = get_float(table, "ti_s", ctx, None, min=0.0, min_exclusive=True,
                               max=1e6)
        kw["td_s"] = get_float(table, "td_s", ctx, 0.0, min=0.0, max=1e5)
        kw["max_heating_c_per_min"] = get_float(
            table, "max_heating_c_per_min", ctx, DEFAULTS["max_heating_c_per_min"], min=0.0,
            min_exclusive=True, max=1000.0)
        kw["max_cooling_c_per_min"] = get_float(
            table, "max_cooling_c_per_min", ctx, DEFAULTS["max_cooling_c_per_min"], min=0.0,
            min_exclusive=True, max=1000.0)
        kw["loss_tau_s"] = get_float(table, "loss_tau_s", ctx, DEFAULTS["loss_tau_s"],
                                     min=10.0, max=1e7)
        kw["lab_c"] = get_float(table, "lab_c", ctx, DEFAULTS["lab_c"], min=-50.0, max=60.0)
        kw["ripple_amplitude_c"] = get_float(table, "ripple_amplitude_c", ctx,
                                             DEFAULTS["ripple_amplitude_c"], min=0.0, max=10.0)
        kw["ripple_period_s"] = get_float(table, "ripple_period_s", ctx,
                                          DEFAULTS["ripple_period_s"], min=10.0, max=86400.0)
        kw["min_temperature_c"] = get_float(table, "min_temperature_c", ctx,
                                            DEFAULTS["min_temperature_c"], min=-200.0,
                                            max=kw["lab_c"] - 1.0)
        for key in ("sensor_noise_c", "sensor_resolution_c"):
            kw[key] = get_float(table, key, ctx, DEFAULTS[key], min=0.0, max=10.0)
        kw["conditioning_noise_c_per_min"] = get_float(
            table, "conditioning_noise_c_per_min", ctx, DEFAULTS["conditioning_noise_c_per_min"],
            min=0.0, max=100.0)
        c = cls(**kw)
        need = (c.lab_c - c.min_temperature_c) / (c.loss_tau_s * c.max_cooling_c_per_min / 60.0)
        if need >= 1.0:
            raise ctx.error("min_temperature_c",
                            f"value {c.min_temperature_c:g} not reachable: holding it takes "
                            f"{need * c.max_cooling_c_per_min:.3g} K/min of cooling against "
                            f"the insulation loss (loss_tau_s), more than "
                            f"max_cooling_c_per_min = {c.max_cooling_c_per_min:g}")
        return c

    def loop(self, step_s: float) -> "ChamberLoop":
        """The controller discretised on a thermal grid of ``step_s`` [s]."""
        return ChamberLoop(self, step_s)


class ChamberLoop:
    """The chamber controller discretised on a thermal grid of ``step_s`` [s].

    :meth:`run` advances the loop over one block given the rate-limited setpoint at the thermal
    grid points and returns the chamber air at the grid points; the state is a plain tuple of
    floats ``(T_a, T_s, I, D, y_prev, cos, sin)`` so splitting a run into blocks is
    bit-identical.
    """

    def __init__(self, controller: ChamberController, step_s: float) -> None:
        c = controller
        self.controller = c
        self.step_s = float(step_s)
        self.n_sub = max(1, int(round(self.step_s / c.sample_s)))
        h = self.step_s / self.n_sub
        self.h = h
        theta = c.sensor_tau_s + h / 2.0
        self.kp = c.kp_per_s if c.kp_per_s is not None else 1.0 / (2.0 * theta)
        self.ti = c.ti_s if c.ti_s is not None else 8.0 * theta
        self.td = c.td_s
        self.q_heat = c.max_heating_c_per_min / 60.0
        self.q_cool = c.max_cooling_c_per_min / 60.0
        # refrigeration capacity zero at T_0: q_cool (T_min − T_0)/(T_lab − T_0) = loss(T_min)
        need = (c.lab_c - c.min_temperature_c) / (c.loss_tau_s * self.q_cool)
        if need >= 1.0:
            raise ValueError("the refrigeration cannot hold min_temperature_c against the "
                             "insulation loss")
        self.t_zero_c = (c.min_temperature_c - need * c.lab_c) / (1.0 - need)
        self.omega = 2.0 * math.pi / c.ripple_period_s
        N = DERIVATIVE_FILTER_N
        self.d_a = self.td / (self.td + N * h) if self.td > 0 else 0.0
        self.d_b = self.kp * self.td * N / (self.td + N * h) if self.td > 0 else 0.0
        self.i_e = self.kp * h / self.ti
        self.i_aw = h / self.ti
        # plant over one controller period: augmented [T_a, T_s, cos, sin, q, T_lab]
        M = np.zeros((6, 6))
        M[0, 0] = -1.0 / c.loss_tau_s
        M[0, 3] = 1.0                       # d = D·sin (D applied below)
        M[0, 4] = 1.0
        M[0, 5] = 1.0 / c.loss_tau_s
        M[1, 0] = 1.0 / c.sensor_tau_s
        M[1, 1] = -1.0 / c.sensor_tau_s
        M[2, 3] = -self.omega
        M[3, 2] = self.omega
        E = scipy.linalg.expm(M * h)
        self._E = E
        self.ripple_gain_per_k_per_s = self._ripple_gain()
        self.d_amp = (c.ripple_amplitude_c / self.ripple_gain_per_k_per_s
                      if c.ripple_amplitude_c > 0 else 0.0)
        # coefficients as Python floats (the loop runs on scalars)
        f = lambda x: float(x)                                     # noqa: E731
        self._paa, self._pas = f(E[0, 0]), f(E[0, 1])
        self._psa, self._pss = f(E[1, 0]), f(E[1, 1])
        self._pac = f(E[0, 2] * self.d_amp)
        self._pas_ = f(E[0, 3] * self.d_amp)
        self._psc = f(E[1, 2] * self.d_amp)
        self._pss_ = f(E[1, 3] * self.d_amp)
        self._pau, self._psu = f(E[0, 4]), f(E[1, 4])
        self._pal, self._psl = f(E[0, 5] * c.lab_c), f(E[1, 5] * c.lab_c)
        self._rcc, self._rcs = f(E[2, 2]), f(E[2, 3])
        self._rsc, self._rss = f(E[3, 2]), f(E[3, 3])
        #: read-out noise [K], quantisation step [K], conditioning noise [K/s] (0: off)
        self.sensor_noise = float(c.sensor_noise_c)
        self.resolution = float(c.sensor_resolution_c)
        self.conditioning_noise = float(c.conditioning_noise_c_per_min) / 60.0
        #: standard normal draws per controller sample the loop needs (0: deterministic)
        self.noise_channels = 2 if (self.sensor_noise > 0 or self.conditioning_noise > 0) else 0

    # ----------------------------------------------------------------- linear analysis

    def _linear_maps(self, E: np.ndarray, d_amp: float) -> tuple[np.ndarray, np.ndarray]:
        """The unsaturated closed loop over one controller period as ``z+ = A z + B o`` with
        ``z = [T_a, T_s, I, D, y_prev]`` (setpoint and laboratory at 0) and ``o = [cos, sin]``.
        Built from the same update equations as :meth:`run`."""
        def step(z: np.ndarray, o: np.ndarray) -> np.ndarray:
            ta, ts, i, d, yp = z
            y = ts
            d = self.d_a * d - self.d_b * (y - yp)
            e = -y
            v = self.kp * e + i + d
            u = v
            ta_n = E[0, 0] * ta + E[0, 1] * ts + E[0, 4] * u + d_amp * (E[0, 2] * o[0]
                                                                        + E[0, 3] * o[1])
            ts_n = E[1, 0] * ta + E[1, 1] * ts + E[1, 4] * u + d_amp * (E[1, 2] * o[0]
                                                                        + E[1, 3] * o[1])
            i_n = i + self.i_e * e
            return np.array([ta_n, ts_n, i_n, d, y])
        A = np.column_stack([step(np.eye(5)[j], np.zeros(2)) for j in range(5)])
        B = np.column_stack([step(np.zeros(5), np.eye(2)[j]) for j in range(2)])
        return A, B

    def _periodic(self, d_amp: float) -> np.ndarray:
        """``X`` (5, 2) with ``z_k = X o_k`` the periodic steady state of the unsaturated loop
        driven by the ripple (Sylvester equation ``X R = A X + B``)."""
        A, B = self._linear_maps(self._E, d_amp)
        if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
            raise ValueError("the chamber loop is unstable with these gains")
        R = self._E[2:4, 2:4]
        # A X − X R = −B
        return scipy.linalg.solve_sylvester(A, -R, -B)

    def _ripple_gain(self) -> float:
        """Peak air fluctuation [K] per unit amplitude of ``d`` [K/s] in closed loop."""
        X = self._periodic(1.0)
        return float(np.hypot(X[0, 0], X[0, 1]))

    # ----------------------------------------------------------------- states

    def initial_state(self, setpoint_c: float) -> tuple[float, ...]:
        """The loop settled at ``setpoint_c`` [°C] in its periodic (ripple) steady state at
        phase 0 (``t = 0``)."""
        r = float(setpoint_c)
        hold = (r - self.controller.lab_c) / self.controller.loss_tau_s
        z = np.array([r, r, hold, 0.0, r])
        if self.d_amp > 0:
            X = self._periodic(self.d_amp)
            z = z + X @ np.array([1.0, 0.0])
        # d = D·sin(ωt): oscillator (cos, sin) = (1, 0) at t = 0
        return (float(z[0]), float(z[1]), float(z[2]), float(z[3]), float(z[4]), 1.0, 0.0)

    # ----------------------------------------------------------------- the loop

    def run(self, state: tuple[float, ...], setpoint_c: np.ndarray,
            noise: np.ndarray | None = None) -> tuple[np.ndarray, tuple[float, ...]]:
        """Advance ``m = len(setpoint_c) − 1`` thermal steps.

        ``setpoint_c`` (m+1,) rate-limited setpoint at the thermal grid points (linear in
        between, sampled at every controller instant). ``noise`` (m·n_sub, 2): standard normal
        draws per controller sample for the read-out and the conditioning noise (used only when
        :attr:`noise_channels` > 0; None: no noise). Returns the chamber air (m,) at the
        grid points ``t0 + h … t0 + m·h`` and the new state.
        """
        s = np.asarray(setpoint_c, dtype=float).reshape(-1)
        m = s.size - 1
        out = np.empty(max(m, 0))
        if m <= 0:
            return out, tuple(state)
        n = self.n_sub
        if n == 1:
            r_all = s[:-1].tolist()
        else:
            frac = np.arange(n) / n
            r_all = (s[:-1, None] + (s[1:, None] - s[:-1, None]) * frac[None, :]).reshape(-1)
            r_all = r_all.tolist()
        if self.resolution > 0 or (self.noise_channels and noise is not None):
            return self._run_noisy(state, r_all, out, noise)
        ta, ts, i, d, yp, oc, os_ = (float(v) for v in state)
        kp, i_e, i_aw, d_a, d_b = self.kp, self.i_e, self.i_aw, self.d_a, self.d_b
        qh, qc0 = self.q_heat, self.q_cool
        tmin = self.t_zero_c
        span = self.controller.lab_c - tmin
        paa, pas, psa, pss = self._paa, self._pas, self._psa, self._pss
        pac, pas_, psc, pss_ = self._pac, self._pas_, self._psc, self._pss_
        pau, psu, pal, psl = self._pau, self._psu, self._pal, self._psl
        rcc, rcs, rsc, rss = self._rcc, self._rcs, self._rsc, self._rss
        k = 0
        for j, r in enumerate(r_all):
            y = ts
            d = d_a * d - d_b * (y - yp)
            e = r - y
            v = kp * e + i + d
            f = (ta - tmin) / span                  # refrigeration capacity left at T_a
            qc = -qc0 * (1.0 if f >= 1.0 else (f if f > 0.0 else 0.0))
            u = qh if v > qh else (qc if v < qc else v)
            ta, ts = (paa * ta + pas * ts + pau * u + pac * oc + pas_ * os_ + pal,
                      psa * ta + pss * ts + psu * u + psc * oc + pss_ * os_ + psl)
            oc, os_ = rcc * oc + rcs * os_, rsc * oc + rss * os_
            i = i + i_e * e + i_aw * (u - v)
            yp = y
            if (j + 1) % n == 0:
                out[k] = ta
                k += 1
        return out, (ta, ts, i, d, yp, oc, os_)

    def _run_noisy(self, state: tuple[float, ...], r_all: list, out: np.ndarray,
                   noise: np.ndarray | None) -> tuple[np.ndarray, tuple[float, ...]]:
        """:meth:`run` with the read-out noise and quantisation and the conditioning noise
        (module docstring); the same recurrence, kept apart so that the plain loop stays as
        fast as before."""
        n = self.n_sub
        if noise is None:
            w_y = w_q = [0.0] * len(r_all)
        else:
            w = np.asarray(noise, dtype=float)
            if w.shape != (len(r_all), 2):
                raise ValueError(f"noise needs shape ({len(r_all)}, 2), got {w.shape}")
            w_y = (w[:, 0] * self.sensor_noise).tolist()
            w_q = (w[:, 1] * self.conditioning_noise).tolist()
        lsb = self.resolution
        ta, ts, i, d, yp, oc, os_ = (float(v) for v in state)
        kp, i_e, i_aw, d_a, d_b = self.kp, self.i_e, self.i_aw, self.d_a, self.d_b
        qh, qc0 = self.q_heat, self.q_cool
        tmin = self.t_zero_c
        span = self.controller.lab_c - tmin
        paa, pas, psa, pss = self._paa, self._pas, self._psa, self._pss
        pac, pas_, psc, pss_ = self._pac, self._pas_, self._psc, self._pss_
        pau, psu, pal, psl = self._pau, self._psu, self._pal, self._psl
        rcc, rcs, rsc, rss = self._rcc, self._rcs, self._rsc, self._rss
        k = 0
        for j, r in enumerate(r_all):
            y = ts + w_y[j]
            if lsb > 0:
                y = round(y / lsb) * lsb
            d = d_a * d - d_b * (y - yp)
            e = r - y
            v = kp * e + i + d
            f = (ta - tmin) / span                  # refrigeration capacity left at T_a
            qc = -qc0 * (1.0 if f >= 1.0 else (f if f > 0.0 else 0.0))
            u = qh if v > qh else (qc if v < qc else v)
            ua = u + w_q[j]                         # what the conditioning really delivers
            ta, ts = (paa * ta + pas * ts + pau * ua + pac * oc + pas_ * os_ + pal,
                      psa * ta + pss * ts + psu * ua + psc * oc + pss_ * os_ + psl)
            oc, os_ = rcc * oc + rcs * os_, rsc * oc + rss * os_
            i = i + i_e * e + i_aw * (u - v)
            yp = y
            if (j + 1) % n == 0:
                out[k] = ta
                k += 1
        return out, (ta, ts, i, d, yp, oc, os_)

    def conditioning(self, state: tuple[float, ...], setpoint_c: float) -> float:
        """The unclipped controller output ``v`` [K/s] for the next sample (diagnostics)."""
        ta, ts, i, d, yp, oc, os_ = state
        d = self.d_a * d - self.d_b * (ts - yp)
        return self.kp * (setpoint_c - ts) + i + d
