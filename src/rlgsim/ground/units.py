"""Unit conversions: the one place where engineering units meet SI.

Inside rlgsim everything is SI (rad, rad/s, m/s², s, W, J/K, W/K); absolute temperatures are in
°C and temperature differences in K. Scenario keys carry their unit in the name and are
converted here, at the edge.
"""

from __future__ import annotations

import math

#: Standard gravity used for µg and g conversions [m/s²] (ISO 80000-3).
G0 = 9.80665
#: Earth rotation rate [rad/s] (WGS-84).
EARTH_RATE = 7.292115e-5

DEG = math.pi / 180.0            # rad per degree
ARCSEC = DEG / 3600.0            # rad per arcsecond
ARCMIN = DEG / 60.0              # rad per arcminute
HOUR = 3600.0                    # s per hour
MINUTE = 60.0                    # s per minute
PPM = 1e-6                       # per part per million
MICRO_G = 1e-6 * G0              # m/s² per µg


def deg_per_h_to_rad_per_s(x):
    """Angular rate °/h → rad/s."""
    return x * DEG / HOUR


def rad_per_s_to_deg_per_h(x):
    """Angular rate rad/s → °/h."""
    return x * HOUR / DEG


def deg_per_s_to_rad_per_s(x):
    return x * DEG


def rad_per_s_to_deg_per_s(x):
    return x / DEG


def deg_per_sqrt_h_to_rad_per_sqrt_s(x):
    """Angle random walk °/√h → rad/√s (= rad/s/√Hz)."""
    return x * DEG / math.sqrt(HOUR)


def rad_per_sqrt_s_to_deg_per_sqrt_h(x):
    return x * math.sqrt(HOUR) / DEG


def deg_per_h_per_sqrt_h_to_rad_per_s_per_sqrt_s(x):
    """Rate random walk °/h/√h → rad/s/√s."""
    return x * DEG / HOUR / math.sqrt(HOUR)


def rad_per_s_per_sqrt_s_to_deg_per_h_per_sqrt_h(x):
    return x * HOUR * math.sqrt(HOUR) / DEG


def ug_to_m_per_s2(x):
    """Acceleration µg → m/s²."""
    return x * MICRO_G


def m_per_s2_to_ug(x):
    return x / MICRO_G


def m_per_s_per_sqrt_h_to_m_per_s_per_sqrt_s(x):
    """Velocity random walk (m/s)/√h → (m/s)/√s."""
    return x / math.sqrt(HOUR)


def ug_per_sqrt_hz_to_m_per_s2_per_sqrt_hz(x):
    """Velocity random walk as µg/√Hz → m/s²/√Hz (= (m/s)/√s)."""
    return x * MICRO_G


def ppm_to_ratio(x):
    return x * PPM


def ratio_to_ppm(x):
    return x / PPM


def arcsec_to_rad(x):
    return x * ARCSEC


def rad_to_arcsec(x):
    return x / ARCSEC


def c_per_min_to_k_per_s(x):
    """Temperature rate °C/min → K/s."""
    return x / MINUTE


def k_per_s_to_c_per_min(x):
    return x * MINUTE


def hours_to_s(x):
    return x * HOUR


def minutes_to_s(x):
    return x * MINUTE

NAUTICAL_MILE = 1852.0             # m per international nautical mile (the INS industry's nmi)
