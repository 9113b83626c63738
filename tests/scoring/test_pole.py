"""Scoring a drive over the North Pole (S003d): the truth is interpolated in ECEF and the
DUT's velocity and attitude are taken into the truth's ENU frame before differencing, so a
right DUT scores zero at and around the pole and a known error is scored as itself before,
at and after it, whatever the DUT's position error."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.rotation import dcm_to_euler, euler_to_dcm, quat_to_dcm, wrap_2pi
from bench.scenario.loader import load_scenario
from bench.scenario.trajectory import truth_at
from bench.scoring.align import interpolate_truth, nav_errors
from bench.scoring.polar import between_frames, is_polar
from bench.topics import NAV_SOLUTION_DTYPE
from tests.scoring.helpers import ARCMIN, drive, truth_of

S003D = Path(__file__).resolve().parents[2] / "test_cases" / "scenarios" / "S003d_over_the_pole.toml"
T_POLE_NS = 167_540_000_000  # the 10 ms truth sample nearest the pole


@pytest.fixture(scope="module")
def traj():
    return load_scenario(S003D).trajectory()


@pytest.fixture(scope="module")
def truth(traj):
    return truth_of(traj)


def _times() -> np.ndarray:
    """DUT epochs off the truth grid, dense around the pole crossing, and one on it."""
    coarse = np.arange(3_000_000, 599_000_000_000, 997_000_000)
    dense = np.arange(T_POLE_NS - 2_000_000_000, T_POLE_NS + 2_000_000_000, 1_300_000)
    return np.unique(np.concatenate([coarse, dense, [T_POLE_NS]]))


def _nav(traj, t_ns, pos_enu=(0.0, 0.0, 0.0), vel=(0.0, 0.0, 0.0), att=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A DUT at the truth plus errors given in the truth's ENU frame, reporting (as a real
    one does) in the ENU frame at its own position."""
    tr = truth_at(traj, t_ns)
    n = len(t_ns)
    x = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h)
    x = x + np.einsum("nji,nj->ni", earth.C_en(tr.lat, tr.lon), np.broadcast_to(pos_enu, (n, 3)))
    lat, lon, h = earth.ecef_to_geodetic(x)
    a = np.broadcast_to(np.asarray(att, dtype=float), (n, 3))
    C = euler_to_dcm(tr.euler[:, 0] + a[:, 0], tr.euler[:, 1] + a[:, 1], tr.euler[:, 2] + a[:, 2])
    v, C = between_frames(lat, lon, tr.lat, tr.lon, tr.vel_n + np.asarray(vel, dtype=float), C)
    psi, theta, gamma = dcm_to_euler(C)
    rec = np.zeros(n, dtype=NAV_SOLUTION_DTYPE)
    rec["t_ns"], rec["rx_ns"] = t_ns, t_ns
    rec["lat"], rec["lon"], rec["h"] = lat, lon, h
    rec["vel_n"] = v
    rec["heading"], rec["pitch"], rec["roll"] = wrap_2pi(psi), theta, gamma
    rec["valid"] = 1
    return rec


def _q_be(lat, lon, q_bn) -> np.ndarray:
    return np.swapaxes(earth.C_en(lat, lon), -1, -2) @ quat_to_dcm(q_bn)


def test_the_pole_truth_is_polar_and_ordinary_drives_are_not(truth):
    assert is_polar(truth["lat"])
    assert not is_polar(truth_of(drive(lat=88.5, duration=20.0))["lat"])


def test_truth_interpolation_through_the_pole(traj, truth):
    t = _times()
    tr = interpolate_truth(truth, t)
    ex = truth_at(traj, t)
    assert tr.polar and np.all(tr.covered)
    d = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h) - earth.geodetic_to_ecef(ex.lat, ex.lon, ex.h)
    assert np.max(np.linalg.norm(d, axis=1)) < 1e-6  # m
    v_i = np.einsum("nji,nj->ni", earth.C_en(tr.lat, tr.lon), tr.vel_n)
    v_x = np.einsum("nji,nj->ni", earth.C_en(ex.lat, ex.lon), ex.vel_n)
    assert np.max(np.abs(v_i - v_x)) < 1e-6  # m/s, ECEF
    dC = _q_be(tr.lat, tr.lon, tr.q_bn) - _q_be(ex.lat, ex.lon, ex.q_bn)
    assert np.max(np.abs(dC)) < 1e-9  # the Earth-fixed attitude
    assert np.all((tr.lon > -np.pi) & (tr.lon <= np.pi))


def test_a_right_dut_scores_zero_at_and_around_the_pole(traj, truth):
    t = _times()
    e = nav_errors(truth, _nav(traj, t))
    assert np.all(e.usable)
    assert np.max(np.abs(e.pos)) < 1e-6
    assert np.max(np.abs(e.vel)) < 1e-6
    assert np.max(np.abs(e.att)) < 1e-9
    assert np.max(e.att_angle) < 1e-9


@pytest.mark.parametrize("pos_enu", [(0.0, 0.0, 0.0), (3.0, -2.0, 1.0)])
def test_a_one_arcmin_heading_error_is_one_arcmin_before_at_and_after_the_pole(traj, truth, pos_enu):
    """With a 3.6 m position error the DUT's own ENU frame turns by up to 180 deg from the
    truth's near the pole; its heading is still scored as the 1' it is off."""
    t = _times()
    e = nav_errors(truth, _nav(traj, t, pos_enu=pos_enu, vel=(0.05, -0.02, 0.0), att=(ARCMIN, 0.0, 0.0)))
    np.testing.assert_allclose(e.att[:, 0], ARCMIN, atol=1e-9)
    np.testing.assert_allclose(e.att[:, 1:], 0.0, atol=1e-9)
    np.testing.assert_allclose(e.att_angle, ARCMIN, atol=1e-9)
    np.testing.assert_allclose(e.vel, np.tile([0.05, -0.02, 0.0], (len(t), 1)), atol=1e-6)
    np.testing.assert_allclose(e.pos, np.tile(pos_enu, (len(t), 1)), atol=1e-6)
    for when in (t < 160e9, np.abs(t - T_POLE_NS) < 50_000_000, t > 175e9):
        assert when.sum() >= 1 and np.all(np.abs(e.att[when, 0] - ARCMIN) < 1e-9)
    if any(pos_enu):  # the reported heading itself is far from truth + 1' at the pole
        nav = _nav(traj, t, pos_enu=pos_enu, att=(ARCMIN, 0.0, 0.0))
        raw = np.abs((nav["heading"] - truth_at(traj, t).euler[:, 0] + np.pi) % (2 * np.pi) - np.pi)
        assert raw.max() > math.radians(10.0)
