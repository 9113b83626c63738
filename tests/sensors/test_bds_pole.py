"""BDS receiver at and over the North Pole: the ENU error is applied in ECEF, so a fix at
the pole is offset by exactly the drawn error (nothing divides by cos(lat)), with the same
draws, hence the same statistics, as anywhere else; the velocity is reported in the ENU
frame of the reported position."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.nav import earth
from bench.scenario.loader import load_scenario
from bench.scenario.trajectory import truth_at
from bench.sensors.bds import BDS_PARAMS, R95_2D, BdsReceiver
from bench.sensors.params import resolve
from tests.sensors.helpers import StaticTrajectory, run_all

S003D = Path(__file__).resolve().parents[2] / "test_cases" / "scenarios" / "S003d_over_the_pole.toml"


def receiver(seed=0, **table):
    return BdsReceiver(resolve("bds", table, BDS_PARAMS), seed)


def _offset_enu(rec, lat, lon, h):
    """The fix's offset from (lat, lon, h): ECEF difference in ENU there, m."""
    d = earth.geodetic_to_ecef(rec["lat"], rec["lon"], rec["h"]) - earth.geodetic_to_ecef(lat, lon, h)
    return np.einsum("...ij,...j->...i", earth.C_en(lat, lon), d)


@pytest.mark.parametrize("lat", [np.pi / 2, np.radians(89.9999999)])
def test_a_fix_at_the_pole_carries_the_same_errors_as_at_mid_latitude(lat):
    polar = run_all(receiver(seed=4, model="seed001"), StaticTrajectory(2000.0, lat=lat, lon=0.3, h=20.0))
    mid = run_all(receiver(seed=4, model="seed001"), StaticTrajectory(2000.0, lat=0.7, lon=0.3, h=20.0))
    assert len(polar) == len(mid) == 2000
    for f in ("lat", "lon", "h", "vel_n"):
        assert np.all(np.isfinite(polar[f])), f
    # the same draws ...
    np.testing.assert_array_equal(polar["error_enu"], mid["error_enu"])
    np.testing.assert_array_equal(polar["vel_error_enu"], mid["vel_error_enu"])
    # ... put the fix exactly where they say, at the pole as at 40 deg
    tr_p = truth_at(StaticTrajectory(1.0, lat=lat, lon=0.3, h=20.0), np.array([0]))
    np.testing.assert_allclose(_offset_enu(polar, tr_p.lat[0], tr_p.lon[0], tr_p.h[0]), polar["error_enu"], atol=1e-6)
    tr_m = truth_at(StaticTrajectory(1.0, lat=0.7, lon=0.3, h=20.0), np.array([0]))
    np.testing.assert_allclose(_offset_enu(mid, tr_m.lat[0], tr_m.lon[0], tr_m.h[0]), mid["error_enu"], atol=1e-6)
    # the horizontal 95 % figure of the model (10 m for seed001) holds at the pole
    horiz = np.hypot(polar["error_enu"][:, 0], polar["error_enu"][:, 1])
    assert np.percentile(horiz, 95) == pytest.approx(10.0, rel=0.25)
    assert polar["sigma_lat"][0] == pytest.approx(10.0 / R95_2D)


def test_velocity_at_the_pole_is_the_drawn_error_in_the_fixs_frame():
    """At rest on the pole: the reported ENU velocity, taken to ECEF through the reported
    position's frame, is the drawn ENU error taken to ECEF through the truth's frame."""
    rec = run_all(receiver(seed=9, model="seed001"), StaticTrajectory(300.0, lat=np.pi / 2, lon=-2.0, h=5.0))
    v_fix = np.einsum("nji,nj->ni", earth.C_en(rec["lat"], rec["lon"]), rec["vel_n"])
    v_true = earth.C_en(np.pi / 2, -2.0).T @ rec["vel_error_enu"].T
    np.testing.assert_allclose(v_fix, v_true.T, atol=1e-12)


def test_fixes_over_the_pole_follow_the_truth():
    traj = load_scenario(S003D).trajectory()
    rec = run_all(receiver(seed=2, model="seed001", rate="10 Hz"), traj, window_s=100.0)
    assert len(rec) == 6000
    for f in ("lat", "lon", "h", "vel_n"):
        assert np.all(np.isfinite(rec[f])), f
    tr = truth_at(traj, rec["t_ns"])
    np.testing.assert_allclose(_offset_enu(rec, tr.lat, tr.lon, tr.h), rec["error_enu"], atol=1e-6)
    # the velocity error, seen in ECEF, is the drawn one; in the fix's frame it may turn
    # by a large angle about the vertical within metres of the pole
    v_fix = np.einsum("nji,nj->ni", earth.C_en(rec["lat"], rec["lon"]), rec["vel_n"])
    v_true = np.einsum("nji,nj->ni", earth.C_en(tr.lat, tr.lon), tr.vel_n + rec["vel_error_enu"])
    np.testing.assert_allclose(v_fix, v_true, atol=1e-9)
