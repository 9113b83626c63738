import numpy as np
import pytest

from bench.nav.alignment import coarse_align, latitude_from_static
from bench.nav.rotation import dcm_to_euler, euler_to_dcm, wrap_pi
from bench.scenario.motion import build_profile
from bench.scenario.trajectory import truth_at
from bench.sensors.imu import ideal_increments
from bench.sensors.imu.analysis import read_psins_imu


def test_coarse_alignment_of_exact_static_increments():
    doc = {
        "initial": {
            "latitude": 34.2,
            "longitude": 108.9,
            "height": 380.0,
            "heading": 237.0,
            "pitch": 2.0,
            "roll": -3.0,
        },
        "segment": [{"kind": "static", "duration": 10.0}],
    }
    traj = build_profile(doc)
    blk = next(ideal_increments(traj, 100.0))
    f = blk.dvel.mean(0) / 0.01
    w = blk.dtheta.mean(0) / 0.01
    assert np.degrees(latitude_from_static(f, w)) == pytest.approx(34.2, abs=1e-6)
    C = coarse_align(f, w, np.radians(34.2))
    assert pytest.approx(truth_at(traj, np.array([0])).C_bn[0], abs=1e-9) == C


def test_real_laser_gyro_log_gives_latitude_and_heading(data_dir):
    # A real RLG unit parked at 34.246048 N with its engine running: the Earth rate it
    # senses gives the latitude and the heading (the log's header heading, 90.6 deg
    # clockwise, is marked "maybe inaccurate" by its author)
    log = read_psins_imu(data_dir / "psins_lasergyro_10min.imu")
    f = log.dvel.mean(0) / log.dt
    w = log.dtheta.mean(0) / log.dt
    assert np.degrees(latitude_from_static(f, w)) == pytest.approx(34.246, abs=0.15)
    psi, theta, gamma = dcm_to_euler(coarse_align(f, w, np.radians(34.246048)))
    assert abs(np.degrees(wrap_pi(psi - np.radians(90.6)))) < 10.0
    assert abs(np.degrees(theta)) < 2.0 and abs(np.degrees(gamma)) < 2.0
    # and gravity magnitude matches the log's own g within the disturbance
    assert np.linalg.norm(f) == pytest.approx(9.780327, rel=2e-3)
    assert euler_to_dcm(psi, theta, gamma).shape == (3, 3)
