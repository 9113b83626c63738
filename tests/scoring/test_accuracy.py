"""Accuracy metrics against hand-computed values, from recordings written by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.scenario.trajectory import truth_at
from bench.scoring.align import interpolate_truth, nav_errors
from bench.scoring.data import DutDataError, NoDataError, load_run
from bench.scoring.metrics import Scorer, ScoringSettings
from bench.scoring.windows import WindowSpec
from tests.scoring.helpers import ARCMIN, drive, nav_of, segments_of, truth_of, write_recording

ALL = WindowSpec("all")


@pytest.fixture(scope="module")
def traj():
    return drive(speed=10.0, duration=100.0, turn=True)


@pytest.fixture(scope="module")
def truth(traj):
    return truth_of(traj)


def _scorer(tmp_path, traj, truth, nav, **kw):
    path = write_recording(tmp_path / "r.mcap", truth=truth, nav=nav, segments=segments_of(traj), **kw)
    return Scorer(load_run(path), ScoringSettings(convergence_ns=20_000_000_000))


def test_constant_position_error_statistics(tmp_path, traj, truth):
    t = np.arange(0, 100_000_000_001, 10_000_000)
    nav = nav_of(traj, t, pos_enu=(3.0, 4.0, -2.0))
    s = _scorer(tmp_path, traj, truth, nav)
    for stat in ("rms", "mean", "max", "p50", "p95", "cep50", "cep95", "final"):
        assert s.metric(f"accuracy.horizontal.{stat}", ALL).value == pytest.approx(5.0, abs=1e-6)
    assert s.metric("accuracy.horizontal.std", ALL).value == pytest.approx(0.0, abs=1e-6)
    assert s.metric("accuracy.vertical.mean", ALL).value == pytest.approx(-2.0, abs=1e-6)
    assert s.metric("accuracy.vertical.max", ALL).value == pytest.approx(2.0, abs=1e-6)
    assert s.metric("accuracy.position.r95", ALL).value == pytest.approx(math.sqrt(29.0), abs=1e-6)
    assert s.metric("accuracy.east.mean", ALL).value == pytest.approx(3.0, abs=1e-6)
    assert s.metric("accuracy.north.mean", ALL).value == pytest.approx(4.0, abs=1e-6)
    assert s.metric("accuracy.horizontal.growth", ALL).value == pytest.approx(0.0, abs=1e-6)


def test_series_statistics_match_hand_values(tmp_path, traj, truth):
    # east error 0, 1, 2, ... 9 m repeating each second, north 0
    t = np.arange(0, 100_000_000_001, 100_000_000)
    e = (np.arange(len(t)) % 10).astype(float)
    nav = nav_of(traj, t, pos_enu=np.column_stack([e, np.zeros_like(e), np.zeros_like(e)]))
    s = _scorer(tmp_path, traj, truth, nav)
    assert s.metric("accuracy.horizontal.rms", ALL).value == pytest.approx(math.sqrt(np.mean(e * e)), abs=1e-6)
    assert s.metric("accuracy.east.std", ALL).value == pytest.approx(np.std(e), abs=1e-6)
    assert s.metric("accuracy.horizontal.p50", ALL).value == pytest.approx(np.percentile(e, 50), abs=1e-6)
    assert s.metric("accuracy.horizontal.max", ALL).value == pytest.approx(9.0, abs=1e-6)
    assert s.metric("accuracy.horizontal.final", ALL).value == pytest.approx(e[-1], abs=1e-6)


def test_growth_and_distance_fraction(tmp_path, traj, truth):
    # a drift of 0.1 m/s north through the blocked last 35 s (after the turn), none before
    blocked = next(seg for seg in traj.segments() if seg.gnss == "blocked")
    assert (blocked.start_s, blocked.end_s) == (65.0, 100.0)
    t = np.arange(0, 100_000_000_001, 10_000_000)
    ts = t * 1e-9
    north = np.where(ts >= 65.0, 0.1 * (ts - 65.0), 0.0)
    nav = nav_of(traj, t, pos_enu=np.column_stack([np.zeros_like(ts), north, np.zeros_like(ts)]))
    s = _scorer(tmp_path, traj, truth, nav)
    outages = WindowSpec("outages", gnss=("blocked",))
    assert s.metric("accuracy.horizontal.growth", outages).value == pytest.approx(3.5, abs=1e-6)
    assert s.metric("accuracy.horizontal.max", outages).value == pytest.approx(3.5, abs=1e-6)
    assert s.metric("accuracy.horizontal.growth", WindowSpec("first", end_ns=65_000_000_000)).value < 1e-6
    # 10 m/s for 35 s = 350 m driven in the window: 3.5 m is 1 %
    assert s.metric("accuracy.horizontal.of_distance", outages).value == pytest.approx(0.01, rel=1e-6)


def test_heading_error_wraps_at_north(tmp_path):
    traj = drive(heading_deg=359.95, duration=40.0)  # heading crosses 0 deg only by the error
    truth = truth_of(traj)
    t = np.arange(0, 40_000_000_001, 10_000_000)
    nav = nav_of(traj, t, att=(math.radians(0.1), 0.0, 0.0))
    tr = truth_at(traj, t)
    assert np.all(tr.euler[:, 0] > math.radians(359.9))
    assert np.all(nav["heading"] < math.radians(0.1))  # the DUT says 0.05 deg, truth 359.95
    s = _scorer(tmp_path, traj, truth, nav)
    assert s.metric("accuracy.heading.mean", ALL).value == pytest.approx(math.radians(0.1), abs=1e-9)
    assert s.metric("accuracy.heading.max", ALL).value == pytest.approx(6.0 * ARCMIN, abs=1e-9)


def test_heading_error_wraps_the_other_way(tmp_path):
    traj = drive(heading_deg=0.05, duration=40.0)
    truth = truth_of(traj)
    t = np.arange(0, 40_000_000_001, 10_000_000)
    nav = nav_of(traj, t, att=(math.radians(-0.1), 0.0, 0.0))
    assert np.all(nav["heading"] > math.radians(359.9))
    s = _scorer(tmp_path, traj, truth, nav)
    assert s.metric("accuracy.heading.mean", ALL).value == pytest.approx(math.radians(-0.1), abs=1e-9)


def test_late_and_irregular_dut_is_aligned_on_time_of_validity(tmp_path, traj, truth):
    rng = np.random.default_rng(5)
    t = np.sort(rng.integers(0, 100_000_000_000, 3000))  # irregular, off the truth grid
    nav = nav_of(traj, t, pos_enu=(1.0, 0.0, 0.0), att=(ARCMIN, 0.0, 0.0), latency_ns=250_000_000)
    s = _scorer(tmp_path, traj, truth, nav)
    # truth interpolated to the DUT's times: the injected errors come back whatever the timing
    assert s.metric("accuracy.horizontal.max", ALL).value == pytest.approx(1.0, abs=1e-4)
    assert s.metric("accuracy.heading.max", ALL).value == pytest.approx(ARCMIN, abs=1e-7)
    assert s.metric("accuracy.velocity.max", ALL).value < 1e-4
    assert s.metric("output.latency_mean", ALL).value == pytest.approx(0.25)


def test_truth_interpolation_on_so3_and_hermite(traj, truth):
    t = np.arange(5_000_000, 99_000_000_000, 7_300_000)  # never on the 10 ms grid
    tr = interpolate_truth(truth, t)
    exact = truth_at(traj, t)
    from bench.nav import earth

    d = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h) - earth.geodetic_to_ecef(exact.lat, exact.lon, exact.h)
    assert np.max(np.linalg.norm(d, axis=1)) < 1e-6  # m, through the 10 deg/s turn
    assert np.max(np.abs(tr.vel_n - exact.vel_n)) < 1e-6  # m/s
    dpsi = (tr.euler[:, 0] - exact.euler[:, 0] + np.pi) % (2 * np.pi) - np.pi
    assert np.max(np.abs(dpsi)) < 1e-9  # rad: rate-matched interpolation on SO(3)
    assert np.all(tr.covered)


def test_epochs_outside_the_truth_are_not_scored(traj, truth):
    t = np.array([-10_000_000, 0, 50_000_000_000, 100_000_000_000, 100_010_000_000])
    nav = nav_of(traj, np.clip(t, 0, 100_000_000_000))
    nav["t_ns"] = t
    e = nav_errors(truth, nav)
    assert e.covered.tolist() == [False, True, True, True, False]
    assert e.usable.tolist() == [False, True, True, True, False]


def test_window_without_dut_epochs_is_no_data_not_zero(tmp_path, traj, truth):
    t = np.arange(0, 40_000_000_001, 10_000_000)  # the DUT stopped at 40 s
    s = _scorer(tmp_path, traj, truth, nav_of(traj, t))
    with pytest.raises(NoDataError, match="no DUT epoch"):
        s.metric("accuracy.horizontal.rms", WindowSpec("late", start_ns=60_000_000_000))
    with pytest.raises(NoDataError, match="selects no time"):
        s.metric("accuracy.horizontal.rms", WindowSpec("none", kinds=("climb",)))


def test_all_invalid_in_window_is_the_duts_failure(tmp_path, traj, truth):
    t = np.arange(0, 100_000_000_001, 10_000_000)
    nav = nav_of(traj, t)
    nav["valid"][t >= 50_000_000_000] = 0
    s = _scorer(tmp_path, traj, truth, nav)
    with pytest.raises(DutDataError, match="invalid"):
        s.metric("accuracy.horizontal.rms", WindowSpec("late", start_ns=60_000_000_000))
    assert s.metric("accuracy.horizontal.rms", WindowSpec("early", end_ns=40_000_000_000)).value < 1e-6


def test_attitude_angle_on_so3(tmp_path, traj, truth):
    t = np.arange(0, 100_000_000_001, 100_000_000)
    nav = nav_of(traj, t, att=(0.0, 3 * ARCMIN, 4 * ARCMIN))
    s = _scorer(tmp_path, traj, truth, nav)
    assert s.metric("accuracy.attitude.max", ALL).value == pytest.approx(5 * ARCMIN, rel=1e-3)
    assert s.metric("accuracy.level.max", ALL).value == pytest.approx(4 * ARCMIN, abs=1e-9)
