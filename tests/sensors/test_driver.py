"""Driver input: steering by the bicycle model, tracked-vehicle levers, brake, pass-through."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.scenario.motion import build_profile
from bench.sensors.driver import DRIVER_PARAMS, LEVER_I, LEVER_II, LEVER_MOST_FORMER, DriverInput
from bench.sensors.params import resolve
from tests.sensors.helpers import EquatorTrajectory, run_all, run_windows

START = {"latitude": 39.84991, "longitude": 116.17715, "height": "60 m", "heading": "0 deg"}


def driver(**table):
    return DriverInput(resolve("driver", table, DRIVER_PARAMS))


def profile(segments):
    return build_profile({"initial": START, "segment": segments})


def at(rec, t0, t1):
    t = rec["t_ns"] * 1e-9
    return rec[(t >= t0) & (t < t1)]


@pytest.fixture(scope="module")
def wheeled_drive():
    return profile(
        [
            {"kind": "static", "duration": "5 s"},
            {"kind": "accelerate", "speed": "10 m/s", "duration": "15 s"},  # 5-20
            {"kind": "turn", "direction": "left", "angle": "90 deg", "radius": "50 m", "duration": "15 s"},  # 20-35
            {"kind": "turn", "direction": "right", "angle": "180 deg", "radius": "25 m", "duration": "15 s"},  # 35-50
            {"kind": "uniform", "duration": "5 s"},  # 50-55
            {"kind": "descend", "angle": "4 deg", "duration": "30 s"},  # 55-85
            {"kind": "stop", "duration": "15 s"},  # 85-100
            {"kind": "static", "duration": "5 s"},
        ]
    )


def test_wheeled_steering_follows_the_path_curvature(wheeled_drive):
    rec = run_all(driver(wheelbase="3.2 m"), wheeled_drive, window_s=4.4)
    assert len(rec) == 105 * 50
    left = at(rec, 22.5, 27.5)  # constant-radius parts of the turns
    right = at(rec, 39.5, 42.5)
    assert np.all(left["steering"] == pytest.approx(math.atan(3.2 / 50.0), rel=1e-3))
    assert np.all(right["steering"] == pytest.approx(-math.atan(3.2 / 25.0), rel=1e-3))
    assert np.all(np.abs(at(rec, 51.0, 55.0)["steering"]) < 1e-6)
    assert np.all(rec["left_lever"] == 0) and np.all(rec["right_lever"] == 0)
    ratio = run_all(driver(wheelbase="3.2 m", steering_ratio=16.0), wheeled_drive)
    np.testing.assert_allclose(ratio["steering"], 16.0 * rec["steering"])


def test_brake_when_slowing_harder_than_coasting_downhill_and_at_rest(wheeled_drive):
    rec = run_all(driver(), wheeled_drive)
    assert np.all(at(rec, 0.0, 4.9)["brake"] == 1)  # at rest
    assert np.all(at(rec, 6.0, 18.0)["brake"] == 0)  # accelerating
    assert np.all(at(rec, 51.0, 55.0)["brake"] == 0)  # level, uniform speed
    assert np.all(at(rec, 65.0, 75.0)["brake"] == 1)  # 4 deg downhill: g sin 4 deg = 0.68 > 0.3 m/s^2
    assert np.all(at(rec, 88.0, 95.0)["brake"] == 1)  # stopping at 1 m/s^2
    gentle = run_all(driver(coast_decel="1 m/s^2"), wheeled_drive)
    assert np.all(at(gentle, 65.0, 75.0)["brake"] == 0)


def test_tracked_levers_follow_the_turn_state():
    drive = profile(
        [
            {"kind": "static", "duration": "5 s"},
            {"kind": "turn", "direction": "right", "angle": "180 deg", "rate": "20 deg/s", "duration": "15 s"},  # 5-20
            {"kind": "accelerate", "speed": "3 m/s", "duration": "10 s"},  # 20-30
            {"kind": "uniform", "duration": "10 s"},  # 30-40
            {"kind": "turn", "direction": "left", "angle": "180 deg", "radius": "8.064 m", "duration": "15 s"},
            {"kind": "uniform", "duration": "5 s"},
        ]
    )
    rec = run_all(driver(vehicle="tracked", track_width="2.8 m"), drive)
    pivot = at(rec, 7.0, 12.0)  # turning in place to the right: right lever in position II
    assert np.all(pivot["right_lever"] == LEVER_II) and np.all(pivot["left_lever"] == LEVER_MOST_FORMER)
    assert np.all(pivot["brake"] == 0)
    straight = at(rec, 31.0, 40.0)
    assert np.all(straight["left_lever"] == LEVER_MOST_FORMER) and np.all(straight["right_lever"] == LEVER_MOST_FORMER)
    curve = at(rec, 43.0, 48.0)  # turning in a curve of radius 2.88 B to the left: left lever in position I
    assert np.all(curve["left_lever"] == LEVER_I) and np.all(curve["right_lever"] == LEVER_MOST_FORMER)
    assert np.all(rec["steering"] == 0.0)
    assert np.all(at(rec, 0.0, 4.9)["brake"] == 1)


def test_plant_commands_pass_through_and_windows_do_not_matter(wheeled_drive):
    class Driven(EquatorTrajectory):
        def driver_input(self, t):
            return {
                "left_lever": (t > 1).astype(int),
                "right_lever": np.full(len(t), 2),
                "steering": 0.1 * t,
                "brake": (t > 2).astype(int),
            }

    rec = run_all(driver(vehicle="tracked"), Driven(3.0))
    t = rec["t_ns"] * 1e-9
    np.testing.assert_allclose(rec["steering"], 0.1 * t)
    assert np.array_equal(rec["left_lever"], (t > 1).astype(np.uint8)) and np.all(rec["right_lever"] == 2)
    assert np.array_equal(rec["brake"], (t > 2).astype(np.uint8))
    a = run_all(driver(), wheeled_drive, window_s=10.0)
    b = run_windows(driver(), wheeled_drive, [0.01, 20.0, 20.02, 81.3])
    assert np.array_equal(a, b)
