"""Odometer: pulses integrate to the wheel's travel, mounting, reverse, statistics."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.rotation import euler_rates_to_omega_nb_b, euler_to_dcm
from bench.scenario.loader import load_scenario
from bench.sensors.odometer import ODOMETER_PARAMS, Odometer
from bench.sensors.params import resolve
from bench.sensors.processes import fit_markov
from tests.sensors.helpers import EquatorTrajectory, run_all, run_windows

SHORT = Path(__file__).parents[1] / "data" / "short_drive.toml"


def odometer(seed=0, faults=(), **table):
    return Odometer(resolve("odometer", table, ODOMETER_PARAMS), seed, faults=faults)


@pytest.fixture(scope="module")
def short_traj():
    return load_scenario(SHORT).trajectory()


def _wheel_speed(traj, t, lever, yaw, pitch):
    """Independent: v_b = C^T v_n + (omega_nb_b + C^T omega_en_n) x l, on the forward axis."""
    k = traj.kinematics(t)
    C = euler_to_dcm(k.euler[:, 0], k.euler[:, 1], k.euler[:, 2])
    w_nb = euler_rates_to_omega_nb_b(*k.euler.T, *k.euler_rate.T)
    w_en = earth.transport_rate_n(k.lat, k.h, k.vel_n)
    w_eb = w_nb + np.einsum("nji,nj->ni", C, w_en)
    v_b = np.einsum("nji,nj->ni", C, k.vel_n) + np.cross(w_eb, lever)
    axis = np.array([math.sin(yaw) * math.cos(pitch), math.cos(yaw) * math.cos(pitch), math.sin(pitch)])
    return v_b @ axis


def test_pulses_integrate_to_the_wheel_travel_within_one_pulse(short_traj):
    lever = np.array([-1.4, 2.0, -1.0])
    yaw, pitch = math.radians(0.5), math.radians(0.5)
    q, k = 0.02, 0.02
    m = odometer(model="seed002", lever_arm=["-1.4 m", "2 m", "-1 m"])
    assert m.q == q and m.p["scale_factor"] == k
    rec = run_all(m, short_traj, window_s=6.1)
    assert np.array_equal(rec["t_ns"], np.arange(1, 9001) * 10_000_000)
    # reference: the wheel's travel integrated at 2 kHz
    tf = np.linspace(0.0, 90.0, 180_001)
    v = _wheel_speed(short_traj, tf, lever, yaw, pitch)
    travel = np.concatenate([[0.0], np.cumsum(0.5 * (np.abs(v[1:]) + np.abs(v[:-1])) * np.diff(tf))])
    ref = travel[::20][1:]  # at the 100 Hz samples
    np.testing.assert_allclose(rec["distance"], ref, atol=2e-4)
    counted = rec["pulses"] * q
    tol = 1e-3  # the 100 Hz trapezoid against the 2 kHz reference
    assert np.all(counted <= (1 + k) * ref + tol)
    assert np.all(counted > (1 + k) * ref - q - tol)  # within one pulse, at every sample
    assert rec["pulses"][-1] > 30_000
    np.testing.assert_allclose(rec["speed"], (1 + k) * v[::20][1:], atol=1e-9)
    assert np.all(rec["valid"] == 1) and np.all(rec["reverse"] == 0)


def test_mounting_angles_project_the_body_speed():
    traj = EquatorTrajectory(10.0, speed=10.0)
    rec = run_all(odometer(mounting_yaw="2 deg", mounting_pitch="1 deg", pulse_equivalent="0.05 m"), traj)
    expected = 10.0 * math.cos(math.radians(2)) * math.cos(math.radians(1))
    np.testing.assert_allclose(rec["speed"], expected, rtol=1e-12)
    assert rec["pulses"][-1] == math.floor(expected * 10.0 / 0.05 + 1e-9)


def test_reverse_counts_up_with_negative_speed():
    traj = EquatorTrajectory(5.0, speed=-3.0)
    rec = run_all(odometer(pulse_equivalent="0.01 m"), traj)
    assert np.all(rec["reverse"] == 1)
    np.testing.assert_allclose(rec["speed"], -3.0)
    assert np.all(np.diff(rec["pulses"]) >= 0) and rec["pulses"][-1] == 1500 - 0  # 15 m backwards
    assert rec["distance"][-1] == pytest.approx(15.0)


def test_plant_wheel_speed_is_measured_not_the_body():
    # the plant's wheel idles at 1.3 times the body speed: the odometer follows the wheel
    traj = EquatorTrajectory(10.0, speed=10.0, wheel=lambda t: np.full(len(t), 13.0))
    rec = run_all(odometer(pulse_equivalent="0.1 m"), traj)
    np.testing.assert_allclose(rec["speed"], 13.0)
    assert rec["pulses"][-1] == 1300


@pytest.mark.slow
def test_scale_factor_markov_and_speed_noise_statistics():
    # 10^6 s at 2 Hz, 5000 correlation times; the process is discretised exactly
    traj = EquatorTrajectory(1_000_000.0, speed=10.0)
    m = odometer(seed=4, rate="2 Hz", scale_factor_markov="0.1 %", scale_factor_tau="200 s", speed_noise="0.03 m/s")
    rec = run_all(m, traj, window_s=100_000.0)
    err = rec["speed"] - 10.0
    s_w, s_m, tau = fit_markov(err, 0.5)
    assert s_w == pytest.approx(0.03, rel=0.10)
    assert s_m / 10.0 == pytest.approx(0.001, rel=0.10)
    assert tau == pytest.approx(200.0, rel=0.10)


def test_output_does_not_depend_on_the_windows(short_traj):
    kw = {"model": "typical_wheeled"}
    a = run_all(odometer(seed=3, **kw), short_traj, window_s=10.0)
    b = run_windows(odometer(seed=3, **kw), short_traj, [0.004, 0.005, 12.345, 50.0, 50.01])
    assert np.array_equal(a, b)
