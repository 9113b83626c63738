import numpy as np
import pytest

from bench.nav import earth
from bench.nav.rotation import skew


def test_radii_at_equator_and_pole():
    R_M, R_N = earth.radii(np.array([0.0, np.pi / 2]))
    assert R_N[0] == pytest.approx(earth.A, abs=1e-6)
    assert R_M[0] == pytest.approx(earth.A * (1 - earth.E2), abs=1e-6)
    assert R_N[1] == pytest.approx(earth.A**2 / earth.B, abs=1e-6)
    assert R_M[1] == pytest.approx(R_N[1], abs=1e-6)


def test_normal_gravity_reference_values():
    # WGS-84 normal gravity at the equator and the poles, and the free-air gradient
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.gravity(np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)
    grad = (earth.gravity(0.6, 1000.0) - earth.gravity(0.6, 0.0)) / 1000.0
    assert grad == pytest.approx(-3.086e-6, rel=5e-3)


@pytest.mark.parametrize("lat_deg", [-89.9, -45.0, 0.0, 34.246, 87.95, 89.99])
@pytest.mark.parametrize("h", [-400.0, 0.0, 380.0, 12000.0])
def test_geodetic_ecef_round_trip(lat_deg, h):
    lat, lon = np.radians(lat_deg), np.radians(108.9)
    xyz = earth.geodetic_to_ecef(lat, lon, h)
    lat2, lon2, h2 = earth.ecef_to_geodetic(xyz)
    assert lat2 == pytest.approx(lat, abs=1e-12)
    assert lon2 == pytest.approx(lon, abs=1e-12)
    assert h2 == pytest.approx(h, abs=1e-6)


def test_ecef_of_a_known_point():
    # 0 N 0 E on the ellipsoid is (a, 0, 0); 90 N is (0, 0, b)
    assert earth.geodetic_to_ecef(0.0, 0.0, 0.0) == pytest.approx([earth.A, 0, 0])
    assert earth.geodetic_to_ecef(np.pi / 2, 0.0, 0.0) == pytest.approx([0, 0, earth.B], abs=1e-6)


def test_enu_round_trip_and_axes():
    lat0, lon0, h0 = np.radians(34.0), np.radians(108.0), 400.0
    enu = np.array([[100.0, 0, 0], [0, 100.0, 0], [0, 0, 100.0], [-12.5, 3000.0, -7.0]])
    xyz = earth.enu_to_ecef(enu, lat0, lon0, h0)
    assert earth.ecef_to_enu(xyz, lat0, lon0, h0) == pytest.approx(enu, abs=1e-8)
    # 100 m north raises the latitude by 100 / (R_M + h)
    lat, lon, _h = earth.ecef_to_geodetic(xyz[1])
    R_M, _ = earth.radii(lat0)
    assert (lat - lat0) * (R_M + h0) == pytest.approx(100.0, abs=1e-3)
    assert lon == pytest.approx(lon0, abs=1e-12)


def test_transport_rate_is_the_rotation_of_the_local_frame():
    # d/dt C_en = -skew(omega_en_n) C_en along a path, by central differences
    lat, lon, h = np.radians(60.0), np.radians(10.0), 100.0
    vel_n = np.array([30.0, -20.0, 1.0])
    lat_dot, lon_dot, _h_dot = earth.position_rates(lat, h, vel_n)
    dt = 1e-3
    Cp = earth.C_en(lat + lat_dot * dt, lon + lon_dot * dt)
    Cm = earth.C_en(lat - lat_dot * dt, lon - lon_dot * dt)
    dC = (Cp - Cm) / (2 * dt)
    w = earth.transport_rate_n(lat, h, vel_n)
    # the ellipsoidal radii make omega_en exact to the rates above
    assert dC == pytest.approx(-skew(w) @ earth.C_en(lat, lon), abs=1e-12)


def test_earth_rate_vector():
    w = earth.earth_rate_n(np.radians(30.0))
    assert w == pytest.approx([0.0, earth.OMEGA_IE * np.sqrt(3) / 2, earth.OMEGA_IE / 2])
