"""Truth over the North Pole (S003d): a drive north from 89.97 N, 10 E at 20 m/s passes the
pole after about 167 s and goes on south along 170 W. The truth must stay finite and exact
through latitude 90 deg: same speed, the meridian plane, ENU velocity that matches the
ECEF path, inertial rates equal to the ENU formulas wherever those are well conditioned.
Drives that stay below the polar limit keep the geodetic integration (see
test_existing_drives_keep_the_geodetic_integration)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.rotation import wrap_pi
from bench.scenario.loader import load_scenario
from bench.scenario.motion import build_profile
from bench.scenario.trajectory import Kinematics, inertial_quantities, truth_at

ROOT = Path(__file__).resolve().parents[2]
S003D = ROOT / "test_cases" / "scenarios" / "S003d_over_the_pole.toml"
LON0 = np.radians(10.0)


@pytest.fixture(scope="module")
def traj():
    return load_scenario(S003D).trajectory()


@pytest.fixture(scope="module")
def truth(traj):
    return truth_at(traj, np.arange(0, traj.duration_ns + 1, 10_000_000))


def _from_pole(tr) -> np.ndarray:
    """Horizontal distance from the North Pole, m."""
    x = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h)
    return np.hypot(x[:, 0], x[:, 1])


def test_the_drive_passes_the_pole_with_finite_truth(traj, truth):
    assert traj.near_pole
    for name in ("lat", "lon", "h", "vel_n", "q_bn", "euler", "omega_ib_b", "f_b", "acc_n"):
        assert np.all(np.isfinite(getattr(truth, name))), name
    i = int(np.argmax(truth.lat))
    assert 166.0 < truth.t_ns[i] * 1e-9 < 169.0
    assert _from_pole(truth)[i] < 0.2  # a 10 ms sample within 20 cm of the pole
    assert np.max(truth.lat) <= np.pi / 2
    assert np.all((truth.lon > -np.pi) & (truth.lon <= np.pi))


def test_speed_height_and_the_meridian_plane(truth):
    np.testing.assert_allclose(np.linalg.norm(truth.vel_n, axis=1), 20.0, atol=1e-9)
    np.testing.assert_allclose(truth.h, 50.0, atol=1e-6)
    x = earth.geodetic_to_ecef(truth.lat, truth.lon, truth.h)
    normal = np.array([-np.sin(LON0), np.cos(LON0), 0.0])  # of the plane of meridians 10 E / 170 W
    assert np.max(np.abs(x @ normal)) < 1e-6
    # the path advances along the meridian: 20 m/s * 600 s of chord lengths
    assert np.sum(np.linalg.norm(np.diff(x, axis=0), axis=1)) == pytest.approx(12_000.0, abs=1e-4)


def test_longitude_and_heading_flip_at_the_pole(truth):
    far = _from_pole(truth) > 100.0
    before = far & (truth.t_ns < 160e9)
    after = far & (truth.t_ns > 175e9)
    assert before.sum() > 10_000 and after.sum() > 40_000
    assert np.max(np.abs(wrap_pi(truth.lon[before] - LON0))) < 1e-9
    assert np.max(np.abs(wrap_pi(truth.lon[after] - (LON0 - np.pi)))) < 1e-9
    assert np.max(np.abs(wrap_pi(truth.euler[before, 0]))) < 1e-9
    assert np.max(np.abs(wrap_pi(truth.euler[after, 0] - np.pi))) < 1e-9
    np.testing.assert_allclose(truth.euler[:, 1:], 0.0, atol=1e-12)


def test_enu_velocity_matches_the_ecef_path_through_the_pole(truth):
    """Central differences of the ECEF positions, turned into ENU at each sample, give the
    recorded ENU velocity, at the pole too (where ENU turns by 180 deg within a metre)."""
    x = earth.geodetic_to_ecef(truth.lat, truth.lon, truth.h)
    dt = 0.01
    v_e = (x[2:] - x[:-2]) / (2.0 * dt)
    v_n = np.einsum("nij,nj->ni", earth.C_en(truth.lat[1:-1], truth.lon[1:-1]), v_e)
    np.testing.assert_allclose(v_n, truth.vel_n[1:-1], atol=1e-6)
    i = int(np.argmax(truth.lat))
    np.testing.assert_allclose(v_n[i - 1], truth.vel_n[i], atol=1e-6)


def test_inertial_rates_are_smooth_through_the_pole(truth):
    """omega_ib_b is Earth rate plus the transport rate v/R about the body's right axis;
    f_b is gravity plus the centripetal v^2/R: no jump at the pole in the body frame."""
    R_M, _ = earth.radii(truth.lat)
    w_tr = -20.0 / (R_M + truth.h)  # pitching down over the Earth's curve: about -x (right)
    C = truth.C_bn
    w_ie_b = np.einsum("nji,nj->ni", C, earth.earth_rate_n(truth.lat))
    np.testing.assert_allclose(truth.omega_ib_b[:, 0] - w_ie_b[:, 0], w_tr, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(truth.omega_ib_b[:, 1:] - w_ie_b[:, 1:], 0.0, atol=1e-15)
    assert np.max(np.abs(np.diff(truth.f_b, axis=0))) < 1e-6


def test_pole_safe_rates_equal_the_enu_formulas_away_from_the_pole(traj):
    """Where tan(lat) is well conditioned, the ENU formulas on the kinematics' ENU fields
    (heading rate, acc_n) give the same omega_ib_b and f_b as the wander-azimuth form."""
    t = np.concatenate([np.linspace(0.0, 150.0, 301), np.linspace(185.0, 600.0, 831)])
    k = traj.kinematics(t)
    assert k.heading_rate_w is not None
    enu = Kinematics(k.t, k.lat, k.lon, k.h, k.vel_n, k.acc_n, k.euler, k.euler_rate)
    _, w_safe, f_safe, _ = inertial_quantities(k)
    _, w_enu, f_enu, _ = inertial_quantities(enu)
    np.testing.assert_allclose(w_safe, w_enu, rtol=0, atol=1e-13)
    np.testing.assert_allclose(f_safe, f_enu, rtol=0, atol=1e-10)


def test_a_turning_polar_drive_keeps_acc_n_the_derivative_of_vel_n():
    """A drive that turns and climbs near the pole: acc_n is d vel_n / dt (the ENU
    components' rate), the heading rate that of the ENU heading."""
    doc = {
        "initial": {"latitude": 89.99, "longitude": -40.0, "height": "10 m", "speed": "15 m/s", "heading": "30 deg"},
        "segment": [
            {"kind": "uniform", "duration": "20 s"},
            {"kind": "turn", "angle": "90 deg", "direction": "left", "rate": "6 deg/s", "duration": "30 s"},
            {"kind": "climb", "angle": "3 deg", "duration": "20 s"},
        ],
    }
    traj = build_profile(doc)
    assert traj.near_pole
    t = np.linspace(1.0, 69.0, 68001)
    k = traj.kinematics(t)
    dt = t[1] - t[0]
    acc = (k.vel_n[2:] - k.vel_n[:-2]) / (2 * dt)
    np.testing.assert_allclose(acc, k.acc_n[1:-1], atol=2e-5)
    psi = np.unwrap(k.euler[:, 0])
    np.testing.assert_allclose((psi[2:] - psi[:-2]) / (2 * dt), k.euler_rate[1:-1, 0], atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(k.vel_n, axis=1), traj.speed(t), atol=1e-9)


def test_existing_drives_keep_the_geodetic_integration():
    """S003a ends at 88.06 N, below the polar limit: the geodetic integration (bitwise as
    before) with the ENU heading channel."""
    traj = load_scenario(ROOT / "test_cases" / "scenarios" / "S003a_polar_crossing.toml").trajectory()
    assert not traj.near_pole
    assert traj.kinematics(np.array([0.0, 600.0])).heading_rate_w is None
