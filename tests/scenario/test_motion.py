"""Motion scripts: every segment kind does what it says, within its limits, and the
kinematics are mutually consistent (velocity is the derivative of position, etc.)."""

import math

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.nav import earth
from bench.nav.rotation import wrap_pi
from bench.scenario.loader import load_scenario
from bench.scenario.motion import build_profile, parse_latlon

BASE = {"initial": {"latitude": 34.0, "longitude": 108.0, "height": 400.0, "heading": 0.0}}


def _traj(*segments, **initial):
    doc = {"initial": {**BASE["initial"], **initial}, "segment": list(segments)}
    return build_profile(doc, file="test.toml")


def test_s000_matches_the_seed(s000_trajectory):
    tr = s000_trajectory
    assert tr.duration_s == 3600.0
    assert tr.distance() == pytest.approx(50600.0, rel=0.01)
    t = np.linspace(0, 3600, 360001)
    assert tr.speed(t).max() == pytest.approx(22.0, abs=1e-9)
    k = tr.kinematics(np.array([0.0]))
    assert np.degrees(k.lat[0]) == pytest.approx(34 + 14.763 / 60, abs=1e-12)
    assert np.degrees(k.lon[0]) == pytest.approx(108 + 54.579 / 60, abs=1e-12)
    assert np.degrees(k.euler[0, 0]) == pytest.approx(30.0)
    kinds = {s.kind for s in tr.segments()}
    assert {"uniform", "accelerate", "decelerate", "turn", "climb", "descend", "stop", "static"} <= kinds


def test_accelerate_respects_limits_and_reaches_the_target():
    tr = _traj({"kind": "accelerate", "speed": "20 m/s", "accel": "1.5 m/s^2", "jerk": "0.8 m/s^3", "duration": "40 s"})
    t = np.linspace(0, tr.duration_s, 40001)
    k = tr.kinematics(t)
    acc = k.acc_n[:, 1]
    assert acc.max() == pytest.approx(1.5, rel=1e-6)
    jerk = np.gradient(acc, t)
    assert jerk.max() <= 0.8 * 1.001
    assert tr.speed(np.array([40.0]))[0] == pytest.approx(20.0, abs=1e-9)


def test_short_speed_change_lowers_the_peak_acceleration():
    tr = _traj({"kind": "accelerate", "speed": "0.5 m/s", "accel": "2 m/s^2", "jerk": "1 m/s^3"})
    t = np.linspace(0, tr.duration_s, 2001)
    assert tr.speed(t)[-1] == pytest.approx(0.5, abs=1e-12)
    assert tr.kinematics(t).acc_n[:, 1].max() < 2.0


@pytest.mark.parametrize("direction,sign", [("right", 1.0), ("left", -1.0)])
def test_turn_by_radius(direction, sign):
    tr = _traj(
        {"kind": "accelerate", "speed": "10 m/s", "duration": "20 s"},
        {"kind": "turn", "direction": direction, "angle": "90 deg", "radius": "50 m", "duration": "20 s"},
    )
    k = tr.kinematics(np.array([20.0, 40.0]))
    assert np.degrees(wrap_pi(k.euler[1, 0] - k.euler[0, 0])) == pytest.approx(sign * 90.0, abs=1e-9)
    rate = np.abs(tr.kinematics(np.linspace(20, 40, 20001)).euler_rate[:, 0]).max()
    assert rate == pytest.approx(10.0 / 50.0, rel=1e-9)  # v / R


def test_coordinated_turn_banks_to_cancel_lateral_specific_force():
    from bench.scenario.trajectory import inertial_quantities

    tr = _traj(
        {"kind": "accelerate", "speed": "15 m/s", "duration": "20 s"},
        {"kind": "coordinated_turn", "direction": "right", "angle": "180 deg", "rate": "6 deg/s"},
    )
    mid = tr.segments()[1].start_s + tr.segments()[1].end_s
    k = tr.kinematics(np.array([mid / 2]))
    r = math.radians(6.0)
    assert k.euler[0, 2] == pytest.approx(math.atan(15.0 * r / 9.80665), rel=1e-9)
    _, _, f_b, _ = inertial_quantities(k)
    # steady banked turn: lateral specific force nearly zero (normal vs standard gravity)
    assert abs(f_b[0, 0]) < 0.01


def test_turn_in_place_at_rest():
    tr = _traj({"kind": "turn", "direction": "left", "angle": "360 deg", "rate": "20 deg/s"})
    k = tr.kinematics(np.array([0.0, tr.duration_s]))
    assert np.degrees(k.euler[1, 0] - k.euler[0, 0]) == pytest.approx(-360.0)
    assert np.allclose(k.vel_n, 0.0) and k.lat[1] == k.lat[0]


def test_climb_by_height_returns_level():
    tr = _traj(
        {"kind": "accelerate", "speed": "10 m/s", "duration": "20 s"},
        {"kind": "climb", "angle": "4 deg", "height": "25 m", "pitch_rate": "1 deg/s"},
        {"kind": "descend", "angle": "2 deg", "duration": "60 s"},
    )
    k = tr.kinematics(np.array([20.0, tr.segments()[1].end_s]))
    assert k.h[1] - k.h[0] == pytest.approx(25.0, abs=1e-3)
    assert k.euler[1, 1] == pytest.approx(0.0, abs=1e-12)


def test_stop_then_static():
    tr = _traj(
        {"kind": "accelerate", "speed": "12 m/s", "duration": "20 s"},
        {"kind": "stop", "accel": "2 m/s^2", "duration": "15 s"},
        {"kind": "static", "duration": "5 s"},
    )
    assert np.abs(tr.speed(np.linspace(35, 40, 11))).max() < 1e-12


def test_kinematics_are_self_consistent(s000_trajectory):
    # velocity = d(position)/dt and acceleration = d(velocity)/dt, by central differences,
    # at many times spread over the drive (including inside turns and hills)
    tr = s000_trajectory
    t = np.linspace(1.0, tr.duration_s - 1.0, 400)
    dt = 1e-3
    kp, km, k = tr.kinematics(t + dt), tr.kinematics(t - dt), tr.kinematics(t)
    xp = earth.geodetic_to_ecef(kp.lat, kp.lon, kp.h)
    xm = earth.geodetic_to_ecef(km.lat, km.lon, km.h)
    v_e = (xp - xm) / (2 * dt)
    v_n = np.einsum("nij,nj->ni", earth.C_en(k.lat, k.lon), v_e)
    assert v_n == pytest.approx(k.vel_n, abs=2e-5)
    assert (kp.vel_n - km.vel_n) / (2 * dt) == pytest.approx(k.acc_n, abs=1e-5)
    assert (kp.euler - km.euler) / (2 * dt) == pytest.approx(k.euler_rate, abs=1e-6)


def test_truth_position_integration_converges_with_the_internal_rate():
    segs = [
        {"kind": "accelerate", "speed": "20 m/s", "duration": "30 s"},
        {"kind": "turn", "direction": "left", "angle": "270 deg", "rate": "5 deg/s"},
        {"kind": "climb", "angle": "3 deg", "duration": "60 s"},
    ]
    doc = {**BASE, "segment": segs}
    a = build_profile(doc, internal_rate_hz=1000.0)
    b = build_profile(doc, internal_rate_hz=4000.0)
    t = np.linspace(0, a.duration_s, 50)
    ka, kb = a.kinematics(t), b.kinematics(t)
    R = earth.A
    assert np.max(np.abs(ka.lat - kb.lat)) * R < 1e-5  # below 10 micrometres
    assert np.max(np.abs(ka.lon - kb.lon)) * R < 1e-5
    assert np.max(np.abs(ka.h - kb.h)) < 1e-5


@pytest.mark.parametrize(
    "segment,key,words",
    [
        ({"kind": "fly", "duration": 1}, "segment[0].kind", "expected kind one of"),
        ({"kind": "uniform"}, "segment[0].duration", "missing field"),
        ({"kind": "uniform", "duration": "10 m"}, "segment[0].duration", "expected time"),
        ({"kind": "uniform", "duration": 5, "speeed": 1}, "segment[0].speeed", "unknown key"),
        ({"kind": "turn", "angle": 90, "rate": 10}, "segment[0].direction", "'left' or 'right'"),
        ({"kind": "accelerate", "speed": "30 m/s", "duration": "3 s"}, "segment[0].duration", "needs"),
        ({"kind": "turn", "direction": "left", "angle": 90, "radius": "10 m"}, "segment[0].radius", "moving"),
        ({"kind": "climb", "angle": "50 deg", "duration": 30}, "segment[0].angle", "between 0 and 45"),
        ({"kind": "turn", "direction": "left", "angle": 90, "rate": "90 deg/s"}, "segment[0].rate", "max_rate"),
    ],
)
def test_bad_segments_name_file_key_and_expectation(segment, key, words):
    with pytest.raises(ConfigError) as exc:
        _traj(segment)
    assert exc.value.file == "test.toml"
    assert exc.value.key == key
    assert words in str(exc.value)


def test_static_while_moving_is_refused():
    with pytest.raises(ConfigError, match="at rest"):
        _traj({"kind": "accelerate", "speed": "5 m/s"}, {"kind": "static", "duration": 10})


@pytest.mark.parametrize(
    "text,axis,deg",
    [
        ("34°14.763'N", "lat", 34.24605),
        ("108°54.579'E", "lon", 108.90965),
        ("33d30m0sS", "lat", -33.5),
        (34.5, "lat", 34.5),
        ("-12.25", "lon", -12.25),
        ("0°30'W", "lon", -0.5),
    ],
)
def test_latlon_formats(text, axis, deg):
    assert math.degrees(parse_latlon(text, axis)) == pytest.approx(deg, abs=1e-9)


def test_latlon_errors():
    with pytest.raises(ConfigError, match="within"):
        parse_latlon(95.0, "lat")
    with pytest.raises(ConfigError, match="hemisphere"):
        parse_latlon("34°N", "lon")


def test_scenario_loader_errors(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('[scenario]\nid = "X"\n[initial]\nlatitude = 1\n')
    with pytest.raises(ConfigError, match="segment"):
        load_scenario(p)
    p.write_text('[scenario]\nid = "X"\ncolour = 1\n')
    with pytest.raises(ConfigError) as exc:
        load_scenario(p)
    assert exc.value.key == "scenario.colour"
    p.write_text("[scenario\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_scenario(p)
    with pytest.raises(ConfigError, match="no scenario"):
        load_scenario("S999_nonexistent")
