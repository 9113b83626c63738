"""What a run produces before any wire: truth and every sensor's samples, window by window.

:class:`RunSource` is shared by ``bench synth`` (which only records them) and the run
engine (which also encodes them onto the links). It builds the trajectory with the
schedule's body-motion faults, the IMU and the aiding-sensor suite from the sensor
tables, declares their topics and run metadata on a recording, and for each window of
bench time writes the truth (at the truth rate) and returns the sensor records. The
Foxglove views are derived from the recording when it is finished
(:mod:`bench.scoring.viewwrite`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.bounds import bounded_quantity
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.faults.motion import with_motion_faults
from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC, FaultSchedule
from bench.record.mcap_io import RecordingWriter
from bench.scenario.loader import Scenario
from bench.scenario.records import TRUTH_TOPIC, truth_records
from bench.scenario.trajectory import Trajectory, truth_at
from bench.sensors.base import SensorModel
from bench.sensors.imu.grade import ImuGrade, load_grade
from bench.sensors.imu.model import LaserImu
from bench.sensors.suite import SensorSuite, build_suite
from bench.topics import TopicSpec

__all__ = ["RunSource", "SourceStats", "imu_settings", "time_grid", "SEGMENTS_TOPIC"]

SEGMENTS_TOPIC = "/scenario/segments"


def imu_settings(
    table: Mapping[str, Any] | None, *, file: str | None, grade: str | None = None, rate_hz: float | None = None
) -> tuple[ImuGrade, float]:
    """IMU grade and rate from an ``[imu]`` table (``grade``, ``rate``), overridden by the
    explicit arguments; defaults: the navigation grade at 200 Hz."""
    table = table or {}
    check_keys(table, ("grade", "rate"), file=file, key="imu")
    g = load_grade(grade or table.get("grade", "navigation"))
    rate = (
        float(rate_hz)
        if rate_hz is not None
        else bounded_quantity(table.get("rate", 200.0), "frequency", "Hz", "imu_rate", file=file, key="imu.rate")
    )
    if not 1.0 <= rate <= 1000.0 or abs(1e9 / rate - round(1e9 / rate)) > 1e-6:
        raise ConfigError(
            f"expected an IMU rate of 1..1000 Hz dividing a second into whole nanoseconds, found {rate:g} Hz",
            file=file,
            key="imu.rate",
        )
    return g, rate


def time_grid(rate_hz: float, t0_ns: int, t1_ns: int, include_start: bool) -> np.ndarray:
    """Times k / rate in (t0, t1] (or [t0, t1] with ``include_start``) as integer ns."""
    period = 1e9 / rate_hz
    k0 = math.floor(t0_ns / period) + (0 if include_start and t0_ns % period == 0 else 1)
    k1 = math.floor(t1_ns / period + 1e-9)
    return np.round(np.arange(k0, k1 + 1) * period).astype(np.int64)


@dataclass
class SourceStats:
    """Running figures of the drive and the sample counts per topic."""

    distance_m: float = 0.0
    max_speed: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)
    _last: tuple[int, np.ndarray] | None = None

    def add_truth(self, t_ns: np.ndarray, vel_n: np.ndarray) -> None:
        """Accumulate distance (trapezoid of the speed) and top speed."""
        speed = np.linalg.norm(vel_n, axis=1)
        self.max_speed = max(self.max_speed, float(speed.max()))
        tt, sp = t_ns, speed
        if self._last is not None:
            tt = np.concatenate([[self._last[0]], t_ns])
            sp = np.concatenate([[self._last[1]], speed])
        self.distance_m += float(np.sum(0.5 * (sp[1:] + sp[:-1]) * np.diff(tt) * 1e-9))
        self._last = (int(t_ns[-1]), speed[-1])


class RunSource:
    """Truth and sensor samples of a scenario for one seed.

    Parameters
    ----------
    scenario:
        The loaded scenario (motion script, track or plant).
    tables:
        Sensor tables (``imu``, ``doppler``, ``odometer``, ``bds``, ``driver``): the
        scenario's own, or a test case's merged over them.
    seed:
        Run seed.
    schedule:
        Fault windows (sensor and wire layers).
    trajectory:
        A trajectory already built from the scenario (built here otherwise).
    imu_grade, imu_rate_hz:
        Overrides of the ``[imu]`` table.
    truth_rate_hz:
        Rate of ``/truth``.
    write_ideal:
        Also record the error-free IMU increments.
    duration_ns:
        Stop early (shortened runs); the scenario's length by default.
    sensors:
        Sensor models to use instead of building the suite from ``tables``.
    """

    def __init__(
        self,
        scenario: Scenario,
        tables: Mapping[str, Any],
        seed: int,
        schedule: FaultSchedule,
        *,
        trajectory: Trajectory | None = None,
        imu_grade: str | None = None,
        imu_rate_hz: float | None = None,
        truth_rate_hz: float = 100.0,
        write_ideal: bool = True,
        duration_ns: int | None = None,
        sensors: Sequence[SensorModel] | None = None,
    ):
        file = str(scenario.path)
        self.scenario = scenario
        self.seed = seed
        self.schedule = schedule
        self.truth_rate_hz = truth_rate_hz
        self.grade, self.imu_rate_hz = imu_settings(tables.get("imu"), file=file, grade=imu_grade, rate_hz=imu_rate_hz)
        self.base_trajectory = trajectory or scenario.trajectory()
        self.trajectory = with_motion_faults(self.base_trajectory, schedule)
        self.imu = LaserImu(self.grade, seed, self.imu_rate_hz, write_ideal=write_ideal)
        if sensors is None:
            self.suite = build_suite(tables, seed=seed, file=file, schedule=schedule, imu_name=self.imu.name)
        else:
            self.suite = SensorSuite(list(sensors), schedule)
        self.models: list[SensorModel] = [self.suite.wrap_imu(self.imu), *self.suite.models]
        full = self.trajectory.duration_ns
        if duration_ns is not None and duration_ns > full:
            raise ConfigError(
                f"the run asks for {duration_ns / 1e9:g} s but the scenario lasts {full / 1e9:g} s",
                file=file,
                key="duration",
            )
        self.duration_ns = full if duration_ns is None else int(duration_ns)
        self.stats = SourceStats()

    @property
    def sensor_topics(self) -> list[TopicSpec]:
        """Columnar topics of the IMU and the aiding sensors."""
        return [spec for m in self.models for spec in m.topics()]

    def metadata(self) -> dict[str, Any]:
        """Facts of the source for ``run_start``."""
        return {
            "scenario": self.scenario.id,
            "scenario_title": self.scenario.title,
            "seed": str(self.seed),
            "imu_rate_hz": f"{self.imu_rate_hz:g}",
            "imu_grade": self.grade.name,
            "truth_rate_hz": f"{self.truth_rate_hz:g}",
            "duration_s": f"{self.duration_ns / 1e9:.9g}",
        }

    def declare(self, rec: RecordingWriter, *, attach_scenario: bool = True) -> None:
        """Declare topics, and write the once-per-run records: parameters, attachments,
        fault windows, segments."""
        if attach_scenario and self.scenario.path.is_file():
            rec.attach(f"scenario/{self.scenario.path.name}", self.scenario.text().encode(), "application/toml")
        if self.grade.source:
            rec.attach(
                f"models/imu/{Path(self.grade.source).name}", Path(self.grade.source).read_bytes(), "application/toml"
            )
        rec.metadata(
            "imu_realised", {k: {kk: vv.tolist() for kk, vv in v.items()} for k, v in self.imu.errors.realised.items()}
        )
        if self.suite.params:
            rec.metadata("sensors", self.suite.record())
        plant = getattr(self.base_trajectory, "run", None)  # an FMU-driven trajectory (bench.plant)
        if plant is not None and hasattr(plant, "sha256"):
            desc = getattr(plant, "description", None)
            rec.metadata(
                "plant",
                {
                    "fmu_sha256": plant.sha256,
                    **(plant.trust.record() if getattr(plant, "trust", None) is not None else {}),
                    "model": str(getattr(desc, "model_name", "")),
                    "fmi_version": str(getattr(desc, "fmi_version", "")),
                    "steps": str(plant.steps),
                    "step_s": f"{plant.step_s:g}",
                    "log_tail": list(plant.log[-20:]),
                    **(plant.record() if callable(getattr(plant, "record", None)) else {}),
                },
            )
        for src in self.suite.sources():
            rec.attach(f"models/sensors/{src.parent.name}/{src.name}", src.read_bytes(), "application/toml")
        rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
        for w in self.schedule:
            rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
        self.stats.counts[FAULT_TOPIC] = len(self.schedule)
        rec.json_topic(SEGMENTS_TOPIC, "bench.Segments", {"type": "object"})
        rec.write_json(SEGMENTS_TOPIC, 0, {"segments": [seg.to_json() for seg in self.trajectory.segments()]})
        for spec in [TRUTH_TOPIC, *self.sensor_topics]:
            rec.columnar_topic(spec.topic, spec.schema, spec.dtype, description=spec.description, units=spec.units)
            self.stats.counts.setdefault(spec.topic, 0)

    def produce(self, rec: RecordingWriter, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        """Write the truth of ``(t0, t1]`` (``[0, t1]`` for the first window) and the sensor
        records; return the sensor records by topic."""
        traj = self.trajectory
        first = t0_ns == 0
        t_truth = time_grid(self.truth_rate_hz, t0_ns, t1_ns, include_start=first)
        if len(t_truth):
            tr = truth_at(traj, t_truth)
            rec.write_block(TRUTH_TOPIC.topic, truth_records(tr, traj.segment_at(t_truth * 1e-9)))
            self.stats.counts[TRUTH_TOPIC.topic] += len(t_truth)
            self.stats.add_truth(t_truth, tr.vel_n)
        out: dict[str, np.ndarray] = {}
        for m in self.models:
            for topic, records in m.run(traj, t0_ns, t1_ns).items():
                rec.write_block(topic, records)
                self.stats.counts[topic] = self.stats.counts.get(topic, 0) + len(records)
                out[topic] = records
        return out
