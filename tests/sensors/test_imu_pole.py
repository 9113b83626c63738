"""Exact IMU increments over the North Pole (S003d): an independent strapdown integrator in
ECEF (the bench's ENU mechanization divides by cos(lat)) turns them back into the truth.

The check integrator: attitude C_be by the rotation vector with the two-sample coning
term and the Earth's turn; velocity in ECEF with rotation compensation and sculling,
normal gravity along the ellipsoid's normal at mid-interval, Coriolis; position by the
trapezoid. Nothing in it is singular at the pole.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from bench.nav import earth
from bench.nav.rotation import dcm_to_quat, quat_to_dcm, quat_to_rotvec
from bench.scenario.loader import load_scenario
from bench.scenario.motion import build_profile
from bench.scenario.trajectory import truth_at
from bench.sensors.imu import ideal_increments, interval_ns

S003D = Path(__file__).resolve().parents[2] / "test_cases" / "scenarios" / "S003d_over_the_pole.toml"


@njit(cache=True)
def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array(
        [
            a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
        ]
    )


@njit(cache=True)
def _rv2q(v: np.ndarray) -> np.ndarray:
    a = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    s = 0.5 - a * a / 48.0 if a < 1e-6 else math.sin(0.5 * a) / a
    return np.array([math.cos(0.5 * a), v[0] * s, v[1] * s, v[2] * s])


@njit(cache=True)
def _dcm(q: np.ndarray) -> np.ndarray:
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    return np.array(
        [
            [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3],
        ]
    )


@njit(cache=True)
def _normal_gravity(r: np.ndarray) -> np.ndarray:
    """Normal gravity vector in ECEF at r: -g(lat, h) along the ellipsoid normal."""
    x, y, z = r[0], r[1], r[2]
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1.0 - E2))
    for _ in range(5):
        s = math.sin(lat)
        R_N = A / math.sqrt(1.0 - E2 * s * s)
        h = p * math.cos(lat) + z * s - A * math.sqrt(1.0 - E2 * s * s)
        lat = math.atan2(z, p * (1.0 - E2 * R_N / (R_N + h)))
    s, c = math.sin(lat), math.cos(lat)
    h = p * c + z * s - A * math.sqrt(1.0 - E2 * s * s)
    s2 = s * s
    g0 = GE * (1.0 + KS * s2) / math.sqrt(1.0 - E2 * s2)
    g = g0 * (1.0 - 2.0 / A * (1.0 + F + M - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))
    lon = math.atan2(y, x)
    return -g * np.array([c * math.cos(lon), c * math.sin(lon), s])


A, E2, F, W = earth.A, earth.E2, earth.F, earth.OMEGA_IE
GE, KS, M = earth._GAMMA_E, earth._K_SOMIGLIANA, earth._M


@njit(cache=True)
def mechanize_ecef(dth: np.ndarray, dv: np.ndarray, T: float, r0: np.ndarray, v0: np.ndarray, q0: np.ndarray):
    """ECEF strapdown over increments (N, 3): positions (N, 3) and attitudes q_be (N, 4)."""
    n = dth.shape[0]
    r, v, q = r0.copy(), v0.copy(), q0.copy()
    v_prev = v0.copy()
    pth, pdv = np.zeros(3), np.zeros(3)
    out_r, out_q = np.empty((n, 3)), np.empty((n, 4))
    wie = np.array([0.0, 0.0, W])
    z_e = np.array([0.0, 0.0, -W * T])
    for k in range(n):
        th, d = dth[k], dv[k]
        phi = th + np.cross(pth, th) / 12.0
        b = d + 0.5 * np.cross(th, d) + (np.cross(pth, d) + np.cross(pdv, th)) / 12.0
        nb = _dcm(q) @ b
        f = nb + 0.5 * np.cross(z_e, nb)  # the Earth turns by -W T about z over the interval
        v_mid = v + 0.5 * (v - v_prev) if k > 0 else v.copy()
        r_mid = r + 0.5 * T * v_mid
        v_new = v + f + (_normal_gravity(r_mid) - 2.0 * np.cross(wie, v_mid)) * T
        r = r + 0.5 * T * (v + v_new)
        v_prev = v.copy()
        v = v_new
        q = _qmul(_rv2q(z_e), _qmul(q, _rv2q(phi)))
        q /= math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        pth, pdv = th.copy(), d.copy()
        out_r[k] = r
        out_q[k] = q
    return out_r, out_q


def _q_be(tr) -> np.ndarray:
    return dcm_to_quat(np.swapaxes(earth.C_en(tr.lat, tr.lon), -1, -2) @ tr.C_bn)


def closure_ecef(traj, rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times s, position error m (N, 3) ECEF, attitude error rad (N,)) of the ECEF
    mechanization of the exact increments against the truth."""
    blocks = list(ideal_increments(traj, rate))
    t = np.concatenate([b.t_ns for b in blocks])
    dth = np.concatenate([b.dtheta for b in blocks])
    dv = np.concatenate([b.dvel for b in blocks])
    t0 = truth_at(traj, np.array([0]))
    C_ne0 = earth.C_en(t0.lat[0], t0.lon[0]).T
    r0 = earth.geodetic_to_ecef(t0.lat, t0.lon, t0.h)[0]
    r, q = mechanize_ecef(dth, dv, interval_ns(rate) * 1e-9, r0, C_ne0 @ t0.vel_n[0], _q_be(t0)[0])
    tr = truth_at(traj, t)
    dr = r - earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h)
    C_err = quat_to_dcm(q) @ np.swapaxes(quat_to_dcm(_q_be(tr)), -1, -2)
    att = np.linalg.norm(quat_to_rotvec(dcm_to_quat(C_err)), axis=1)
    return t * 1e-9, dr, att


@pytest.fixture(scope="module")
def s003d():
    return load_scenario(S003D).trajectory()


def test_s003d_closes_through_the_pole_at_200_hz(s003d):
    t, dr, att = closure_ecef(s003d, 200.0)
    err = np.linalg.norm(dr, axis=1)
    assert np.all(np.isfinite(err)) and np.all(np.isfinite(att))
    # 600 s of free inertial navigation (vertical channel included) over the pole
    assert err[-1] < 1e-4, f"position closure {err[-1]:.3e} m after 600 s"  # 4e-8 m when written
    assert np.degrees(att.max()) * 3600.0 < 1e-3, f"attitude closure {np.degrees(att.max()) * 3600:.6f} arcsec"
    # nothing happens at the pole crossing: the error there is as small as before it
    near = (t > 160.0) & (t < 175.0)
    assert err[near].max() < 1e-5


def test_a_turning_polar_drive_closes():
    """Turns, accelerations and a climb 600 m from the pole: the increments carry the
    transport rate of the wander-azimuth truth correctly."""
    doc = {
        "initial": {"latitude": 89.995, "longitude": 120.0, "height": "10 m", "speed": "10 m/s", "heading": "-20 deg"},
        "segment": [
            {"kind": "uniform", "duration": "10 s"},
            {"kind": "turn", "angle": "120 deg", "direction": "right", "rate": "10 deg/s", "duration": "20 s"},
            {"kind": "accelerate", "speed": "18 m/s", "duration": "10 s"},
            {"kind": "climb", "angle": "4 deg", "duration": "15 s"},
            {"kind": "coordinated_turn", "angle": "200 deg", "direction": "left", "rate": "8 deg/s",
             "duration": "30 s"},
            {"kind": "uniform", "duration": "35 s"},
        ],
    }
    traj = build_profile(doc)
    assert traj.near_pole
    _, dr, att = closure_ecef(traj, 200.0)
    assert np.linalg.norm(dr, axis=1).max() < 0.005  # 0.3 mm when written
    assert np.degrees(att.max()) * 3600.0 < 0.05

