"""IMU faults on top of the IMU model: bias steps, axis failures, saturation.

:class:`FaultyImu` wraps a :class:`~bench.sensors.imu.model.LaserImu` and applies the
scheduled IMU windows (:func:`bench.faults.sensor.imu_apply`) to its measured increments
(``/<name>``); the error-free increments (``/<name>/ideal``) stay as they are, so the
difference shows what was injected.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bench.faults.schedule import FaultWindow
from bench.faults.sensor import imu_apply
from bench.scenario.trajectory import Trajectory
from bench.sensors.base import SensorModel
from bench.sensors.imu.errors import ImuErrorModel
from bench.sensors.imu.model import LaserImu
from bench.topics import TopicSpec

__all__ = ["FaultyImu"]


class FaultyImu(SensorModel):
    """A :class:`LaserImu` with fault windows.

    Parameters
    ----------
    imu:
        The IMU model (its ``name`` is the fault target).
    faults:
        Sensor-layer windows aimed at it (``bias_step``, ``axis_failure``, ``saturation``).
    """

    def __init__(self, imu: LaserImu, faults: Sequence[FaultWindow]):
        self.imu = imu
        self.name = imu.name
        self.faults = list(faults)
        self._held: dict[int, np.ndarray] = {}
        self._last = np.zeros(6)

    @property
    def errors(self) -> ImuErrorModel:
        """The wrapped model's error model (its realised draws)."""
        return self.imu.errors

    def topics(self) -> list[TopicSpec]:
        return self.imu.topics()

    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        out = self.imu.run(traj, t0_ns, t1_ns)
        rec = out.get(f"/{self.name}")
        if rec is None or len(rec) == 0:
            return out
        rec = rec.copy()
        dtheta = rec["dtheta"].copy()
        dvel = rec["dvel"].copy()
        status = rec["status"].copy()
        imu_apply(self.faults, rec["t_ns"], dtheta, dvel, status, self.imu.T_ns * 1e-9, self._held, self._last)
        rec["dtheta"] = dtheta
        rec["dvel"] = dvel
        rec["status"] = status
        self._last = np.concatenate([dtheta[-1], dvel[-1]])
        out[f"/{self.name}"] = rec
        return out
