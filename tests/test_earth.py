"""WGS-84 normal gravity and the Earth rate (src/rlgsim/ground/earth.py).

References: the published WGS-84 normal gravity at the equator and the poles (NIMA TR8350.2,
3rd ed., table 3.4), Somigliana's formula in its original form with the semi-axes a, b and the
polar gravity (not the k, e² form under test), the free-air gradient, and the geometry of the
Earth-rate vector.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rlgsim.ground.earth import earth_rate_enu, normal_gravity
from rlgsim.ground.units import EARTH_RATE

GAMMA_E = 9.7803253359       # TR8350.2 table 3.4: normal gravity at the equator [m/s²]
GAMMA_P = 9.8321849378       # ... at the poles [m/s²]
A, B = 6378137.0, 6356752.3142   # WGS-84 semi-major and semi-minor axes [m] (table 3.3)


def somigliana(lat_deg: float) -> float:
    """γ = (a γ_e cos²L + b γ_p sin²L) / sqrt(a² cos²L + b² sin²L) (Somigliana 1929)."""
    c2, s2 = math.cos(math.radians(lat_deg)) ** 2, math.sin(math.radians(lat_deg)) ** 2
    return (A * GAMMA_E * c2 + B * GAMMA_P * s2) / math.sqrt(A * A * c2 + B * B * s2)


def test_normal_gravity_at_the_equator_45_degrees_and_the_poles():
    assert normal_gravity(0.0) == pytest.approx(GAMMA_E, abs=1e-12)
    assert normal_gravity(90.0) == pytest.approx(GAMMA_P, abs=1e-9)
    assert normal_gravity(-90.0) == pytest.approx(GAMMA_P, abs=1e-9)
    for lat in (15.0, 34.0, 45.0, 60.0, -45.0):
        assert normal_gravity(lat) == pytest.approx(somigliana(lat), abs=2e-9), lat
    # symmetric about the equator, increasing towards the poles
    assert normal_gravity(45.0) == normal_gravity(-45.0)
    g = [normal_gravity(lat) for lat in range(0, 91, 5)]
    assert all(b > a for a, b in zip(g, g[1:]))


def test_free_air_correction():
    # −2γ/a (1 + f + m − 2f sin²L) ≈ −3.086e-6 m/s² per metre near the surface
    for lat in (0.0, 34.0, 80.0):
        grad = (normal_gravity(lat, 100.0) - normal_gravity(lat, -100.0)) / 200.0
        assert grad == pytest.approx(-3.086e-6, rel=3e-3)
    # the second-order term 3h²/a² makes γ(h) convex
    g0, g1, g2 = (normal_gravity(34.0, h) for h in (0.0, 10000.0, 20000.0))
    assert g0 - 2 * g1 + g2 == pytest.approx(3 * 20000.0 ** 2 / A ** 2 * g0 / 2, rel=2e-2)


@pytest.mark.parametrize("lat", [-90.0, -34.0, 0.0, 34.0, 51.5, 90.0])
def test_earth_rate_points_along_the_spin_axis(lat):
    w = earth_rate_enu(lat)
    assert w.shape == (3,) and w[0] == 0.0
    assert np.linalg.norm(w) == pytest.approx(EARTH_RATE, rel=1e-15)
    # elevation of the spin axis above the northern horizon is the latitude
    assert math.degrees(math.atan2(w[2], w[1])) == pytest.approx(lat, abs=1e-12)


def test_radii_and_transport_rate_one_form_with_the_ellipse_geometry():
    """The degree forms are the array forms at one point (one implementation), and R_M, R_N
    agree with the ellipse itself: the meridian's curvature radius |dP/dL| from its parametric
    form x = a cos β, z = b sin β with tan β = (b/a) tan L (complex-step derivative, exact to
    rounding), and the prime vertical's R_N = x / cos L. Tolerance 1e-12: tan L at 89° carries
    its rounding ×57 into β, far below it elsewhere."""
    from rlgsim.ground.earth import (WGS84_A, WGS84_E2, radii_of_curvature,
                                     radii_of_curvature_rad, transport_rate_enu,
                                     transport_rate_enu_rad)
    from rlgsim.ground.units import DEG
    lats = np.array([-80.0, -33.3, 0.0, 12.5, 34.0, 51.5, 89.0])
    rm_a, rn_a = radii_of_curvature_rad(lats * DEG)
    v = np.array([12.0, -7.0, 0.3])
    for i, lat in enumerate(lats):
        # the same arithmetic: one point is the array form at one point (numpy's vectorised
        # power may round the last bit otherwise than the scalar one: 1e-15 against arrays)
        assert radii_of_curvature(lat) == tuple(float(r) for r in
                                                radii_of_curvature_rad(np.float64(lat * DEG)))
        assert radii_of_curvature(lat) == pytest.approx((rm_a[i], rn_a[i]), rel=1e-15)
        np.testing.assert_array_equal(transport_rate_enu(lat, 250.0, v),
                                      transport_rate_enu_rad(np.float64(lat * DEG), 250.0, v))
    b = WGS84_A * math.sqrt(1.0 - WGS84_E2)
    for i, lat in enumerate(lats):
        h = 1e-20
        phi = lat * DEG + 1j * h
        beta = np.arctan(b / WGS84_A * np.tan(phi))
        dx = (WGS84_A * np.cos(beta)).imag / h
        dz = (b * np.sin(beta)).imag / h
        assert math.hypot(dx, dz) == pytest.approx(rm_a[i], rel=1e-12)
        x = WGS84_A * math.cos(beta.real)
        if abs(lat) < 89.5:
            assert x / math.cos(lat * DEG) == pytest.approx(rn_a[i], rel=1e-12)
