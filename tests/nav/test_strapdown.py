"""The reference mechanization against exact increments and against textbook error
responses (Schuler oscillation, heading drift)."""

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.rotation import quat_conj, quat_mul, quat_to_rotvec
from bench.nav.strapdown import NavState, Strapdown, mechanize
from bench.scenario.motion import build_profile
from bench.scenario.trajectory import truth_at
from bench.sensors.imu import ideal_increments

LAT, LON, H = np.radians(34.246), np.radians(108.91), 380.0


def _static(duration_s: float, heading_deg: float = 0.0):
    doc = {
        "initial": {"latitude": np.degrees(LAT), "longitude": np.degrees(LON), "height": H, "heading": heading_deg},
        "segment": [{"kind": "static", "duration": duration_s}],
    }
    return build_profile(doc)


def _increments(traj, rate=200.0):
    blocks = list(ideal_increments(traj, rate))
    return (
        np.concatenate([b.t_ns for b in blocks]),
        np.concatenate([b.dtheta for b in blocks]),
        np.concatenate([b.dvel for b in blocks]),
    )


def _init(traj):
    t0 = truth_at(traj, np.array([0]))
    return NavState(t0.lat[0], t0.lon[0], t0.h[0], t0.vel_n[0], t0.q_bn[0])


def test_static_hour_stays_put():
    traj = _static(3600.0, heading_deg=30.0)
    t, dth, dv = _increments(traj)
    res = mechanize(dth, dv, 0.005, _init(traj))
    R_M, R_N = earth.radii(LAT)
    north = (res.lat - LAT) * (R_M + H)
    east = (res.lon - LON) * (R_N + H) * np.cos(LAT)
    # unaided, vertical channel free: exact increments leave every channel at rest
    assert np.max(np.hypot(north, east)) < 1e-3
    assert np.max(np.abs(res.h - H)) < 1e-3
    att = quat_to_rotvec(quat_mul(res.q_bn, quat_conj(truth_at(traj, t).q_bn)))
    assert np.degrees(np.max(np.abs(att))) * 3600 < 0.01


def test_step_by_step_equals_batch():
    traj = _static(20.0)
    _, dth, dv = _increments(traj)
    rng = np.random.default_rng(0)
    dth = dth + rng.normal(scale=1e-6, size=dth.shape)
    dv = dv + rng.normal(scale=1e-4, size=dv.shape)
    batch = mechanize(dth, dv, 0.005, _init(traj))
    sd = Strapdown(_init(traj))
    for k in range(len(dth)):
        sd.step(dth[k], dv[k], 0.005)
    s = sd.state
    assert s.lat == batch.lat[-1] and s.lon == batch.lon[-1] and s.h == batch.h[-1]
    assert np.array_equal(s.vel_n, batch.vel_n[-1]) and np.array_equal(s.q_bn, batch.q_bn[-1])


def test_accelerometer_bias_gives_the_schuler_oscillation():
    # 100 ug on the north-pointing accelerometer: north error (b / ws^2)(1 - cos ws t),
    # peak 2 b R / g after half a Schuler period
    b = 100e-6 * 9.80665
    g = earth.gravity(LAT, H)
    R_M, R_N = earth.radii(LAT)
    R = np.sqrt((R_M + H) * (R_N + H))
    ws = np.sqrt(g / R)
    half = np.pi / ws
    traj = _static(half + 1.0)
    t, dth, dv = _increments(traj)
    dv[:, 1] += b * 0.005  # heading 0: body y is north
    n = len(t)
    res = mechanize(dth, dv, 0.005, _init(traj), h_ref=np.full(n, H), vu_ref=np.zeros(n))
    north = (res.lat - LAT) * (R_M + H)
    k = np.searchsorted(t, half * 1e9)
    assert north[k] == pytest.approx(2 * b / ws**2, rel=0.02)
    # and a quarter period in, half of it
    k4 = np.searchsorted(t, half / 2 * 1e9)
    assert north[k4] == pytest.approx(b / ws**2, rel=0.03)


def test_vertical_gyro_bias_drifts_heading_linearly():
    bias = np.radians(1.0 / 3600.0)  # 1 deg/h on the up gyro
    traj = _static(600.0)
    t, dth, dv = _increments(traj)
    dth[:, 2] += bias * 0.005
    n = len(t)
    res = mechanize(dth, dv, 0.005, _init(traj), h_ref=np.full(n, H), vu_ref=np.zeros(n))
    phi = quat_to_rotvec(quat_mul(res.q_bn, quat_conj(truth_at(traj, t).q_bn)))
    # the body turns left (positive about up) by bias * t: heading decreases
    assert phi[-1, 2] == pytest.approx(bias * 600.0, rel=0.01)
