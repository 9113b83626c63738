"""Exact IMU increments: closure of the reference mechanization over the whole S000 drive,
and the properties that make the increments exact."""

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.rotation import quat_conj, quat_mul, quat_to_rotvec
from bench.nav.strapdown import NavState, mechanize
from bench.scenario.motion import build_profile
from bench.scenario.trajectory import truth_at
from bench.sensors.imu import ideal_increments, interval_ns


def _all(traj, rate, **kw):
    blocks = list(ideal_increments(traj, rate, **kw))
    return (
        np.concatenate([b.t_ns for b in blocks]),
        np.concatenate([b.dtheta for b in blocks]),
        np.concatenate([b.dvel for b in blocks]),
    )


def closure(traj, rate):
    """Max horizontal position error (m) and attitude error (arcsec) of the mechanization
    of exact increments against truth, vertical channel held to truth."""
    t, dth, dv = _all(traj, rate)
    tru = truth_at(traj, t)
    t0 = truth_at(traj, np.array([0]))
    init = NavState(t0.lat[0], t0.lon[0], t0.h[0], t0.vel_n[0], t0.q_bn[0])
    res = mechanize(dth, dv, interval_ns(rate) * 1e-9, init, h_ref=tru.h, vu_ref=tru.vel_n[:, 2])
    R_M, R_N = earth.radii(tru.lat)
    hor = np.hypot((res.lat - tru.lat) * (R_M + tru.h), (res.lon - tru.lon) * (R_N + tru.h) * np.cos(tru.lat))
    att = np.linalg.norm(quat_to_rotvec(quat_mul(res.q_bn, quat_conj(tru.q_bn))), axis=1)
    return float(hor.max()), float(np.degrees(att.max()) * 3600.0)


def test_s000_closure_at_200_hz(s000_trajectory):
    hor, att = closure(s000_trajectory, 200.0)
    assert hor < 1.0, f"horizontal closure {hor:.4f} m"
    assert att < 3.0, f"attitude closure {att:.5f} arcsec"
    # the figures are far inside the limits; catch a regression long before it matters
    assert hor < 0.02 and att < 0.01


@pytest.mark.slow
def test_s000_closure_at_1000_hz(s000_trajectory):
    hor, att = closure(s000_trajectory, 1000.0)
    assert hor < 1.0 and att < 3.0
    assert hor < 0.01 and att < 0.01


def test_increments_do_not_depend_on_chunking_or_range(s000_trajectory):
    tr = s000_trajectory
    a = _all(tr, 200.0, start_index=60_000, stop_index=62_000, chunk_s=10.0)
    b = _all(tr, 200.0, start_index=60_000, stop_index=62_000, chunk_s=0.37)
    c = _all(tr, 200.0, start_index=61_000, stop_index=62_000, chunk_s=3.0)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x, y)
    assert np.array_equal(a[1][1000:], c[1]) and np.array_equal(a[2][1000:], c[2])
    assert a[0][0] == 60_001 * 5_000_000


def test_quadrature_has_converged(s000_trajectory):
    # 3 Gauss points per piece versus 6: the same to rounding on a manoeuvring stretch
    tr = s000_trajectory
    _, th3, v3 = _all(tr, 200.0, start_index=64_000, stop_index=70_000, nodes=3)
    _, th6, v6 = _all(tr, 200.0, start_index=64_000, stop_index=70_000, nodes=6)
    assert np.abs(th3 - th6).max() < 1e-15
    assert np.abs(v3 - v6).max() < 1e-12


def test_static_increments_are_earth_rate_and_gravity():
    doc = {
        "initial": {"latitude": 45.0, "longitude": 7.0, "height": 1000.0, "heading": 120.0},
        "segment": [{"kind": "static", "duration": 2.0}],
    }
    traj = build_profile(doc)
    t, dth, dv = _all(traj, 100.0)
    tru = truth_at(traj, t[:1])
    C_nb = tru.C_bn[0].T
    lat = np.radians(45.0)
    assert dth[0] == pytest.approx(C_nb @ earth.earth_rate_n(lat) * 0.01, abs=1e-18)
    assert dv[0] == pytest.approx(C_nb @ [0, 0, earth.gravity(lat, 1000.0) * 0.01], abs=1e-14)


def test_coning_motion_is_integrated_exactly():
    # a body rolling and pitching at once (coning-like): the increments integrate the
    # body-frame rate, which the mechanization's coning term must resolve; compare the
    # 200 Hz mechanized attitude with truth after 200 s of continuous wobble
    segs = []
    for _ in range(20):
        segs += [
            {"kind": "coordinated_turn", "direction": "left", "angle": "30 deg", "rate": "15 deg/s"},
            {"kind": "coordinated_turn", "direction": "right", "angle": "30 deg", "rate": "15 deg/s"},
        ]
    doc = {
        "initial": {"latitude": 30.0, "longitude": 100.0, "height": 0.0, "heading": 0.0, "speed": 20.0},
        "segment": segs,
    }
    traj = build_profile(doc)
    hor, att = closure(traj, 200.0)
    assert att < 0.05 and hor < 0.01


def test_rate_must_divide_a_second():
    with pytest.raises(ValueError, match="whole number"):
        interval_ns(300.0)
    assert interval_ns(400.0) == 2_500_000
