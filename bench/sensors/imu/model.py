"""The laser-gyro IMU as a sensor: exact increments through the error model."""

from __future__ import annotations

import numpy as np

from bench.scenario.trajectory import Trajectory
from bench.sensors.base import SensorModel
from bench.sensors.imu.errors import ImuErrorModel
from bench.sensors.imu.grade import ImuGrade
from bench.sensors.imu.ideal import ImuBlock, count_intervals, ideal_increments, interval_ns
from bench.topics import TopicSpec

__all__ = ["IMU_DTYPE", "LaserImu", "imu_records", "imu_block"]

IMU_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("dtheta", "<f8", (3,)),
        ("dvel", "<f8", (3,)),
        ("status", "u1"),
        ("temperature", "<f4"),
    ]
)
_UNITS = {"t_ns": "ns (end of interval)", "dtheta": "rad", "dvel": "m/s", "status": "ICD bits", "temperature": "degC"}


def imu_records(block: ImuBlock, temperature_c: float) -> np.ndarray:
    """Structured records of an :class:`ImuBlock`."""
    rec = np.empty(len(block), dtype=IMU_DTYPE)
    rec["t_ns"] = block.t_ns
    rec["dtheta"] = block.dtheta
    rec["dvel"] = block.dvel
    rec["status"] = block.status
    rec["temperature"] = temperature_c
    return rec


def imu_block(records: np.ndarray) -> ImuBlock:
    """Inverse of :func:`imu_records`."""
    return ImuBlock(
        records["t_ns"].astype(np.int64),
        records["dtheta"].astype(float),
        records["dvel"].astype(float),
        records["status"].astype(np.uint8),
    )


class LaserImu(SensorModel):
    """Strapdown IMU: exact increments (``/<name>/ideal``) and as measured (``/<name>``).

    Parameters
    ----------
    grade:
        Error parameters.
    seed:
        Run seed.
    rate_hz:
        Output rate (200 Hz default, up to 1000 Hz).
    name:
        Instance name (topic prefix and noise stream name).
    write_ideal:
        Also return the error-free increments.
    """

    def __init__(self, grade: ImuGrade, seed: int, rate_hz: float = 200.0, name: str = "imu", write_ideal: bool = True):
        self.name = name
        self.grade = grade
        self.rate_hz = float(rate_hz)
        self.T_ns = interval_ns(rate_hz)
        self.errors = ImuErrorModel(grade, seed, rate_hz, name=name)
        self.write_ideal = write_ideal

    def topics(self) -> list[TopicSpec]:
        measured = TopicSpec(
            f"/{self.name}",
            "bench.ImuSample",
            IMU_DTYPE,
            f"IMU increments as measured ({self.grade.name}), body frame RFU",
            _UNITS,
        )
        if not self.write_ideal:
            return [measured]
        ideal = TopicSpec(
            f"/{self.name}/ideal",
            "bench.ImuSample",
            IMU_DTYPE,
            "exact IMU increments (error-free), body frame RFU",
            _UNITS,
        )
        return [measured, ideal]

    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        k0 = t0_ns // self.T_ns
        k1 = min(t1_ns // self.T_ns, count_intervals(traj, self.rate_hz))
        ideal = [b for b in ideal_increments(traj, self.rate_hz, start_index=k0, stop_index=k1, chunk_s=1e9)]
        if not ideal:
            return {}
        block = ideal[0]
        measured = self.errors.apply(block)
        out = {f"/{self.name}": imu_records(measured, self.grade.temperature_c)}
        if self.write_ideal:
            out[f"/{self.name}/ideal"] = imu_records(block, self.grade.temperature_c)
        return out
