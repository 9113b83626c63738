"""Sensor-level faults: the S002 fault table in the odometer stream, body-motion faults,
IMU faults, and the checks of fault parameters."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench import paths
from bench.errors import ConfigError
from bench.faults.motion import FaultedTrajectory, with_motion_faults
from bench.faults.schedule import parse_schedule
from bench.faults.sensor import windows_for
from bench.nav import earth
from bench.nav.rotation import quat_to_dcm
from bench.record.mcap_io import RecordingReader
from bench.scenario.loader import load_scenario
from bench.scenario.motion import build_profile
from bench.scenario.trajectory import truth_at
from bench.sensors.imu.faulty import FaultyImu
from bench.sensors.imu.grade import ImuGrade
from bench.sensors.imu.model import LaserImu
from bench.sensors.odometer import ODOMETER_PARAMS, Odometer
from bench.sensors.params import resolve
from bench.sensors.suite import build_suite, fault_schedule
from bench.synth import SynthOptions, synthesize

STATES = Path(__file__).parent / "data" / "S002_states.toml"
S002_FAULTS = paths.test_cases_dir() / "faults" / "S002_odometer.toml"
Q, K = 0.02, 0.02  # seed 002 odometer: pulse equivalent (assumed) and scale-factor error


@pytest.fixture(scope="module")
def s002(tmp_path_factory):
    """The S002 states drive synthesized with the S002 fault file, and a fault-free odometer."""
    sc = load_scenario(STATES)
    out = tmp_path_factory.mktemp("s002") / "s002.mcap"
    synthesize(sc, out, SynthOptions(seed=2, write_ideal=False, fault_files=(str(S002_FAULTS),)))
    r = RecordingReader(out)
    clean_traj = sc.trajectory()
    odo = Odometer(resolve("odometer", sc.doc["odometer"], ODOMETER_PARAMS), 2)
    clean = []
    for t0 in range(0, clean_traj.duration_ns, 100_000_000_000):
        clean.append(odo.run(clean_traj, t0, min(t0 + 100_000_000_000, clean_traj.duration_ns))["/odometer"])
    return {
        "odo": r.read_columnar("/odometer"),
        "truth": r.read_columnar("/truth"),
        "driver": r.read_columnar("/driver"),
        "faults": [doc for _, doc in r.iter_json("/faults")],
        "clean": np.concatenate(clean),
    }


def _win(rec, a, b):
    return (rec["t_ns"] >= round(a * 1e9)) & (rec["t_ns"] < round(b * 1e9))


def _travel(odo, a, b):
    """Metres counted by the odometer between the samples at a and b (s)."""
    t = odo["t_ns"]
    i, j = np.searchsorted(t, [round(a * 1e9), round(b * 1e9)])
    return (odo["pulses"][j] - odo["pulses"][i]) * Q


def _body(truth, a, b):
    """Truth over [a, b]: path length of the IMU point and its lateral (body x) travel."""
    m = (truth["t_ns"] >= round(a * 1e9)) & (truth["t_ns"] <= round(b * 1e9))
    tr = truth[m]
    C = quat_to_dcm(tr["q_bn"])
    v_b = np.einsum("nji,nj->ni", C, tr["vel_n"])
    dt = np.diff(tr["t_ns"]) * 1e-9

    def integral(x):
        return float(np.sum(0.5 * (x[1:] + x[:-1]) * dt))

    return integral(np.linalg.norm(tr["vel_n"], axis=1)), integral(v_b[:, 0]), integral(v_b[:, 1])


def test_windows_recorded_with_kind_and_times(s002):
    f = s002["faults"]
    assert [(w["start_ns"], w["end_ns"], w["kind"]) for w in f] == [
        (240 * 10**9, 245 * 10**9, "idling"),
        (540 * 10**9, 550 * 10**9, "sideslip"),
        (540 * 10**9, 550 * 10**9, "idling"),
        (840 * 10**9, 845 * 10**9, "no_output"),
        (1110 * 10**9, 1120 * 10**9, "sideslip"),
        (1110 * 10**9, 1120 * 10**9, "idling"),
        (1360 * 10**9, 1365 * 10**9, "sliding"),
    ]
    assert all(w["target"] == "odometer" and w["layer"] == "sensor" for w in f)
    assert [w["id"] for w in f] == list(range(7))
    assert f[2]["params"] == {"ratio": 0.3, "speed": 1.0}


def test_the_drive_is_in_the_seed_driving_states(s002):
    tr, drv = s002["truth"], s002["driver"]
    speed = np.linalg.norm(tr["vel_n"], axis=1)
    for a, b, v in ((240, 245, 8.0), (840, 845, 8.0), (1360, 1365, 6.0)):
        assert np.allclose(speed[_win(tr, a, b)], v, atol=1e-6)
    assert np.all(np.degrees(tr["euler"][_win(tr, 1360, 1365), 1]) == pytest.approx(-3.0))
    # levers: turning in place (position II), turning in curve (position I), straight
    assert np.all(drv["right_lever"][_win(drv, 540, 550)] == 2)
    assert np.all(drv["right_lever"][_win(drv, 1110, 1120)] == 1)
    assert np.all(drv["right_lever"][_win(drv, 240, 245)] == 0) and np.all(drv["left_lever"] == 0)


def test_idling_reads_distance_the_body_did_not_travel(s002):
    odo, clean = s002["odo"], s002["clean"]
    body, _, _ = _body(s002["truth"], 240, 245)
    assert body == pytest.approx(40.0, abs=1e-6)
    counted, clean_counted = _travel(odo, 240, 245), _travel(clean, 240, 245)
    assert clean_counted == pytest.approx((1 + K) * 40.0 * math.cos(math.radians(0.5)) ** 2, abs=2 * Q)
    assert counted == pytest.approx(1.3 * clean_counted, abs=2 * Q)
    assert counted - (1 + K) * body > 0.29 * body  # 12 m the body did not travel
    # outside the window the two runs count the same
    assert _travel(odo, 100, 239) == _travel(clean, 100, 239)


def test_turning_in_place_idling_and_an_unseen_sideslip(s002):
    odo, clean, tr = s002["odo"], s002["clean"], s002["truth"]
    w = _win(odo, 540, 550)
    # idling: the wheel runs 30 % faster plus 1 m/s, whatever the hull does; of the 0.3 m/s
    # sideslip it sees only what its 0.5 deg mounting yaw projects (and idles on that too)
    leak = 1.3 * 0.3 * math.sin(math.radians(0.5)) + 1e-9
    np.testing.assert_allclose(odo["wheel_speed"][w], 1.3 * clean["wheel_speed"][w] + 1.0, atol=leak)
    path, lateral, forward = _body(tr, 540, 550)
    # the hull pivots: its own displacement is the sideslip only, 0.3 m/s over 10 s less one ramp
    assert lateral == pytest.approx(0.3 * 9.5, rel=1e-3)
    assert abs(forward) < 1e-3
    counted = _travel(odo, 540, 550)
    assert counted > 10.0 > 2.0 * path  # the odometer reads distance the body did not travel
    # the sideslip is not seen: the odometer counts what idling alone would give
    expected = (1 + K) * (1.3 * _travel(clean, 540, 550) / (1 + K) + 1.0 * 10.0)
    assert counted == pytest.approx(expected, abs=3 * Q)


def test_no_output_reads_zero_while_the_body_moves(s002):
    odo = s002["odo"]
    body, _, _ = _body(s002["truth"], 840, 845)
    assert body == pytest.approx(40.0, abs=1e-6)
    w = _win(odo, 840.005, 845)
    assert np.all(odo["pulses"][w] == odo["pulses"][w][0])
    assert np.all(odo["speed"][_win(odo, 840, 845)] == 0.0)
    assert np.all(odo["valid"] == 1)  # the frames keep claiming valid: the DUT must notice
    after = _win(odo, 845.5, 850)
    assert np.allclose(odo["speed"][after], (1 + K) * 8.0 * math.cos(math.radians(0.5)) ** 2)
    assert _travel(odo, 840.01, 844.99) == 0.0
    assert _travel(odo, 840, 845) <= 0.08 + 1e-9  # at most the half intervals at the edges (8 m/s * 5 ms each)


def test_turning_in_curve_sideslip_is_lateral_displacement_the_odometer_does_not_see(s002):
    odo, clean, tr = s002["odo"], s002["clean"], s002["truth"]
    _, lateral, forward = _body(tr, 1110, 1120)
    assert lateral == pytest.approx(-0.6 * 9.5, rel=1e-3)  # slid 5.7 m to the left
    assert forward == pytest.approx(30.0, rel=1e-3)  # 3 m/s forward meanwhile
    w = _win(odo, 1110, 1120)
    leak = 1.2 * 0.6 * math.sin(math.radians(0.5)) + 1e-9  # the slide projected by the mounting yaw
    assert np.max(np.abs(odo["wheel_speed"][w] - 1.2 * clean["wheel_speed"][w])) < leak
    counted = _travel(odo, 1110, 1120)
    assert counted == pytest.approx(1.2 * _travel(clean, 1110, 1120), abs=3 * Q + 10.0 * leak)
    # what it counted is the left track's forward travel (3 m/s + yaw rate x 1.4 m), idled by 20 %:
    # the 5.7 m sideways are not in it
    m = _win(tr, 1110, 1120.001)
    w_z = tr["omega_ib_b"][m, 2]  # forward speed of the track = forward speed + omega_z * l_x, l_x = -1.4 m
    turned = float(np.sum(0.5 * (w_z[1:] + w_z[:-1]) * np.diff(tr["t_ns"][m]) * 1e-9))
    track_travel = forward - 1.4 * turned
    assert track_travel == pytest.approx(30.0 + 1.4 * math.radians(21.315) * 10.0, rel=1e-3)
    assert counted / (1 + K) == pytest.approx(1.2 * track_travel * math.cos(math.radians(0.5)) ** 2, abs=0.15)


def test_sliding_downhill_reads_too_little(s002):
    odo, clean = s002["odo"], s002["clean"]
    body, _, _ = _body(s002["truth"], 1360, 1365)
    assert body == pytest.approx(30.0, abs=1e-6)
    counted = _travel(odo, 1360, 1365)
    assert counted == pytest.approx(0.5 * _travel(clean, 1360, 1365), abs=2 * Q)
    assert counted < 0.55 * (1 + K) * body


def test_no_fault_outside_the_windows(s002):
    odo, clean = s002["odo"], s002["clean"]
    quiet = _win(odo, 0, 239.9) | _win(odo, 246, 539) | _win(odo, 551, 839) | _win(odo, 846, 1109)
    np.testing.assert_allclose(odo["speed"][quiet], clean["speed"][quiet], atol=1e-9)


# -- body-motion faults ----------------------------------------------------------------
@pytest.fixture(scope="module")
def turn_drive():
    start = {"latitude": 39.9, "longitude": 116.2, "height": "60 m", "heading": "10 deg"}
    return build_profile(
        {
            "initial": start,
            "segment": [
                {"kind": "accelerate", "speed": "6 m/s", "duration": "10 s"},
                {"kind": "turn", "direction": "left", "angle": "180 deg", "radius": "20 m", "duration": "20 s"},
                {"kind": "uniform", "duration": "10 s"},
            ],
        }
    )


def test_faulted_trajectory_is_kinematically_consistent(turn_drive):
    sched = parse_schedule(
        [
            {"start": "14 s", "end": "22 s", "target": "odometer", "kind": "sideslip", "params": {"speed": "0.8 m/s"}},
            {"start": "33 s", "end": "33.4 s", "target": "odometer", "kind": "bump", "params": {"height": "0.1 m"}},
        ]
    )
    traj = with_motion_faults(turn_drive, sched)
    assert isinstance(traj, FaultedTrajectory)
    assert set(np.round(traj.knots(), 6)) >= {14.0, 14.5, 21.5, 22.0, 33.0, 33.4}
    t = np.linspace(0.5, 39.5, 4001)
    h = 1e-4
    k, kp, km = traj.kinematics(t), traj.kinematics(t + h), traj.kinematics(t - h)
    dlat, dlon, dh = earth.position_rates(k.lat, k.h, k.vel_n)
    np.testing.assert_allclose((kp.lat - km.lat) / (2 * h), dlat, atol=1e-11)  # ~6e-5 m/s
    np.testing.assert_allclose((kp.lon - km.lon) / (2 * h), dlon, atol=1e-11)
    np.testing.assert_allclose((kp.h - km.h) / (2 * h), dh, atol=1e-5)
    np.testing.assert_allclose((kp.vel_n - km.vel_n) / (2 * h), k.acc_n, atol=1e-4)
    # the slide: lateral body velocity 0.8 m/s mid-window, displacement stays afterwards
    tr = truth_at(traj, np.array([18_000_000_000]))
    v_b = tr.C_bn[0].T @ tr.vel_n[0]
    assert v_b[0] == pytest.approx(0.8, abs=1e-9) and v_b[1] == pytest.approx(6.0, abs=1e-9)
    base = truth_at(turn_drive, np.array([30_000_000_000]))
    moved = truth_at(traj, np.array([30_000_000_000]))
    R_M, R_N = earth.radii(base.lat)
    shift = [
        (moved.lon - base.lon)[0] * (R_N + base.h)[0] * np.cos(base.lat[0]),
        (moved.lat - base.lat)[0] * (R_M + base.h)[0],
    ]
    # expected: the lateral speed along the turning body x axis, integrated (trapezoid, 10 kHz)
    ts = np.linspace(14.0, 22.0, 80_001)
    x = np.clip(np.minimum(ts - 14.0, 22.0 - ts) / 0.5, 0.0, 1.0)
    v_lat = 0.8 * x**3 * (10 - 15 * x + 6 * x * x)
    psi = turn_drive.kinematics(ts).euler[:, 0]
    x_n = np.column_stack([np.cos(psi), -np.sin(psi)])  # body right axis in E, N (level)
    f = v_lat[:, None] * x_n
    expected = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(ts)[:, None], axis=0)
    assert np.hypot(*expected) == pytest.approx(4.8, abs=0.1)  # a chord: the axis turned 120 deg meanwhile
    np.testing.assert_allclose(shift, expected, atol=2e-3)
    # the bump lifts the body 0.1 m at mid-window
    up = truth_at(traj, np.array([33_200_000_000])).h - truth_at(turn_drive, np.array([33_200_000_000])).h
    assert up[0] == pytest.approx(0.1, abs=1e-9)


def test_bump_spikes_the_wheel_and_jolts_the_body(turn_drive):
    sched = parse_schedule(
        [{"start": "33 s", "end": "33.4 s", "target": "odometer", "kind": "bump", "params": {"speed": "3 m/s"}}]
    )
    traj = with_motion_faults(turn_drive, sched)
    odo = Odometer(resolve("odometer", {}, ODOMETER_PARAMS), 0, faults=windows_for(sched, "odometer"))
    rec = odo.run(traj, 0, traj.duration_ns)["/odometer"]
    w = _win(rec, 33.0, 33.4)
    assert rec["speed"][w].max() == pytest.approx(6.0 + 3.0, abs=0.01)
    assert np.all(rec["speed"][_win(rec, 31, 33)] == pytest.approx(6.0))
    tr = truth_at(traj, np.array([33_000_000_000, 33_200_000_000, 33_400_000_000]))
    base = truth_at(turn_drive, np.array([33_000_000_000, 33_200_000_000, 33_400_000_000]))
    np.testing.assert_allclose(tr.h - base.h, [0.0, 0.05, 0.0], atol=1e-9)
    # the IMU feels the jolt: vertical specific force changes by up to 64 * 0.375 * 0.05 / 0.16 m/s^2
    f = (
        truth_at(traj, np.array([33_200_000_000])).f_b[0, 2]
        - truth_at(turn_drive, np.array([33_200_000_000])).f_b[0, 2]
    )
    assert f == pytest.approx(-64 * 0.375 * 0.05 / 0.4**2, rel=1e-3)


# -- IMU faults ------------------------------------------------------------------------
def test_imu_bias_step_axis_failure_and_saturation(turn_drive):
    tables = [
        {
            "start": "2 s",
            "end": "4 s",
            "target": "imu",
            "kind": "bias_step",
            "params": {"gyro": [0, 0, "36 deg/h"], "accel": "1 mg"},
        },
        {
            "start": "5 s",
            "end": "6 s",
            "target": "imu",
            "kind": "axis_failure",
            "params": {"sensor": "accel", "axis": "y"},
        },
        {
            "start": "7 s",
            "end": "9.5 s",
            "target": "imu",
            "kind": "axis_failure",
            "params": {"sensor": "gyro", "axis": "x", "mode": "stuck", "flag": False},
        },
        {"start": "14 s", "end": "20 s", "target": "imu", "kind": "saturation", "params": {"gyro_range": "10 deg/s"}},
    ]
    sched = parse_schedule(tables)
    imu = FaultyImu(LaserImu(ImuGrade.ideal(), 0, 100.0), windows_for(sched, "imu"))
    parts = [imu.run(turn_drive, a, a + 1_300_000_000) for a in range(0, 39_000_000_000, 1_300_000_000)]
    meas = np.concatenate([p["/imu"] for p in parts])
    ideal = np.concatenate([p["/imu/ideal"] for p in parts])
    T = 0.01
    b = _win(meas, 2, 4)
    np.testing.assert_allclose(
        meas["dtheta"][b] - ideal["dtheta"][b], np.tile([0, 0, math.radians(0.01) * T], (b.sum(), 1)), atol=1e-15
    )
    np.testing.assert_allclose(meas["dvel"][b] - ideal["dvel"][b], 9.80665e-3 * T, atol=1e-15)
    dead = _win(meas, 5, 6)
    assert np.all(meas["dvel"][dead, 1] == 0.0)
    assert np.all(meas["status"][dead] == 0b0110_1111)  # accel y (bit 4) invalid, BIT fault (bit 6)
    stuck = _win(meas, 7, 9.5)
    held = meas["dtheta"][np.flatnonzero(stuck)[0] - 1, 0]
    assert np.all(meas["dtheta"][stuck, 0] == held)  # held across several run windows
    assert np.all(meas["status"][stuck] == 0b0011_1111)  # unflagged: the hard case
    sat = _win(meas, 14, 20)
    rate = np.abs(ideal["dtheta"][sat, 2]) / T
    clipped = rate > math.radians(10)
    assert clipped.sum() > 100  # the turn runs at 17 deg/s
    assert np.allclose(np.abs(meas["dtheta"][sat, 2][clipped]), math.radians(10) * T)
    assert np.all(meas["status"][sat][clipped] & 0x80) and not np.any(meas["status"][sat][~clipped] & 0x80)
    other = ~(b | dead | stuck | sat)
    assert np.array_equal(meas["dtheta"][other], ideal["dtheta"][other])


# -- checks -----------------------------------------------------------------------------
def test_fault_parameters_are_checked():
    with pytest.raises(ConfigError, match="unknown parameter 'ratoi'"):
        parse_schedule([{"start": 1, "end": 2, "target": "odometer", "kind": "idling", "params": {"ratoi": 0.2}}])
    with pytest.raises(ConfigError, match="applies to odometer"):
        parse_schedule([{"start": 1, "end": 2, "target": "bds", "kind": "idling"}])
    with pytest.raises(ConfigError, match="applies to doppler"):
        parse_schedule([{"start": 1, "end": 2, "target": "odometer", "kind": "bias_step"}])
    bad = parse_schedule([{"start": 1, "end": 2, "target": "bds", "kind": "outage", "params": {"style": "loud"}}])
    with pytest.raises(ConfigError, match="no_fix or silent"):
        windows_for(bad, "bds")
    bad = parse_schedule([{"start": 1, "end": 2, "target": "bds", "kind": "multipath", "params": {"factor": 0}}])
    with pytest.raises(ConfigError, match="factor must be positive"):
        windows_for(bad, "bds")
    bad = parse_schedule([{"start": 1, "end": 2, "target": "imu", "kind": "axis_failure", "params": {"axis": "w"}}])
    with pytest.raises(ConfigError, match="axis must be one of x, y, z"):
        windows_for(bad, "imu")


def test_a_fault_on_a_missing_sensor_is_an_error():
    doc = {"doppler": {}, "fault": [{"start": 1, "end": 2, "target": "odometer", "kind": "no_output"}]}
    sched = fault_schedule(doc)
    with pytest.raises(ConfigError, match="no such sensor"):
        build_suite(doc, seed=0, schedule=sched)
    doc["odometer"] = {}
    suite = build_suite(doc, seed=0, schedule=sched)
    assert [m.name for m in suite.models] == ["doppler", "odometer"]
