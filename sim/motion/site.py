"""The site: where the turntable stands (geodetic latitude, height above the ellipsoid).

The Earth model itself — WGS-84 normal gravity (Somigliana + free-air correction, NIMA TR8350.2)
and the Earth rate in ENU — lives in :mod:`rlgsim.ground.earth`, shared with the estimators; a
:class:`Site` evaluates it once for its latitude and height and validates a scenario's
``[site]`` table. Navigation frame ENU (x East, y North, z Up); gravity vector
g^n = (0, 0, −γ); the specific force sensed at rest f^n = −g^n = (0, 0, γ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG, earth_rate_enu, normal_gravity
from rlgsim.sim.config import Ctx, check_known_keys, get_float

#: the heights [m] the Earth model is used at: from the deepest ocean trench to the
#: stratospheric balloons (~40 km; U-2 and high-altitude drones fly at ~21 km) — a site, a
#: route's start and every point of a vehicle's route stay inside. Normal gravity's free-air
#: series (NIMA TR8350.2 eq. 4-3) stops at h²; the dropped term, ~−4(h/a)³γ, is 2.3e-6 m/s² at
#: 25 km and 1.9e-5 m/s² (~2 µg) at 50 km, below a navigation-grade accelerometer's bias
MIN_HEIGHT_M, MAX_HEIGHT_M = -11000.0, 50000.0


@dataclass(frozen=True)
class Site:
    """Where the turntable stands: geodetic latitude [°] and height above the ellipsoid [m].

    Default latitude :data:`rlgsim.ground.earth.DEFAULT_LATITUDE_DEG` (docs/design.md).
    Attributes computed once:
    ``earth_rate_enu`` ω_ie^n [rad/s], ``gravity`` γ [m/s²], ``gravity_enu`` g^n = (0, 0, −γ)
    [m/s²] and ``specific_force_enu`` f^n = (0, 0, γ) [m/s²] (at rest on the Earth).
    """

    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = 0.0
    earth_rate_enu: np.ndarray = field(init=False, repr=False, compare=False)
    gravity: float = field(init=False, repr=False, compare=False)
    gravity_enu: np.ndarray = field(init=False, repr=False, compare=False)
    specific_force_enu: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (-90.0 <= self.latitude_deg <= 90.0) or not math.isfinite(self.latitude_deg):
            raise ValueError(f"latitude_deg must be in [-90, 90], got {self.latitude_deg!r}")
        if not (MIN_HEIGHT_M <= self.height_m <= MAX_HEIGHT_M) or not math.isfinite(self.height_m):
            raise ValueError(f"height_m must be in [{MIN_HEIGHT_M:g}, {MAX_HEIGHT_M:g}] m, got "
                             f"{self.height_m!r}")
        w = earth_rate_enu(self.latitude_deg)
        g = normal_gravity(self.latitude_deg, self.height_m)
        for name, value in (("earth_rate_enu", w), ("gravity", g),
                            ("gravity_enu", np.array([0.0, 0.0, -g])),
                            ("specific_force_enu", np.array([0.0, 0.0, g]))):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def from_config(cls, table: Mapping | None, ctx: Ctx) -> "Site":
        """Build from a scenario's ``[site]`` table (keys ``latitude_deg``, ``height_m``).

        A missing table gives the default site (the default latitude, 0 m). Bad values raise
        :class:`~rlgsim.ground.errors.UserInputError` naming file, key and value.
        """
        table = {} if table is None else table
        check_known_keys(table, ("latitude_deg", "height_m"), ctx)
        return cls(latitude_deg=get_float(table, "latitude_deg", ctx, DEFAULT_LATITUDE_DEG,
                                          min=-90.0, max=90.0),
                   height_m=get_float(table, "height_m", ctx, 0.0, min=MIN_HEIGHT_M,
                                       max=MAX_HEIGHT_M))
