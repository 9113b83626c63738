"""Faults that move the vehicle: a trajectory with sideslips and bumps added to the truth.

An odometer ``sideslip`` window makes the body slide sideways: a lateral body velocity
``v_lat(t)`` along the body x axis (right), rising and falling by quintic smoothsteps
over ``ramp`` seconds, whose displacement stays after the window (the vehicle has slid).
An odometer ``bump`` window lifts the body by ``height * 64 (x (1 - x))^3`` along the
local vertical (x = 0..1 over the window). Velocities and accelerations get the exact
derivatives of these offsets, so the IMU increments, the Doppler radar and the BDS
receiver sense the motion as they would on a vehicle, while the odometer (which measures
its wheel) does not see the slide.

Position offsets of a sideslip are integrated on a 1 kHz grid in latitude, longitude
and height (``dlat/dt = v_N / (R_M + h)``...) and read between grid points by cubic
Hermite interpolation with the exact rates, as the motion scripts do.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from bench.faults.schedule import FaultSchedule, FaultWindow
from bench.faults.sensor import MOTION_KINDS, bump_shape
from bench.nav import earth
from bench.nav.rotation import euler_rates_to_omega_nb_b, euler_to_dcm
from bench.scenario.trajectory import Kinematics, SegmentInfo, Trajectory

__all__ = ["FaultedTrajectory", "with_motion_faults", "motion_windows"]

_GRID_HZ = 1000.0


def motion_windows(schedule: FaultSchedule | Iterable[FaultWindow] | None) -> list[FaultWindow]:
    """The sensor-layer windows that move the body (odometer sideslip and bump)."""
    if schedule is None:
        return []
    return [w for w in schedule if w.layer == "sensor" and w.target.startswith("odometer") and w.kind in MOTION_KINDS]


def with_motion_faults(traj: Trajectory, schedule: FaultSchedule | Iterable[FaultWindow] | None) -> Trajectory:
    """``traj`` with the schedule's body motions added (``traj`` itself when there are none)."""
    windows = motion_windows(schedule)
    if not windows or isinstance(traj, FaultedTrajectory):
        return traj
    return FaultedTrajectory(traj, windows)


def _smooth(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quintic smoothstep and its derivative on [0, 1] (clipped outside)."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x), 30.0 * x * x * (1.0 - x) ** 2


class _Slide:
    """One sideslip window: lateral speed profile and its integrated position offsets."""

    def __init__(self, base: Trajectory, w: FaultWindow):
        self.t0 = w.start_ns * 1e-9
        self.t1 = min(w.end_ns * 1e-9, base.duration_s)
        self.speed = float(w.params["speed"])
        self.ramp = min(float(w.params["ramp"]), 0.5 * (self.t1 - self.t0))
        n = max(math.ceil((self.t1 - self.t0) * _GRID_HZ), 8) + 1
        self.grid = np.linspace(self.t0, self.t1, n)
        k = base.kinematics(self.grid)
        v, _ = self.lateral(self.grid)
        rates = self._rates(k, v)
        dt = np.diff(self.grid)
        steps = 0.5 * (rates[1:] + rates[:-1]) * dt[:, None]
        self.pos = np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])  # dlat, dlon, dh
        self.rate = rates

    def lateral(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lateral speed (m/s) and its time derivative at ``t`` (s)."""
        if self.ramp <= 0.0:
            inside = (t >= self.t0) & (t < self.t1)
            return np.where(inside, self.speed, 0.0), np.zeros_like(t)
        up, dup = _smooth((t - self.t0) / self.ramp)
        down, ddown = _smooth((self.t1 - t) / self.ramp)
        return self.speed * up * down, self.speed * (dup * down - up * ddown) / self.ramp

    @staticmethod
    def _axes(k: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        C = euler_to_dcm(k.euler[:, 0], k.euler[:, 1], k.euler[:, 2])
        w = euler_rates_to_omega_nb_b(
            k.euler[:, 0], k.euler[:, 1], k.euler[:, 2], k.euler_rate[:, 0], k.euler_rate[:, 1], k.euler_rate[:, 2]
        )
        return C, w

    def _rates(self, k: Kinematics, v_lat: np.ndarray) -> np.ndarray:
        C, _ = self._axes(k)
        v_n = C[:, :, 0] * v_lat[:, None]
        dlat, dlon, dh = earth.position_rates(k.lat, k.h, v_n)
        return np.column_stack([dlat, dlon, dh])

    def add(self, k: Kinematics, t: np.ndarray) -> None:
        """Add the slide to kinematics ``k`` at times ``t`` (in place)."""
        after = t >= self.t1
        if after.any():
            k.lat[after] += self.pos[-1, 0]
            k.lon[after] += self.pos[-1, 1]
            k.h[after] += self.pos[-1, 2]
        inside = (t > self.t0) & (t < self.t1)
        if not inside.any():
            return
        ti = t[inside]
        dt = self.grid[1] - self.grid[0]
        u = (ti - self.t0) / dt
        i = np.clip(np.floor(u).astype(np.int64), 0, len(self.grid) - 2)
        x = (u - i)[:, None]
        p0, p1 = self.pos[i], self.pos[i + 1]
        m0, m1 = self.rate[i] * dt, self.rate[i + 1] * dt
        x2, x3 = x * x, x * x * x
        p = (2 * x3 - 3 * x2 + 1) * p0 + (x3 - 2 * x2 + x) * m0 + (-2 * x3 + 3 * x2) * p1 + (x3 - x2) * m1
        k.lat[inside] += p[:, 0]
        k.lon[inside] += p[:, 1]
        k.h[inside] += p[:, 2]
        sub = Kinematics(
            ti, k.lat[inside], k.lon[inside], k.h[inside], k.vel_n[inside], k.acc_n[inside],
            k.euler[inside], k.euler_rate[inside],
        )  # fmt: skip
        C, w = self._axes(sub)
        v, dv = self.lateral(ti)
        x_n, y_n, z_n = C[:, :, 0], C[:, :, 1], C[:, :, 2]
        k.vel_n[inside] += x_n * v[:, None]
        # d/dt (C e_x) = C (omega_nb_b x e_x) = C [0, w_z, -w_y]
        k.acc_n[inside] += x_n * dv[:, None] + v[:, None] * (y_n * w[:, 2:3] - z_n * w[:, 1:2])


class FaultedTrajectory(Trajectory):
    """A trajectory with sideslip and bump windows added to its motion.

    Parameters
    ----------
    base:
        The motion without the faults.
    windows:
        Odometer ``sideslip`` and ``bump`` windows (others are ignored).
    """

    def __init__(self, base: Trajectory, windows: Iterable[FaultWindow]):
        self.base = base
        self.duration_s = base.duration_s
        self.windows = [w for w in windows if w.kind in MOTION_KINDS]
        self._slides = [
            _Slide(base, w) for w in self.windows if w.kind == "sideslip" and w.start_ns * 1e-9 < base.duration_s
        ]
        self._bumps = [w for w in self.windows if w.kind == "bump" and w.params["height"] != 0.0]
        knots = [base.knots()]
        for s in self._slides:
            knots.append(np.array([s.t0, s.t0 + s.ramp, s.t1 - s.ramp, s.t1]))
        for w in self._bumps:
            knots.append(np.array([w.start_ns * 1e-9, w.end_ns * 1e-9]))
        allk = np.unique(np.concatenate(knots))
        self._knots = allk[(allk > 0.0) & (allk < self.duration_s)]

    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        k = self.base.kinematics(t)
        k = Kinematics(
            k.t, k.lat.copy(), k.lon.copy(), k.h.copy(), k.vel_n.copy(), k.acc_n.copy(), k.euler, k.euler_rate
        )
        for s in self._slides:
            s.add(k, t)
        for w in self._bumps:
            t_ns = np.round(t * 1e9).astype(np.int64)
            m = (t_ns > w.start_ns) & (t_ns < w.end_ns)
            if m.any():
                f, df, d2f = bump_shape(w, t_ns[m])
                H = w.params["height"]
                k.h[m] += H * f
                k.vel_n[m, 2] += H * df
                k.acc_n[m, 2] += H * d2f
        return k

    def knots(self) -> np.ndarray:
        return self._knots

    def wheel_speed(self, t: np.ndarray) -> np.ndarray | None:
        return self.base.wheel_speed(t)

    def driver_input(self, t: np.ndarray) -> dict[str, np.ndarray] | None:
        return self.base.driver_input(t)

    def segments(self) -> list[SegmentInfo]:
        return self.base.segments()

    def segment_at(self, t: np.ndarray) -> np.ndarray:
        return self.base.segment_at(t)
