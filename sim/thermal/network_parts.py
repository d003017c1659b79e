"""The elements of a thermal network besides its nodes and linear links: controlled heaters,
the nonlinear parts of links (exact radiation, natural convection), further boundaries with
prescribed temperatures, the unit-to-unit tolerances and bulk materials; the physical constants
they use (docs/thermal.md §1.2b-c). :class:`rlgsim.sim.thermal.network.ThermalNetwork` holds
them; :mod:`rlgsim.sim.thermal.network_builder` reads them from a preset."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["STEFAN_BOLTZMANN", "ZERO_C_K", "CHAMBER_AIR", "Heater", "NonlinearLink", "Boundary",
           "Tolerance", "Material", "nonlinear_flow_w"]


#: Stefan–Boltzmann constant [W/(m²·K⁴)] (CODATA 2018, exact).
STEFAN_BOLTZMANN = 5.670374419e-8
#: 0 °C in kelvin.
ZERO_C_K = 273.15
#: The reserved name of the chamber air node (integrator state column 0).
CHAMBER_AIR = "chamber_air"


@dataclass(frozen=True)
class Heater:
    """A controlled heater (state-dependent heat source): a digital PI controller, sampled on
    the thermal grid, drives ``power ∈ [0, max_power_w]`` into ``node`` to hold the
    temperature of ``sensor`` at ``setpoint_c + track_gain·(T_track − track_reference_c)``
    (``track_node`` optional: a set point that follows another node, as the
    frequency-stabilisation heater of paper 001 §2.1 follows the cavity). Works only while the
    device is powered. Equations: docs/thermal.md §1.2b."""

    name: str
    node: int
    sensor: int
    setpoint_c: float
    max_power_w: float
    kp_w_per_k: float
    ti_s: float
    track_node: int = -1
    track_gain: float = 0.0
    track_reference_c: float = 0.0


@dataclass(frozen=True)
class NonlinearLink:
    """The part of a link's heat flow that the linear conductance does not carry.

    ``kind = "radiation"``: ``q = c·(T_a⁴ − T_b⁴)`` [K in kelvin], ``c = ε σ A``, of which
    ``4 c T_ref³ (T_a − T_b)`` is in the network's conductances; ``kind = "convection"``
    (natural convection): ``q = h_ref A (|ΔT|/ΔT_ref)^n ΔT``, of which ``h_ref A ΔT`` is in the
    conductances. ``a`` is a node index; ``b`` a node index, ``-1`` the chamber air or
    ``-2 − j`` boundary ``j``. docs/thermal.md §1.2c."""

    a: int
    b: int
    kind: str
    coefficient: float        # c = εσA [W/K⁴] or h_ref·A [W/K]
    linear_w_per_k: float     # the part already in the conductances [W/K]
    reference_dt_k: float = 1.0
    exponent: float = 0.25


@dataclass(frozen=True)
class Boundary:
    """A second boundary of the network (beside the chamber air) with a prescribed
    temperature ``temperature_c + amplitude_c·sin(2π t/period + phase)`` [°C] — e.g. the
    laboratory seen through the turntable shaft, with its air-conditioning or daily cycle.
    Sampled on the thermal grid and linear in between (the integrator's first-order hold)."""

    name: str
    temperature_c: float
    amplitude_c: float = 0.0
    period_s: float = 86400.0
    phase_rad: float = 0.0

    def __call__(self, t_s: Any) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        if self.amplitude_c == 0.0:
            return np.full(t.shape, self.temperature_c)
        return self.temperature_c + self.amplitude_c * np.sin(
            2.0 * np.pi * t / self.period_s + self.phase_rad)


@dataclass(frozen=True)
class Tolerance:
    """Relative 1-σ unit-to-unit spreads (log-normal factors ``exp(σ·N(0,1))``)."""

    capacitance_rel: float = 0.0
    conductance_rel: float = 0.0
    ambient_conductance_rel: float = 0.0
    power_rel: float = 0.0
    heater_setpoint_k: float = 0.0      # 1σ offset of a heater's set point [K] (sensor, trim)


@dataclass(frozen=True)
class Material:
    """Bulk thermal properties: density [kg/m³], specific heat [J/(kg·K)], conductivity [W/(m·K)]."""

    name: str
    density_kg_per_m3: float
    specific_heat_j_per_kg_k: float
    conductivity_w_per_m_k: float | None = None


def nonlinear_flow_w(link: NonlinearLink, ta: Any, tb: Any) -> np.ndarray:
    """Heat [W] from end ``a`` to end ``b`` carried by the nonlinear part of ``link``
    (temperatures in °C)."""
    ta = np.asarray(ta, dtype=float)
    tb = np.asarray(tb, dtype=float)
    d = ta - tb
    if link.kind == "radiation":
        full = link.coefficient * ((ta + ZERO_C_K) ** 4 - (tb + ZERO_C_K) ** 4)
    else:
        full = link.coefficient * (np.abs(d) / link.reference_dt_k) ** link.exponent * d
    return full - link.linear_w_per_k * d
