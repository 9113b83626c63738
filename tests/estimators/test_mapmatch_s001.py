"""The shipped S001 network: it regenerates identically, and the matcher keeps the S001 truth
track plus 3 m Gaussian noise on the route (>= 99 %, no distractor episode over 2 s)."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.estimators.mapmatch import OnlineMatcher, RoadNetwork, match
from bench.roadgen import network_doc
from bench.scenario.loader import load_scenario

NET = Path(__file__).parents[2] / "test_cases" / "scenarios" / "S001_roads.geojson"


@pytest.fixture(scope="module")
def truth():
    traj = load_scenario("S001").trajectory()
    t = np.arange(0.0, traj.duration_ns * 1e-9, 1.0)
    return t, traj.kinematics(t)


def test_network_file_is_current():
    assert json.loads(NET.read_text()) == json.loads(json.dumps(network_doc("S001")))


def _episodes(flags, dt=1.0):
    best = run = 0
    for f in flags:
        run = run + 1 if f else 0
        best = max(best, run)
    return best * dt


def test_s001_noisy_truth_is_matched_on_the_route(truth):
    t, k = truth
    net = RoadNetwork.from_geojson(NET)
    rng = np.random.default_rng(13)
    en = net.to_enu(k.lat, k.lon) + rng.normal(0.0, 3.0, (t.size, 2))
    lat, lon = net.lat0 + en[:, 1] / 6378137.0, net.lon0 + en[:, 0] / (6378137.0 * math.cos(net.lat0))
    speed = np.hypot(k.vel_n[:, 0], k.vel_n[:, 1])
    hdg = k.euler[:, 0] + rng.normal(0.0, math.radians(3), t.size)
    out = match(OnlineMatcher(net, sigma_distance=5.0, lag=2), (t * 1e9).astype(np.int64), lat, lon, hdg, speed)
    true_en = net.to_enu(k.lat, k.lon)
    seg, _ = net.nearest(true_en[:, 0], true_en[:, 1], mask=net.is_route)
    m_en = np.array([net.to_enu(m.lat, m.lon) for m in out])
    lat_m, _ = net.project(seg, m_en[:, 0], m_en[:, 1])
    lat_raw, _ = net.project(seg, en[:, 0], en[:, 1])
    on_m, on_raw = np.mean(lat_m < 5.0), np.mean(lat_raw < 5.0)
    print(f"on-road within 5 m: matched {on_m:.4f}, unmatched {on_raw:.4f}")
    assert on_m >= 0.99
    assert on_raw < on_m
    assert _episodes([m.role == "distractor" for m in out]) <= 2.0
