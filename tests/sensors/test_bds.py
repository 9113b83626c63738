"""BDS receiver: lever arm and latency exact, 95 % figures, error split, sky and faults."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.faults.schedule import parse_schedule
from bench.faults.sensor import windows_for
from bench.nav import earth
from bench.scenario.loader import load_scenario
from bench.scenario.trajectory import SegmentInfo, truth_at
from bench.sensors.bds import BDS_PARAMS, R95_1D, R95_2D, BdsReceiver
from bench.sensors.params import resolve
from bench.sensors.processes import fit_markov
from tests.sensors.helpers import StaticTrajectory, run_all, run_windows

SHORT = Path(__file__).parents[1] / "data" / "short_drive.toml"
ERROR_FREE = {"horizontal_95": 0, "vertical_95": 0, "velocity_95": 0, "vertical_velocity_95": 0}


def receiver(seed=0, faults=(), **table):
    return BdsReceiver(resolve("bds", table, BDS_PARAMS), seed, faults=faults)


@pytest.fixture(scope="module")
def short_traj():
    return load_scenario(SHORT).trajectory()


def _errors_enu(rec, lat, lon, h):
    """The fix's offset from the truth: the ECEF difference in ENU at the truth (exact; the
    receiver applies its error so, which differs from a latitude/longitude linearisation by
    err^2 / 2R, 70 um for 30 m)."""
    d = earth.geodetic_to_ecef(rec["lat"], rec["lon"], rec["h"]) - earth.geodetic_to_ecef(lat, lon, h)
    return np.einsum("...ij,...j->...i", earth.C_en(lat, lon), d)


@pytest.mark.parametrize("rate", ["1 Hz", "5 Hz", "10 Hz"])
def test_lever_arm_and_latency_reproduce_exactly_without_errors(short_traj, rate):
    lever = np.array([0.5, 1.2, 1.8])
    m = receiver(rate=rate, lever_arm=["0.5 m", "1.2 m", "1.8 m"], latency="80 ms", **ERROR_FREE)
    rec = run_all(m, short_traj, window_s=4.3)
    hz = float(rate.split()[0])
    assert np.array_equal(rec["t_ns"], np.arange(1, int(90 * hz) + 1) * round(1e9 / hz))
    assert np.all(rec["tx_ns"] - rec["t_ns"] == 80_000_000)
    # antenna = IMU + C_bn l, through the local ENU frame of the IMU
    tr = truth_at(short_traj, rec["t_ns"])
    ant = np.array(
        [earth.enu_to_ecef(C @ lever, la, lo, hh) for C, la, lo, hh in zip(tr.C_bn, tr.lat, tr.lon, tr.h, strict=True)]
    )
    lat, lon, h = earth.ecef_to_geodetic(ant)
    err = _errors_enu(rec, lat, lon, h)
    assert np.max(np.abs(err)) < 1e-6

    # antenna velocity = time derivative of the antenna position (central differences)
    def ant_ecef(t_ns):
        trd = truth_at(short_traj, t_ns)
        return np.array(
            [
                earth.enu_to_ecef(C @ lever, la, lo, hh)
                for C, la, lo, hh in zip(trd.C_bn, trd.lat, trd.lon, trd.h, strict=True)
            ]
        )

    sel = rec[(rec["t_ns"] > 0) & (rec["t_ns"] < 90_000_000_000)][::3]
    d = 500_000
    v_e = (ant_ecef(sel["t_ns"] + d) - ant_ecef(sel["t_ns"] - d)) / (2 * d * 1e-9)
    trs = truth_at(short_traj, sel["t_ns"])
    v_n = np.einsum("nij,nj->ni", earth.C_en(trs.lat, trs.lon), v_e)
    np.testing.assert_allclose(sel["vel_n"], v_n, atol=2e-4)
    assert np.max(np.abs(sel["vel_n"] - trs.vel_n)) > 0.1  # the lever arm matters in the turns
    assert np.all(rec["fix_quality"] == 1) and np.all(rec["outage_style"] == 0)


@pytest.mark.slow
@pytest.mark.parametrize(("model", "h95", "v95"), [("seed001", 10.0, 10.0), ("seed001_asia_pacific", 5.0, 5.0)])
def test_long_static_run_matches_the_95_percent_figures(model, h95, v95):
    traj = StaticTrajectory(1_000_000.0)
    rec = run_all(receiver(seed=21, model=model, lever_arm=["0.5 m", "1.2 m", "1.8 m"]), traj, window_s=100_000.0)
    assert len(rec) == 1_000_000
    tr = truth_at(traj, rec["t_ns"][:1])
    ant = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h)[0] + earth.C_en(tr.lat[0], tr.lon[0]).T @ (
        tr.C_bn[0] @ [0.5, 1.2, 1.8]
    )
    lat, lon, h = earth.ecef_to_geodetic(ant)
    err = _errors_enu(rec, lat, lon, h)
    horiz = np.percentile(np.hypot(err[:, 0], err[:, 1]), 95)
    vert = np.percentile(np.abs(err[:, 2]), 95)
    vel = np.percentile(np.hypot(rec["vel_n"][:, 0], rec["vel_n"][:, 1]), 95)
    vvert = np.percentile(np.abs(rec["vel_n"][:, 2]), 95)
    assert horiz == pytest.approx(h95, rel=0.10)
    assert vert == pytest.approx(v95, rel=0.10)
    assert vel == pytest.approx(0.2, rel=0.10)
    assert vvert == pytest.approx(0.2, rel=0.10)
    # reported 1-sigma (GST) is the per-axis sigma of the 95 % figures
    assert rec["sigma_lat"][0] == pytest.approx(h95 / R95_2D) and rec["sigma_alt"][0] == pytest.approx(v95 / R95_1D)


@pytest.mark.slow
def test_white_and_markov_parts_have_the_configured_sigma_and_tau():
    traj = StaticTrajectory(1_000_000.0)
    rec = run_all(receiver(seed=8, model="seed001", velocity_markov_fraction=0.5), traj, window_s=200_000.0)
    err = rec["error_enu"]
    s_h, s_v = 10.0 / R95_2D, 10.0 / R95_1D
    for axis, s in ((0, s_h), (1, s_h), (2, s_v)):
        s_w, s_m, tau = fit_markov(err[:, axis], 1.0)
        assert s_w == pytest.approx(s * np.sqrt(0.2), rel=0.10)
        assert s_m == pytest.approx(s * np.sqrt(0.8), rel=0.10)
        assert tau == pytest.approx(60.0, rel=0.10)
    s_w, s_m, tau = fit_markov(rec["vel_error_enu"][:, 0], 1.0)
    assert s_w == pytest.approx(0.2 / R95_2D * np.sqrt(0.5), rel=0.10)
    assert s_m == pytest.approx(0.2 / R95_2D * np.sqrt(0.5), rel=0.10)
    assert tau == pytest.approx(5.0, rel=0.10)


def _sky_traj():
    segs = [
        SegmentInfo(0, "static", 0.0, 3000.0, gnss="open"),
        SegmentInfo(1, "static", 3000.0, 6000.0, gnss="urban"),
        SegmentInfo(2, "static", 6000.0, 6100.0, gnss="blocked"),
        SegmentInfo(3, "static", 6100.0, 7000.0, gnss="open"),
    ]
    return StaticTrajectory(7000.0, segments=segs)


def test_error_level_sigma_hdop_and_satellites_follow_the_sky():
    traj = _sky_traj()
    rec = run_all(receiver(seed=2, markov_fraction=0.0, urban_factor=2.5, reacquisition="10 s"), traj)
    t = rec["t_ns"] * 1e-9
    open_, urban = t < 3000, (t >= 3000) & (t < 6000)  # a segment holds its start time
    blocked = (t >= 6000) & (t < 6100)
    reacq = (t >= 6100) & (t < 6109)  # within 10 s of the last blocked epoch (6099 s)
    after = t >= 6109
    e = rec["error_enu"]
    assert np.std(e[urban, 0]) / np.std(e[open_, 0]) == pytest.approx(2.5, rel=0.1)
    assert np.all(rec["sigma_lat"][urban] == pytest.approx(2.5 * rec["sigma_lat"][0]))
    assert np.all(rec["hdop"][open_] == pytest.approx(0.8)) and np.all(rec["hdop"][urban] == pytest.approx(2.0))
    assert np.all(rec["num_sats"][open_] == 16) and np.all(rec["num_sats"][urban] == 6)
    nofix = blocked | reacq
    assert np.all(rec["fix_quality"][nofix] == 0) and np.all(rec["outage_style"][nofix] == 1)
    assert np.all(np.isnan(rec["lat"][nofix])) and np.all(np.isnan(rec["hdop"][nofix]))
    assert np.all(rec["num_sats"][nofix] == 0)
    assert np.all(rec["fix_quality"][after] == 1) and not np.any(np.isnan(rec["lat"][after]))
    assert reacq.sum() == 9
    silent = run_all(receiver(outage_style="silent"), traj)
    assert np.all(silent["outage_style"][blocked] == 2) and np.all(silent["outage_style"][~blocked] == 0)


def test_scheduled_outage_jump_drift_and_multipath():
    tables = [
        {"start": "10 s", "end": "20 s", "target": "bds", "kind": "outage"},
        {"start": "30 s", "end": "40 s", "target": "bds", "kind": "outage", "params": {"style": "silent"}},
        {"start": "50 s", "end": "55 s", "target": "bds", "kind": "jump", "params": {"east": "30 m", "up": "-5 m"}},
        {"start": "60 s", "end": "70 s", "target": "bds", "kind": "drift", "params": {"north": "0.5 m/s"}},
        {"start": "80 s", "end": "90 s", "target": "bds", "kind": "multipath", "params": {"azimuth": "90 deg"}},
    ]
    sched = parse_schedule(tables)
    traj = StaticTrajectory(100.0)
    rec = run_all(receiver(faults=windows_for(sched, "bds"), rate="5 Hz", **ERROR_FREE), traj, window_s=3.0)
    t = rec["t_ns"]
    tr = truth_at(traj, t)
    err = _errors_enu(rec, tr.lat, tr.lon, tr.h)

    def win(a, b):
        return (t >= a * 1e9) & (t < b * 1e9)

    assert np.all(rec["outage_style"][win(10, 20)] == 1) and np.all(rec["outage_style"][win(30, 40)] == 2)
    assert np.all(rec["fix_quality"][win(10, 20) | win(30, 40)] == 0)
    np.testing.assert_allclose(err[win(50, 55)], np.tile([30.0, 0.0, -5.0], (25, 1)), atol=1e-6)
    d = win(60, 70)
    np.testing.assert_allclose(err[d, 1], 0.5 * (t[d] * 1e-9 - 60.0), atol=1e-6)
    np.testing.assert_allclose(rec["vel_n"][d, 1], 0.5)
    mp = win(80, 90)
    np.testing.assert_allclose(err[mp], np.tile([5.0, 0.0, 0.0], (50, 1)), atol=1e-6)
    assert np.all(rec["hdop"][mp] == pytest.approx(2.4)) and np.all(rec["num_sats"][mp] == 5)
    quiet = ~(win(10, 20) | win(30, 40) | win(50, 55) | win(60, 70) | win(80, 90))
    assert np.max(np.abs(err[quiet])) < 1e-6 and np.all(rec["fix_quality"][quiet] == 1)


def test_output_does_not_depend_on_the_windows():
    traj = _sky_traj()
    kw = {"model": "seed001", "reacquisition": "3 s"}
    a = run_all(receiver(seed=6, **kw), traj, window_s=500.0)
    b = run_windows(receiver(seed=6, **kw), traj, [0.5, 0.6, 6050.0, 6101.5, 6102.0])
    assert np.array_equal(a.view(np.uint8), b.view(np.uint8))  # NaNs included


def test_rate_must_be_1_5_or_10_hz():
    with pytest.raises(ConfigError, match="1, 5 or 10 Hz"):
        receiver(rate="2 Hz")
