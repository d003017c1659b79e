"""The airflow in a vehicle's equipment bay: film coefficients that grow with the speed.

On a vehicle (``[trajectory]``, docs/trajectories.md) the chamber programme is the air of the
IMU's bay; ``[vehicle_bay]`` adds the airflow over the unit. The thermal preset's ambient
conductances g_i describe the unit in still air (natural convection, a parked vehicle); moving,
a fraction ``airflow_fraction`` of the ground speed v blows through the bay, u = a·v, and the
film coefficient of forced convection over a plate grows as u^n (turbulent flat plate,
Nu ∝ Re^0.8: Incropera & DeWitt, *Fundamentals of Heat and Mass Transfer*, 6th ed., eq. 7.36).
Natural and forced convection combine as h = (h_N³ + h_F³)^(1/3) (Churchill & Usagi's blend
for mixed convection, Incropera & DeWitt eq. 9.66). With h_F = h_N at u = u_eq
(``film_speed_m_s``), every ambient conductance is scaled by

    φ(v) = (1 + (a·v/u_eq)^(3n))^(1/3)        (φ = 1 at rest)

The three numbers are **judgements** — no source gives a bay's airflow: by default a tenth of
the ground speed reaches the unit (a = 0.1, ducted cooling air is slower than the free stream),
forced convection matches the still-air film at u_eq = 0.5 m/s (typical natural-convection
films of 3–6 W/(m²·K) against forced ones of 10–25 W/(m²·K) at 1–3 m/s), n = 0.8.

The integrator (:mod:`rlgsim.sim.thermal.integrator`) keeps its exact propagation of the
still-air network and adds the airflow's residual heat (φ − 1)·g_i·(T_air − T_i), evaluated at
each grid point and held over the step (exponential Euler; its error is of order
Δt·(φ − 1)·g_i/C_i, a fraction of a per cent of the residual at the 1 s step for the presets'
time constants of minutes; tests/test_vehicle_bay.py checks it against the exact propagation
of the scaled network).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rlgsim.sim.config import Ctx, check_known_keys, get_float

KEYS = ("airflow_fraction", "film_speed_m_s", "film_exponent")


@dataclass(frozen=True)
class VehicleBay:
    """A bay's airflow: ``airflow_fraction`` a [-], ``film_speed_m_s`` u_eq [m/s],
    ``film_exponent`` n [-] (module docstring)."""

    airflow_fraction: float = 0.1
    film_speed_m_s: float = 0.5
    film_exponent: float = 0.8

    def factor(self, speed_m_s: Any) -> np.ndarray:
        """φ(v): the scaling of every ambient conductance at ground speeds ``speed_m_s``."""
        u = self.airflow_fraction * np.abs(np.asarray(speed_m_s, dtype=float))
        return np.cbrt(1.0 + (u / self.film_speed_m_s) ** (3.0 * self.film_exponent))

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "VehicleBay":
        """Validate a scenario's ``[vehicle_bay]`` table."""
        check_known_keys(table, KEYS, ctx)
        return cls(get_float(table, "airflow_fraction", ctx, 0.1, min=0.0, max=1.0),
                   get_float(table, "film_speed_m_s", ctx, 0.5, min=0.0, min_exclusive=True),
                   get_float(table, "film_exponent", ctx, 0.8, min=0.0, max=2.0))
