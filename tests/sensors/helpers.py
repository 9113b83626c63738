"""Analytic trajectories and run helpers for the aiding-sensor tests.

Long statistical runs (10^5..10^6 s) cannot use motion scripts (their 1 kHz position
grid would take gigabytes), so these trajectories are closed-form: a vehicle standing
still, and one driving due east along the equator (a great circle, so a constant
heading and speed are an exact, consistent motion).
"""

from __future__ import annotations

import itertools

import numpy as np

from bench.nav import earth
from bench.scenario.trajectory import Kinematics, SegmentInfo, Trajectory
from bench.sensors.base import SensorModel


class StaticTrajectory(Trajectory):
    """At rest at (lat, lon, h) with the given attitude (rad)."""

    def __init__(self, duration_s, lat=0.6, lon=1.9, h=100.0, euler=(0.5, 0.0, 0.0), segments=None):
        self.duration_s = float(duration_s)
        self.p = (lat, lon, h)
        self.euler = np.asarray(euler, dtype=float)
        self._segments = segments

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        n = len(t)
        lat, lon, h = self.p
        z = np.zeros((n, 3))
        return Kinematics(
            t, np.full(n, lat), np.full(n, lon), np.full(n, h), z, z.copy(), np.tile(self.euler, (n, 1)), z.copy()
        )

    def segments(self):
        return self._segments or super().segments()


class EquatorTrajectory(Trajectory):
    """Due east along the equator at constant ``speed`` (m/s), height ``h``.

    ``segments`` (optional) are ``(start_s, end_s, surface, gnss)`` tuples.
    """

    def __init__(self, duration_s, speed=20.0, h=0.0, lon0=0.0, segments=None, wheel=None):
        self.duration_s = float(duration_s)
        self.speed = float(speed)
        self.h = float(h)
        self.lon0 = float(lon0)
        self._wheel = wheel
        self._segments = [
            SegmentInfo(i, "uniform", a, b, gnss=g, surface=s) for i, (a, b, s, g) in enumerate(segments or [])
        ]

    def kinematics(self, t):
        t = np.asarray(t, dtype=float)
        n = len(t)
        vel = np.zeros((n, 3))
        vel[:, 0] = self.speed
        lon = self.lon0 + self.speed * t / (earth.A + self.h)
        euler = np.zeros((n, 3))
        euler[:, 0] = np.pi / 2
        return Kinematics(t, np.zeros(n), lon, np.full(n, self.h), vel, np.zeros((n, 3)), euler, np.zeros((n, 3)))

    def segments(self):
        return self._segments or super().segments()

    def wheel_speed(self, t):
        return None if self._wheel is None else self._wheel(np.asarray(t, dtype=float))


def run_all(model: SensorModel, traj: Trajectory, window_s: float = 1000.0, topic: str | None = None) -> np.ndarray:
    """Every record of ``model`` over ``traj``, run in windows of ``window_s``."""
    parts = []
    step = round(window_s * 1e9)
    t0 = 0
    topic = topic or model.topics()[0].topic
    while t0 < traj.duration_ns:
        t1 = min(t0 + step, traj.duration_ns)
        out = model.run(traj, t0, t1)
        if topic in out:
            parts.append(out[topic])
        t0 = t1
    return np.concatenate(parts)


def run_windows(model: SensorModel, traj: Trajectory, cuts_s, topic: str | None = None) -> np.ndarray:
    """Records over ``traj`` with the run cut at the given times (s)."""
    topic = topic or model.topics()[0].topic
    edges = [0, *[round(c * 1e9) for c in cuts_s], traj.duration_ns]
    parts = [model.run(traj, a, b).get(topic) for a, b in itertools.pairwise(edges)]
    return np.concatenate([p for p in parts if p is not None])
