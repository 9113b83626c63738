"""Fault isolation, frame switch, consistency, output-quality and integrity metrics,
against values computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from bench.faults.schedule import FaultWindow
from bench.scoring.data import NoDataError, load_run
from bench.scoring.frameswitch import SwitchSettings
from bench.scoring.integrity import check_integrity
from bench.scoring.metrics import Scorer, ScoringSettings
from bench.scoring.windows import WindowSpec
from tests.scoring.helpers import ARCMIN, drive, nav_of, quality_of, segments_of, truth_of, write_recording

ALL = WindowSpec("all")
S = 1_000_000_000


@pytest.fixture(scope="module")
def traj():
    return drive(speed=10.0, duration=100.0)


@pytest.fixture(scope="module")
def truth(traj):
    return truth_of(traj)


def _scorer(tmp_path, traj, truth, nav, quality=None, settings=None, name="r.mcap", **kw):
    path = write_recording(tmp_path / name, truth=truth, nav=nav, quality=quality, segments=segments_of(traj), **kw)
    return Scorer(load_run(path), settings or ScoringSettings())


def _t(step_ms: int = 10, end_s: int = 100):
    return np.arange(0, end_s * S + 1, step_ms * 1_000_000)


# -- faults ------------------------------------------------------------------------------
def test_fault_windows_detection_latency_exclusion_false_alarms(tmp_path, traj, truth):
    t = _t()
    ts = t / S
    nav = nav_of(traj, t)
    q = quality_of(nav)
    faults = [
        FaultWindow(0, "sensor", "odometer", "idling", 10 * S, 15 * S),
        FaultWindow(1, "sensor", "odometer", "sliding", 30 * S, 40 * S),
        FaultWindow(2, "sensor", "odometer", "no_output", 60 * S, 65 * S),
        FaultWindow(3, "sensor", "doppler", "dropout", 80 * S, 82 * S),
    ]
    # window 0: detected after 0.5 s, excluded 0.5..5 s (90 %); window 1: detected at 2 s,
    # never excluded; window 2: missed; doppler: detected at once, excluded throughout
    det = ((ts >= 10.5) & (ts < 15.0)) | ((ts >= 32.0) & (ts < 40.0)) | ((ts >= 50.0) & (ts < 51.0))
    exc = (ts >= 10.5) & (ts < 15.0)
    q["fault_detected"] = det.astype(np.uint8)
    q["excluded"] = exc.astype(np.uint8)
    dop = (ts >= 80.0) & (ts < 82.0)
    q["fault_detected"] |= (dop * 2).astype(np.uint8)
    q["excluded"] |= (dop * 2).astype(np.uint8)
    s = _scorer(tmp_path, traj, truth, nav, q, faults=faults)
    odo = {"target": ("odometer",)}
    assert s.metric("faults.windows", ALL, odo).value == 3
    assert s.metric("faults.detected", ALL, odo).value == 2
    assert s.metric("faults.missed", ALL, odo).value == 1
    assert s.metric("faults.detection_rate", ALL, odo).value == pytest.approx(2 / 3)
    assert s.metric("faults.latency_max", ALL, odo).value == math.inf  # one window missed
    assert s.metric("faults.latency_mean", ALL, odo).value == pytest.approx((0.5 + 2.0) / 2)
    assert s.metric("faults.exclusion_min", ALL, odo).value == 0.0
    assert s.metric("faults.exclusion_mean", ALL, odo).value == pytest.approx((0.9 + 0 + 0) / 3)
    # the 50-51 s episode starts outside every odometer window: one false alarm over the
    # fault-free time 100 - 5 - 10 - 5 s (all sensors' windows are not counted)
    assert s.metric("faults.false_alarms", ALL, odo).value == 1
    rate = s.metric("faults.false_alarm_rate", ALL, odo).value
    assert rate == pytest.approx(1 / (100 - 5 - 10 - 5 - 2))
    windows = s.metric("faults.windows", ALL, odo).details["windows"]
    assert [w["detected"] for w in windows] == [True, True, False]
    assert windows[2]["latency_s"] is None  # infinite, as JSON
    dop_only = {"target": ("doppler",)}
    assert s.metric("faults.latency_max", ALL, dop_only).value == 0.0
    assert s.metric("faults.exclusion_min", ALL, dop_only).value == 1.0
    # the excluded flag as detection flag: window 1 is then missed too
    assert s.metric("faults.detected", ALL, {**odo, "flag": "excluded"}).value == 1


def test_fault_error_growth_recovery_residual(tmp_path, traj, truth):
    t = _t()
    ts = t / S
    # 1 m before; grows 1 m/s through 20-25 s; recovers linearly to 1 m by 35 s
    e = np.where(ts < 20, 1.0, np.where(ts < 25, 1.0 + (ts - 20), np.maximum(1.0, 6.0 - (ts - 25) * 0.5)))
    nav = nav_of(traj, t, pos_enu=np.column_stack([e, 0 * e, 0 * e]))
    q = quality_of(nav)
    faults = [FaultWindow(0, "sensor", "odometer", "idling", 20 * S, 25 * S)]
    settings = ScoringSettings()  # pre 30 s, after 30 s, tolerance 1 m
    s = _scorer(tmp_path, traj, truth, nav, q, settings, faults=faults)
    assert s.metric("faults.growth_max", ALL).value == pytest.approx(5.0, abs=1e-6)
    # back within 1 m of the pre-fault level (1 m) when 6 - 0.5 (t - 25) <= 2: t = 33 s
    assert s.metric("faults.recovery_max", ALL).value == pytest.approx(8.0, abs=0.011)
    assert s.metric("faults.residual_max", ALL).value == pytest.approx(0.0, abs=1e-6)


def test_no_fault_windows_is_no_data_but_false_alarms_count(tmp_path, traj, truth):
    nav = nav_of(traj, _t())
    s = _scorer(tmp_path, traj, truth, nav, quality_of(nav))
    with pytest.raises(NoDataError, match="no recorded fault window"):
        s.metric("faults.detection_rate", ALL)
    assert s.metric("faults.false_alarms", ALL).value == 0
    assert s.metric("faults.windows", ALL).value == 0


# -- frame switch ------------------------------------------------------------------------
def test_a_reference_period_widens_the_band_to_the_duts_ordinary_wander(tmp_path, traj, truth):
    """A heading error that wanders 2' with a 25 s period, switch or not: judged against
    the pre window alone the wander after the switch looks like an oscillation; against
    its own ordinary excursions over the reference period it is none. A 3' swing added by
    the switch stands out either way."""
    t = _t()
    ts = t / S
    frame = (ts >= 75.0).astype(np.uint8)
    wander = 2 * ARCMIN * np.sin(2 * np.pi * ts / 25.0)
    swing = 3 * ARCMIN * np.exp(-(((ts - 80.0) / 1.5) ** 2))
    base = dict(pre_ns=15 * S, post_ns=15 * S, floor_heading=0.1 * ARCMIN)
    out = {}
    for name, att0 in (("wander", wander), ("swing", wander + swing)):
        nav = nav_of(traj, t, att=np.column_stack([att0, 0 * ts, 0 * ts]), frame=frame)
        for ref in (0, 60):
            st = ScoringSettings(switches=SwitchSettings(reference_ns=ref * S, **base))
            sc = _scorer(tmp_path, traj, truth, nav, settings=st, name=f"{name}{ref}.mcap")
            out[name, ref] = sc.metric("frameswitch.excess_heading", ALL).value
            if ref:
                ordinary = sc.metric("frameswitch.ordinary_heading", ALL).value
                assert 2.5 * ARCMIN < ordinary < 4.1 * ARCMIN  # the wander's swing within 15 s
            else:
                with pytest.raises(NoDataError):
                    sc.metric("frameswitch.ordinary_heading", ALL)
    assert out["wander", 0] > 0.3 * ARCMIN  # the pre window alone calls the wander an oscillation
    assert out["wander", 60] == 0.0
    assert out["swing", 60] > 1.0 * ARCMIN
    assert out["swing", 0] > out["swing", 60]


def test_a_switch_on_an_update_epoch_is_judged_beyond_the_updates_own_step(tmp_path, traj, truth):
    """A DUT whose 1 Hz fixes move its position by 0.6 m: a switch that falls on a fix
    epoch and moves it by 0.6 m has no excess; one that moves it by 2 m has 1.4 m."""
    t = _t()
    ts = t / S
    frame = (ts >= 51.0).astype(np.uint8)
    saw = 0.6 * (np.floor(ts) % 2)  # 0.6 m steps north on the whole seconds (up at 51 s)
    for extra, excess in ((0.0, 0.0), (1.4, 1.4)):
        north = saw + np.where(ts >= 51, extra, 0.0)
        pos = np.column_stack([0 * ts, north, 0 * ts])
        nav = nav_of(traj, t, pos_enu=pos, frame=frame)
        s = _scorer(tmp_path, traj, truth, nav, name=f"r{extra}.mcap")
        assert s.metric("frameswitch.step_position", ALL).value == pytest.approx(0.6, abs=1e-6)
        assert s.metric("frameswitch.jump_position", ALL).value == pytest.approx(0.6 + extra, abs=1e-6)
        assert s.metric("frameswitch.jump_excess_position", ALL).value == pytest.approx(excess, abs=1e-6)
        # the largest step after the switch over the largest before: 1 when nothing was added
        assert s.metric("frameswitch.step_after_position", ALL).value == pytest.approx(0.6 + extra, abs=1e-6)
        assert s.metric("frameswitch.step_ratio_position", ALL).value == pytest.approx((0.6 + extra) / 0.6, rel=1e-6)


def test_frame_switch_jump_oscillation_settling_ratio(tmp_path, traj, truth):
    t = _t()
    ts = t / S
    frame = (ts >= 50.0).astype(np.uint8)
    # position: 2 m east before, 2 m + 1.5 m north jump after; heading: 1' before,
    # then an oscillation 3' sin(2 pi (t - 50) / 20) for 40 s on top; velocity: 0.2 m/s jump
    pos = np.column_stack([np.full_like(ts, 2.0), np.where(ts >= 50, 1.5, 0.0), 0 * ts])
    osc = np.where((ts >= 50) & (ts < 90), 3 * ARCMIN * np.sin(2 * np.pi * (ts - 50) / 20), 0.0)
    att = np.column_stack([ARCMIN + osc, 0 * ts, 0 * ts])
    vel = np.column_stack([0 * ts, np.where(ts >= 50, 0.2, 0.0), 0 * ts])
    nav = nav_of(traj, t, pos_enu=pos, att=att, vel=vel, frame=frame)
    cmds = [{"t_ns": 49_950_000_000, "command": "grid"}]
    s = _scorer(tmp_path, traj, truth, nav, commands=cmds)
    assert s.metric("frameswitch.count", ALL).value == 1
    assert s.metric("frameswitch.count", ALL, {"to": "geographic"}).value == 0
    assert s.metric("frameswitch.jump_position", ALL).value == pytest.approx(1.5, abs=1e-6)
    assert s.metric("frameswitch.jump_velocity", ALL).value == pytest.approx(0.2, abs=1e-9)
    assert s.metric("frameswitch.jump_heading", ALL).value == pytest.approx(0.0, abs=1e-12)
    assert s.metric("frameswitch.step_position", ALL).value == pytest.approx(0.0, abs=1e-6)
    assert s.metric("frameswitch.jump_excess_position", ALL).value == pytest.approx(1.5, abs=1e-6)
    assert s.metric("frameswitch.amplitude_heading", ALL).value == pytest.approx(3 * ARCMIN, rel=1e-9)
    band = math.radians(0.1 / 60)  # the floor: the heading error was constant before
    assert s.metric("frameswitch.excess_heading", ALL).value == pytest.approx(3 * ARCMIN - band, rel=1e-9)
    # settles when the sine last leaves the 0.1' band: just before 90 s
    settle = s.metric("frameswitch.settling_heading", ALL).value
    assert 39.8 < settle < 40.0
    assert s.metric("frameswitch.amplitude_position", ALL).value == pytest.approx(1.5, abs=1e-6)
    assert s.metric("frameswitch.settling_position", ALL).value == math.inf  # never back
    ratio = math.sqrt(4 + 1.5**2) / 2.0
    assert s.metric("frameswitch.rms_ratio_position", ALL).value == pytest.approx(ratio, rel=1e-6)
    assert s.metric("frameswitch.delay", ALL).value == pytest.approx(0.05)
    sw = s.metric("frameswitch.count", ALL).details["switches"][0]
    assert sw["t_s"] == 50.0 and sw["to"] == "grid"


def test_no_switch_is_no_data(tmp_path, traj, truth):
    s = _scorer(tmp_path, traj, truth, nav_of(traj, _t()))
    assert s.metric("frameswitch.count", ALL).value == 0
    with pytest.raises(NoDataError, match="no navigation-frame switch"):
        s.metric("frameswitch.amplitude_heading", ALL)


# -- consistency -------------------------------------------------------------------------
def test_nees_against_sigmas(tmp_path, traj, truth):
    t = _t()
    nav = nav_of(traj, t, pos_enu=(2.0, 0.0, 0.0), vel=(0.0, 0.1, 0.0), att=(2 * ARCMIN, 0, 0))
    q = quality_of(nav, sigma_pos=(1.0, 1.0, 1.0), sigma_vel=(0.1, 0.1, 0.1), sigma_att=(ARCMIN,) * 3)
    s = _scorer(tmp_path, traj, truth, nav, q)
    assert s.metric("consistency.position.nees", ALL).value == pytest.approx(4.0 / 3.0, rel=1e-6)
    assert s.metric("consistency.velocity.nees", ALL).value == pytest.approx(1.0 / 3.0, rel=1e-6)
    assert s.metric("consistency.heading.nees", ALL).value == pytest.approx(4.0, rel=1e-6)
    lo, hi = chi2.ppf([0.025, 0.975], 1)
    assert lo < 4.0 < hi
    assert s.metric("consistency.heading.within", ALL).value == 1.0
    assert s.metric("consistency.heading.above", ALL).value == 0.0
    d = s.metric("consistency.heading.within", ALL).details
    assert (d["lower"], d["upper"]) == pytest.approx((lo, hi))
    # a tenth of the sigma: NEES 400, above the bound at every epoch
    q2 = quality_of(nav, sigma_att=(0.1 * ARCMIN,) * 3)
    s2 = _scorer(tmp_path, traj, truth, nav, q2, name="b.mcap")
    assert s2.metric("consistency.heading.above", ALL).value == 1.0


# -- output quality ----------------------------------------------------------------------
def test_output_rate_latency_missing_bad_frames(tmp_path, traj, truth):
    t = _t()
    keep = np.ones(len(t), dtype=bool)
    keep[1000:1010] = False  # 10 epochs lost at 10 s
    nav = nav_of(traj, t, latency_ns=3_000_000)[keep]
    nav["rx_ns"][2000:2100] += 47_000_000  # late for a second: 50 ms
    nav["valid"][:500] = 0
    bad = [{"t_ns": 5 * S, "link": "can", "kind": "crc"}, {"t_ns": 6 * S, "link": "can", "kind": "counter"}]
    s = _scorer(tmp_path, traj, truth, nav, quality_of(nav), bad_frames=bad)
    assert s.metric("output.rate", ALL).value == pytest.approx(9990 / 100)  # delivered in [0, 100 s)
    assert s.metric("output.median_rate", ALL).value == pytest.approx(100.0)
    assert s.metric("output.missing_epochs", ALL).value == 10
    assert s.metric("output.counter_gaps", ALL).value == 10
    assert s.metric("output.max_gap", ALL).value == pytest.approx(0.11)
    assert s.metric("output.missing_fraction", ALL).value == pytest.approx(10 / 10001)
    assert s.metric("output.latency_max", ALL).value == pytest.approx(0.05)
    assert s.metric("output.latency_mean", ALL).value == pytest.approx((0.003 * 9891 + 0.05 * 100) / 9991)
    assert s.metric("output.invalid_fraction", ALL).value == pytest.approx(500 / 9991)
    assert s.metric("output.bad_frames", ALL).value == 2
    assert s.metric("output.bad_frame_rate", ALL).value == pytest.approx(2 / 100)
    assert s.metric("output.bad_frames", ALL).details["by_kind"] == {"crc": 1, "counter": 1}
    assert s.metric("output.quality_unmatched", ALL).value == 0
    assert s.metric("output.out_of_order", ALL).value == 0


def test_output_stopping_early_counts_the_missing_tail(tmp_path, traj, truth):
    nav = nav_of(traj, _t(end_s=90))
    s = _scorer(tmp_path, traj, truth, nav)
    # epochs expected strictly between the last one and the window's edge: 90.01 .. 99.99 s
    assert s.metric("output.missing_epochs", ALL).value == 999
    assert s.metric("output.missing_epochs", WindowSpec("tail", start_ns=95 * S)).value == 499


def test_irregular_output_rate(tmp_path, traj, truth):
    t = np.cumsum(np.tile([8_000_000, 12_000_000, 10_000_000], 3400)) - 8_000_000
    t = t[t <= 100 * S]
    s = _scorer(tmp_path, traj, truth, nav_of(traj, t))
    assert s.metric("output.rate", ALL).value == pytest.approx(np.sum(t < 100 * S) / 100)
    assert s.metric("output.median_rate", ALL).value == pytest.approx(100.0)
    assert s.metric("output.mean_rate", ALL).value == pytest.approx((len(t) - 1) / ((t[-1] - t[0]) / S))
    assert s.metric("output.missing_epochs", ALL).value == 0


# -- integrity ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("status", "bench", "dut"),
    [("complete", 0, 0), ("dut_error", 1, 0), ("interrupted", 1, 0), ("timing_budget", 1, 0), ("link_lost", 1, 0),
     ("error", 1, 0), ("dut_failed", 0, 1)],
)
def test_run_end_status_splits_bench_and_dut(tmp_path, traj, truth, status, bench, dut):
    p = write_recording(tmp_path / "r.mcap", truth=truth, nav=nav_of(traj, _t()), status=status, reason="why")
    i = check_integrity(load_run(p))
    assert (len(i.bench), len(i.dut)) == (bench, dut)


def test_timing_budget_and_missing_topics(tmp_path, traj, truth):
    timing = np.zeros(100, dtype=[("t_ns", "<i8"), ("lateness_ns", "<i8")])
    timing["t_ns"] = np.arange(100) * 10_000_000
    timing["lateness_ns"][7] = 3_000_000
    p = write_recording(tmp_path / "r.mcap", truth=truth, nav=nav_of(traj, _t()), timing=timing)
    assert check_integrity(load_run(p), budget_ns=5_000_000).bench == []
    issues = check_integrity(load_run(p), budget_ns=2_000_000).bench
    assert len(issues) == 1 and "1 of 100" in issues[0]
    p2 = write_recording(tmp_path / "r2.mcap", truth=truth)
    assert any("no DUT output" in x for x in check_integrity(load_run(p2)).bench)
