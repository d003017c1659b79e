"""The Earth at the turntable's site: WGS-84 normal gravity and the Earth rate in ENU.

Navigation frame ENU (x East, y North, z Up), fixed to the Earth at the site. The turntable does
not move over the Earth, so the transport rate is zero and the only rotation of the navigation
frame with respect to inertial space is the Earth's:

    ω_ie^n = (0, Ω cos L, Ω sin L)                                           [rad/s]

with Ω = 7.292115e-5 rad/s (WGS-84, :data:`rlgsim.ground.units.EARTH_RATE`) and L the geodetic
latitude (Titterton & Weston, *Strapdown Inertial Navigation Technology*, 2nd ed., §3.4.3).

Normal gravity (gravitation plus centrifugal acceleration of the rotating Earth, which is what a
static accelerometer senses) on the ellipsoid follows the closed Somigliana formula with the
WGS-84 constants (NIMA TR8350.2, 3rd ed. 2000, eq. 4-1):

    γ_0(L) = γ_e (1 + k sin²L) / sqrt(1 − e² sin²L)

and above the ellipsoid the second-order free-air correction (NIMA TR8350.2 eq. 4-3):

    γ(L, h) = γ_0 [1 − 2/a (1 + f + m − 2 f sin²L) h + 3 h²/a²]

The plumb line is taken along −Up (the deflection of the vertical, a few arcseconds, is ignored),
so the gravity vector in ENU is g^n = (0, 0, −γ) and the specific force sensed by an IMU at rest
on the table is f^n = −g^n = (0, 0, γ).

Away from the fixed site (the navigator, :mod:`rlgsim.estimators.ins`) the local-level frame
moves over the ellipsoid; its radii of curvature (Groves, *Principles of GNSS, Inertial and
Multisensor Integrated Navigation Systems*, 2nd ed. 2013, eqs. 2.105–2.106; Titterton & Weston
eqs. 3.83–3.84) are

    R_M(L) = a (1 − e²) / (1 − e² sin²L)^{3/2}      meridian (north–south)
    R_E(L) = a / sqrt(1 − e² sin²L)                 transverse (east–west, prime vertical)

and the transport rate of the ENU frame for a velocity v^n = (v_E, v_N, v_U) at height h is
(Titterton & Weston eq. 3.87 written in ENU)

    ω_en^n = (−v_N/(R_M + h), v_E/(R_E + h), v_E tan L/(R_E + h))              [rad/s]

Both sides use these functions: the simulator's site (:class:`rlgsim.sim.motion.site.Site`) and the
strapdown navigation of the calibration (:mod:`rlgsim.estimators.strapdown`), so the dataset's
truth and its estimate share one Earth model.
"""

from __future__ import annotations

import math

import numpy as np

from rlgsim.ground.units import DEG, EARTH_RATE

#: The site's geodetic latitude [°] when a scenario, dataset or recording gives none
#: (docs/design.md): the one default every wing uses.
DEFAULT_LATITUDE_DEG = 34.0

# WGS-84 defining and derived constants (NIMA TR8350.2, 3rd ed., tables 3.1 and 3.3).
WGS84_A = 6378137.0                      # semi-major axis [m]
WGS84_F = 1.0 / 298.257223563            # flattening [-]
WGS84_GAMMA_E = 9.7803253359             # normal gravity at the equator [m/s²]
WGS84_K = 0.00193185265241               # Somigliana constant k = bγ_p/(aγ_e) − 1 [-]
WGS84_E2 = 0.00669437999013              # first eccentricity squared [-]
WGS84_M = 0.00344978650684               # m = ω²a²b/GM [-]


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity magnitude γ(L, h) [m/s²] (Somigliana + free-air, NIMA TR8350.2 eq. 4-1, 4-3).

    ``latitude_deg`` geodetic latitude [°]; ``height_m`` height above the WGS-84 ellipsoid [m].
    """
    s2 = math.sin(latitude_deg * DEG) ** 2
    gamma0 = WGS84_GAMMA_E * (1.0 + WGS84_K * s2) / math.sqrt(1.0 - WGS84_E2 * s2)
    a = WGS84_A
    return gamma0 * (1.0 - 2.0 / a * (1.0 + WGS84_F + WGS84_M - 2.0 * WGS84_F * s2) * height_m
                     + 3.0 * height_m ** 2 / a ** 2)


def earth_rate_enu(latitude_deg: float) -> np.ndarray:
    """Earth rate in the local ENU frame ω_ie^n = (0, Ω cos L, Ω sin L) [rad/s], (3,)."""
    lat = latitude_deg * DEG
    return np.array([0.0, EARTH_RATE * math.cos(lat), EARTH_RATE * math.sin(lat)])


def radii_of_curvature(latitude_deg: float) -> tuple[float, float]:
    """Meridian and transverse radii of curvature (R_M, R_E) [m] of the WGS-84 ellipsoid at
    geodetic latitude ``latitude_deg`` [°]: :func:`radii_of_curvature_rad` (Groves 2013
    eqs. 2.105–2.106) at one latitude given in degrees."""
    r_m, r_e = radii_of_curvature_rad(np.float64(latitude_deg * DEG))
    return float(r_m), float(r_e)


def transport_rate_enu(latitude_deg: float, height_m: float, v_enu: np.ndarray) -> np.ndarray:
    """Transport rate ω_en^n [rad/s] (3,) of the ENU frame for the ENU velocity ``v_enu`` [m/s]
    at ``latitude_deg`` [°] and ``height_m`` [m]: :func:`transport_rate_enu_rad` (Titterton &
    Weston eq. 3.87, ENU) at one point given in degrees."""
    return transport_rate_enu_rad(np.float64(latitude_deg * DEG), float(height_m),
                                  np.asarray(v_enu, dtype=float))


# ------------------------------------------------------------------ a vehicle on the ellipsoid
#
# The simulator's vehicle (rlgsim.sim.motion.trajectory) needs the same Earth model along its
# path at many points at once: the ``_rad`` functions below take numpy arrays of radians (and
# the ECEF position and C_n^e its tests use; Groves 2013 eqs. 2.112, 2.150). The radii and the
# transport rate are written once, here; the degree forms above call them at one point.


def radii_of_curvature_rad(lat_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii of curvature (R_M, R_N) [m] of the WGS-84 ellipsoid at
    geodetic latitudes ``lat_rad`` [rad] (Groves 2013 eqs. 2.105, 2.106):

        R_N = a / sqrt(1 − e² sin²L),   R_M = a (1 − e²) / (1 − e² sin²L)^(3/2)
    """
    s2 = np.sin(lat_rad) ** 2
    d = 1.0 - WGS84_E2 * s2
    return WGS84_A * (1.0 - WGS84_E2) / d ** 1.5, WGS84_A / np.sqrt(d)


def earth_rate_enu_rad(lat_rad: np.ndarray) -> np.ndarray:
    """ω_ie^n = (0, Ω cos L, Ω sin L) [rad/s] at latitudes ``lat_rad`` [rad], (…, 3)."""
    lat = np.asarray(lat_rad, dtype=float)
    return np.stack([np.zeros_like(lat), EARTH_RATE * np.cos(lat), EARTH_RATE * np.sin(lat)],
                    axis=-1)


def transport_rate_enu_rad(lat_rad: np.ndarray, height_m: np.ndarray, v_enu: np.ndarray
                           ) -> np.ndarray:
    """Transport rate ω_en^n [rad/s] of the ENU frame carried at ground velocity ``v_enu``
    (…, 3) [m/s] over the ellipsoid (Titterton & Weston eq. 3.87 in ENU):

        ω_en^n = (−v_N/(R_M + h), v_E/(R_N + h), v_E tan L/(R_N + h))
    """
    rm, rn = radii_of_curvature_rad(lat_rad)
    ve, vn = v_enu[..., 0], v_enu[..., 1]
    rnh = rn + height_m
    return np.stack([-vn / (rm + height_m), ve / rnh, ve * np.tan(lat_rad) / rnh], axis=-1)


def normal_gravity_rad(lat_rad: np.ndarray, height_m: np.ndarray) -> np.ndarray:
    """Normal gravity γ(L, h) [m/s²] at arrays of latitudes [rad] and heights [m]: the formula
    of :func:`normal_gravity` (NIMA TR8350.2 eqs. 4-1, 4-3) on numpy's arrays."""
    s2 = np.sin(lat_rad) ** 2
    gamma0 = WGS84_GAMMA_E * (1.0 + WGS84_K * s2) / np.sqrt(1.0 - WGS84_E2 * s2)
    a = WGS84_A
    return gamma0 * (1.0 - 2.0 / a * (1.0 + WGS84_F + WGS84_M - 2.0 * WGS84_F * s2) * height_m
                     + 3.0 * height_m ** 2 / a ** 2)


def geodetic_to_ecef(lat_rad: np.ndarray, lon_rad: np.ndarray, height_m: np.ndarray
                     ) -> np.ndarray:
    """Earth-centred Earth-fixed position [m], (…, 3), of geodetic coordinates on WGS-84
    (Groves 2013 eq. 2.112)."""
    _, rn = radii_of_curvature_rad(lat_rad)
    cl = np.cos(lat_rad)
    return np.stack([(rn + height_m) * cl * np.cos(lon_rad),
                     (rn + height_m) * cl * np.sin(lon_rad),
                     ((1.0 - WGS84_E2) * rn + height_m) * np.sin(lat_rad)], axis=-1)


def enu_to_ecef_matrix(lat_rad: np.ndarray, lon_rad: np.ndarray) -> np.ndarray:
    """C_n^e (…, 3, 3): ENU components → ECEF components at geodetic (L, λ) (Groves 2013
    eq. 2.150, written for ENU)."""
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    z = np.zeros_like(sl * so)
    return np.stack([np.stack([-so + z, -sl * co, cl * co], -1),
                     np.stack([co + z, -sl * so, cl * so], -1),
                     np.stack([z, cl + z, sl + z], -1)], -2)
