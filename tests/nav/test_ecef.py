"""The ECEF mechanization (bench.nav.ecef) against the bench's ENU one, and at the pole."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.ecef import (
    dcm_quat,
    ecef_position,
    enu_frame,
    from_geographic,
    geodetic,
    grid_frame,
    step_e,
    to_geographic,
)
from bench.nav.grid import C_eG
from bench.nav.rotation import euler_to_quat, quat_to_dcm
from bench.nav.strapdown import _step


def _increments(n: int, T: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A manoeuvring vehicle's increments: gravity on the up axis, turns and accelerations."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * T
    w = np.column_stack([0.02 * np.sin(0.3 * t), 0.01 * np.cos(0.2 * t), 0.05 * np.sin(0.05 * t + rng.uniform())])
    f = np.column_stack([0.3 * np.sin(0.1 * t), 0.5 * np.cos(0.07 * t), 9.80 + 0.05 * np.sin(0.5 * t)])
    return w * T, f * T


def test_geodetic_round_trip_and_the_pole():
    rng = np.random.default_rng(3)
    out = np.zeros(3)
    for lat, lon, h in zip(rng.uniform(-np.pi / 2, np.pi / 2, 200), rng.uniform(-np.pi, np.pi, 200),
                           rng.uniform(-100, 9000, 200), strict=True):
        ecef_position(lat, lon, h, out)
        assert np.allclose(out, earth.geodetic_to_ecef(lat, lon, h), atol=1e-6)
        la, lo, hh = geodetic(*out)
        assert la == pytest.approx(lat, abs=1e-12) and hh == pytest.approx(h, abs=1e-5)
        if abs(lat) < np.pi / 2 - 1e-6:
            assert math.remainder(lo - lon, 2 * np.pi) == pytest.approx(0.0, abs=1e-12)
    la, lo, hh = geodetic(0.0, 0.0, earth.B + 50.0)
    assert (la, lo) == (pytest.approx(np.pi / 2), 0.0) and hh == pytest.approx(50.0, abs=1e-6)


def test_frames_match_the_numpy_ones_and_hold_at_the_pole():
    C = np.zeros((3, 3))
    for lat, lon in ((0.3, 2.0), (np.radians(88.0), np.radians(10.0)), (np.pi / 2, 1.0), (-np.pi / 2, -2.0)):
        grid_frame(lat, lon, C)
        assert np.allclose(C, C_eG(lat, lon), atol=1e-15)
        enu_frame(lat, lon, C)
        assert np.allclose(C, earth.C_en(lat, lon), atol=1e-15)
    q = np.zeros(4)
    for psi in np.linspace(-3.1, 3.1, 13):
        R = quat_to_dcm(euler_to_quat(psi, 0.3, -1.2))
        dcm_quat(R, q, 0)
        assert np.allclose(quat_to_dcm(q), R, atol=1e-14)


@pytest.mark.parametrize("lat_deg", [31.939, 60.0, 85.0, 88.0])
def test_ecef_and_enu_mechanizations_agree_over_ten_minutes(lat_deg):
    T, n = 0.005, 120_000
    dth, dv = _increments(n, T, 1)
    sg = np.zeros(20)
    sg[0], sg[1], sg[2] = math.radians(lat_deg), math.radians(10.0), 50.0
    sg[3:6] = 3.0, 15.0, 0.0
    sg[6:10] = euler_to_quat(0.2, 0.0, 0.0)
    se = np.zeros(20)
    from_geographic(sg, se)
    back = np.zeros(20)
    to_geographic(se, back)
    assert np.allclose(back, sg, rtol=0, atol=1e-9)
    for k in range(n):
        _step(sg, dth[k], dv[k], T)
        step_e(se, dth[k], dv[k], T)
    to_geographic(se, back)
    # both are second-order algorithms: what they disagree by is their truncation, far
    # below the bench's millimetre closure of truth
    d = earth.geodetic_to_ecef(back[0], back[1], back[2]) - earth.geodetic_to_ecef(sg[0], sg[1], sg[2])
    assert np.linalg.norm(d) < 2e-3
    assert np.allclose(back[3:6], sg[3:6], atol=2e-6)
    Ce, Cg = quat_to_dcm(back[6:10]), quat_to_dcm(sg[6:10])
    assert np.linalg.norm(Ce @ Cg.T - np.eye(3)) < 1e-9
    # and the distance travelled was kilometres: the comparison is not vacuous
    assert abs(sg[0] - math.radians(lat_deg)) * earth.A > 5_000.0


def test_a_drive_over_the_pole_stays_on_its_great_circle():
    """At rest-level attitude, driving north at 20 m/s through latitude 90 deg: the IMU senses
    the Earth's rate, gravity and the transport rate of a great circle; the ECEF state
    passes the pole with speed, height and the great circle's plane kept."""
    T, n, v = 0.005, 60_000, 20.0
    lat0, lon0, h = math.radians(89.97), math.radians(10.0), 50.0
    se = np.zeros(20)
    ecef_position(lat0, lon0, h, se[0:3])
    Cen = np.zeros((3, 3))
    enu_frame(lat0, lon0, Cen)
    se[3:6] = Cen.T @ np.array([0.0, v, 0.0])
    # body RFU: forward = north; C_b^n = I for heading 0
    dcm_quat(Cen.T, se, 6)
    plane = np.cross(se[0:3], se[3:6])
    plane /= np.linalg.norm(plane)
    for _ in range(n):
        lat, lon, hh = geodetic(se[0], se[1], se[2])
        Cbe = quat_to_dcm(se[6:10])
        r = np.linalg.norm(se[0:3])
        w_eb_e = plane * v / r  # the great circle's rate (spherical at the pole: R_M = R_N there)
        w_ib_b = Cbe.T @ (np.array([0.0, 0.0, earth.OMEGA_IE]) + w_eb_e)
        u = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
        g = float(earth.gravity(lat, hh))
        # specific force = a - g: centripetal of the circle plus the Coriolis, minus gravity
        wie = np.array([0.0, 0.0, earth.OMEGA_IE])
        a_e = np.cross(w_eb_e, se[3:6]) + 2 * np.cross(wie, se[3:6])
        f_b = Cbe.T @ (a_e + g * u)
        step_e(se, w_ib_b * T, f_b * T, T)
    lat, lon, hh = geodetic(se[0], se[1], se[2])
    assert np.isfinite(se).all()
    # 6 km from 3.34 km short of the pole: 2.66 km past it, on the meridian 180 deg away
    past = (math.pi / 2 - lat) * 6_399_594.0
    assert past == pytest.approx(6000.0 - (math.pi / 2 - lat0) * 6_399_594.0, abs=1.0)
    assert math.remainder(lon - (lon0 + np.pi), 2 * np.pi) == pytest.approx(0.0, abs=1e-3)
    assert np.linalg.norm(se[3:6]) == pytest.approx(v, abs=1e-3)
    assert abs(float(plane @ se[0:3])) < 1.0  # on the great circle's plane within a metre
