"""The controlled heaters' step terms in the modal basis: written once for the thermal
integrator (:class:`rlgsim.sim.thermal.integrator.ThermalIntegrator`, one network) and the
batched twin of the thermal fit (:mod:`rlgsim.lab.identify.batch_twin`, many parameter sets).

With ``S = C^-½ K C^-½ = V Λ Vᵀ`` and the modal state ``w = Vᵀ C^½ T`` (docs/thermal.md §2), a
heater's power ``P`` held over a step (zero-order hold) into node ``i`` adds
``a_u ⊙ Vᵀ[:, i]·C_i^-½ · P`` to ``w`` — ``a_u = (1 − e^{−λh})/λ`` per mode — and its PI
controller reads its sensor node ``T_s = (C^-½ V)[s, :] · w``. The discrete PI law
(docs/thermal.md §1.2b, eq. (H1)): ``v = kp·e + I``, ``P = clip(v, 0, max)``,
``I ← I + ki·e + aw·(P − v)`` with ``ki = kp·h/ti`` and the back-calculation anti-windup gain
``aw = h/ti``; a set point that tracks another node is ``(sp − gain·ref) + gain·T_track``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from rlgsim.sim.thermal.network_parts import Heater

__all__ = ["HeaterTerms", "heater_terms"]


@dataclass(frozen=True)
class HeaterTerms:
    """The step terms of a network's ``H`` controlled heaters (``n`` modes)."""

    #: (n, H) modal input column of each heater per watt held over one step
    cols: np.ndarray
    #: (H, n) row reading each heater's sensor node [°C] from the modal state
    sensor_rows: np.ndarray
    #: (H, n) row reading each heater's tracked node (node 0 where it tracks none)
    track_rows: np.ndarray
    #: (H,) proportional gain [W/K]
    kp: np.ndarray
    #: (H,) integral gain per step ``kp·h/ti`` [W/K]
    ki: np.ndarray
    #: (H,) anti-windup gain per step ``h/ti`` [-]
    aw: np.ndarray
    #: (H,) power limit [W]
    max_power: np.ndarray
    #: (H,) set point less the tracked part, ``sp − gain·ref`` [°C]
    setpoint: np.ndarray
    #: (H,) tracking gain (0 where the set point is fixed) [-]
    track_gain: np.ndarray


def heater_terms(heaters: Sequence[Heater], inv_sqrt_c: np.ndarray, modes: np.ndarray,
                 zoh_weight: np.ndarray, step_s: float) -> HeaterTerms:
    """The :class:`HeaterTerms` of ``heaters`` (non-empty) for a step of ``step_s`` [s]:
    ``inv_sqrt_c`` (n,) is ``C^-½`` [K^½/J^½], ``modes`` (n, n) the eigenvectors ``V`` of ``S``
    (columns), ``zoh_weight`` (n,) each mode's response to a unit input held over the step,
    ``a_u = ∫₀ʰ e^{−λ(h−t)} dt`` [s] (the integrator takes it from each mode's augmented
    exponential, the batched twin from its closed form)."""
    d, V, h = inv_sqrt_c, modes, float(step_s)
    nodes_map = d[:, None] * V                                        # T = nodes_map @ w
    return HeaterTerms(
        cols=np.column_stack([V.T[:, q.node] * d[q.node] * zoh_weight for q in heaters]),
        sensor_rows=np.array([nodes_map[q.sensor] for q in heaters]),
        track_rows=np.array([nodes_map[max(q.track_node, 0)] for q in heaters]),
        kp=np.array([q.kp_w_per_k for q in heaters]),
        ki=np.array([q.kp_w_per_k * h / q.ti_s for q in heaters]),
        aw=np.array([h / q.ti_s for q in heaters]),
        max_power=np.array([q.max_power_w for q in heaters]),
        setpoint=np.array([q.setpoint_c - (q.track_gain * q.track_reference_c
                                           if q.track_node >= 0 else 0.0) for q in heaters]),
        track_gain=np.array([q.track_gain if q.track_node >= 0 else 0.0 for q in heaters]))
