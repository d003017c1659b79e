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

from rlgsim.ground.errors import UserInputError
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
        with np.errstate(over="ignore"):          # inf: refused by check_step
            return np.cbrt(1.0 + (u / self.film_speed_m_s) ** (3.0 * self.film_exponent))

    def check_step(self, film: np.ndarray, speed_m_s: np.ndarray, rate_per_step: float,
                   source: str, step_s: float) -> None:
        """Refuse (one :class:`~rlgsim.ground.errors.UserInputError` line) airflow so strong
        that the residual heat held over a thermal step overshoots the bay's air: for a node
        with the fraction κ = 1 − exp(−g_i Δt/C_i) of its deviation from the air relaxed per
        still-air step, the held term (φ − 1)·g_i·(T_air − T_i) moves it by (φ − 1)·κ of that
        deviation, so the node would cross the air temperature (and oscillate, diverging past
        1 + e^(−g_i Δt/C_i)) once (φ − 1)·κ ≥ 1 — a one-node bound, applied with the largest κ
        of the network (``rate_per_step``). ``film`` = φ − 1 at ``speed_m_s``."""
        worst = int(np.argmax(np.where(np.isfinite(film), film, np.inf)))
        if np.isfinite(film[worst]) and film[worst] * rate_per_step < 1.0:
            return
        raise UserInputError(
            f"{source}: vehicle_bay: the airflow scales the bay's film coefficients by "
            f"{film[worst] + 1.0:.4g} at {speed_m_s[worst]:.4g} m/s, too strong for a "
            f"{step_s:g}-s thermal step (the held airflow heat would carry a node past the "
            f"air: needs (φ − 1)·{rate_per_step:.3g} < 1); lower airflow_fraction or "
            f"film_exponent, raise film_speed_m_s, or shorten [acquisition] thermal_step_s")

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "VehicleBay":
        """Validate a scenario's ``[vehicle_bay]`` table."""
        check_known_keys(table, KEYS, ctx)
        return cls(get_float(table, "airflow_fraction", ctx, 0.1, min=0.0, max=1.0),
                   get_float(table, "film_speed_m_s", ctx, 0.5, min=0.0, min_exclusive=True),
                   get_float(table, "film_exponent", ctx, 0.8, min=0.0, min_exclusive=True,
                             max=2.0))    # n = 0: a constant (u/u_eq)^0 = 1, φ ≠ 1 at rest
