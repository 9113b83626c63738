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


def _rocking_imu(seconds: float, lat: float, psi: float, amp: float, seed: int, vib: float = 0.05e-3):
    """Exact 100 Hz increments of a unit at rest at heading ``psi`` whose body rocks about
    its right and forward axes (``amp`` rad at 0.37 and 0.61 Hz) and vibrates (0.05 mm at
    15-17 Hz along each axis: 0.5 m/s^2, 5 mm/s), with white accelerometer noise of 10
    ug/sqrt(Hz)."""
    from bench.nav.earth import OMEGA_IE
    from bench.nav.rotation import dcm_to_quat, quat_to_rotvec

    dt = 0.01
    n = round(seconds / dt)
    t = np.arange(n + 1) * dt
    u = np.array([0.0, np.cos(lat), np.sin(lat)])

    def rot(axis, a):
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k

    C0 = euler_to_dcm(psi, 0.01, -0.02)
    Cbn = [C0 @ rot([1, 0, 0], amp * np.sin(2 * np.pi * 0.37 * tk))
           @ rot([0, 1, 0], amp * np.sin(2 * np.pi * 0.61 * tk + 1)) for tk in t]
    Cbi = [rot(u, OMEGA_IE * tk) @ C for tk, C in zip(t, Cbn, strict=True)]  # C_b^i0
    rng = np.random.default_rng(seed)
    th = np.zeros((n, 3))
    dv = np.zeros((n, 3))
    g = np.array([0.0, 0.0, 9.79])
    w = 2 * np.pi * np.array([15.0, 16.0, 17.0])
    ph = rng.uniform(0, 2 * np.pi, 3)
    vel = vib * w * np.cos(np.outer(t, w) + ph)  # the vibration's velocity, ENU
    for k in range(n):
        th[k] = quat_to_rotvec(dcm_to_quat(Cbi[k].T @ Cbi[k + 1]))
        Cm = 0.5 * (Cbn[k] + Cbn[k + 1])
        dv[k] = Cm.T @ (g * dt + vel[k + 1] - vel[k]) + rng.normal(0.0, 1e-4 * np.sqrt(dt), 3)
    return th, dv, (np.arange(1, n + 1) * 10_000_000).astype(np.int64), Cbn[-1]


def test_inertial_frame_alignment_of_a_rocking_unit_beats_the_analytic_one_and_knows_its_accuracy():
    """A unit rocking by 10 arcmin: the mean gyro rate is the rocking's, so the analytic
    alignment's heading is degrees off; the inertial-frame alignment over the same 60 s
    is within its own 3 sigma and far closer."""
    from bench.nav.alignment import InertialAlignment

    lat, psi = np.radians(34.2), np.radians(237.0)
    th, dv, t, C_true = _rocking_imu(60.0, lat, psi, np.radians(10.0 / 60.0), 1)
    al = InertialAlignment()
    for k in range(0, len(t), 100):  # 1 s blocks
        al.add(th[k : k + 100], dv[k : k + 100], t[k : k + 100])
    fit = al.fit(lat)
    E = fit.C_bn @ C_true.T
    err = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    sig = np.sqrt(np.diag(fit.cov))
    assert np.all(np.abs(err) <= 3.0 * sig), (err, sig)
    assert abs(err[2]) < np.radians(0.5) and np.all(np.abs(err[:2]) < np.radians(1.0 / 60.0))
    analytic = coarse_align(dv.sum(0) / 60.0, th.sum(0) / 60.0, lat)
    h_an = dcm_to_euler(analytic)[0]
    assert abs(wrap_pi(h_an - psi)) > 5.0 * abs(err[2])
    assert 0.0 < fit.disturbance < 0.01  # the vibration's velocity: millimetres per second
