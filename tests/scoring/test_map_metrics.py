"""Map metrics on a straight route with a parallel distractor 20 m north."""

import math

import numpy as np

from bench.scoring.mapmetrics import map_metrics
from bench.scoring.roadmap import RoadNetwork

LAT0, LON0 = math.radians(29.72), math.radians(106.63)


def _net():
    def ll(e, n):
        return np.array([[math.degrees(LON0 + x / (6378137.0 * math.cos(LAT0))), math.degrees(LAT0 + y / 6378137.0)]
                         for x, y in zip(e, n, strict=True)])
    lines = [("r", "route", None, ll([0, 1000], [0, 0])), ("p", "distractor", None, ll([0, 1000], [20, 20]))]
    return RoadNetwork(lines, (LAT0, LON0))


def test_on_the_road_and_a_3_s_distractor_episode():
    net = _net()
    t = np.arange(0, 60, 1.0)
    truth = np.stack([10 * t, np.zeros_like(t)], axis=1)
    m = map_metrics(net, t, truth + np.array([0.0, 1.0]), truth, 5.0)
    assert m["on_road"] == 1.0 and abs(m["lateral.rms"] - 1.0) < 1e-9 and m["distractor_max"] == 0.0
    dut = truth.copy()
    dut[10:13, 1] = 19.0
    m = map_metrics(net, t, dut, truth, 5.0)
    assert abs(m["on_road"] - 57 / 60) < 1e-12
    assert m["distractor_max"] == 3.0 and m["lateral.max"] == 19.0
