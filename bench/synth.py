"""``bench synth``: truth and sensor streams of a scenario, written to one MCAP file.

The run is processed in windows of bench time; in each window the truth is sampled at
the truth rate and every sensor model produces its samples, so memory stays bounded on
long drives and the progress can be reported. The output is a deterministic function of
the scenario, the sensor parameters and the seed: the same seed gives byte-identical
message payloads.
"""

from __future__ import annotations

import datetime as _dt
import math
import platform
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench import __version__
from bench.errors import ConfigError
from bench.faults.motion import with_motion_faults
from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC, FaultSchedule
from bench.nav import earth
from bench.paths import project_root
from bench.record.foxglove import LOCATION_FIX, POSE_IN_FRAME, location_fixes, poses_in_frame
from bench.record.mcap_io import RecordingWriter
from bench.scenario.loader import Scenario
from bench.scenario.records import TRUTH_TOPIC, truth_records
from bench.scenario.trajectory import Trajectory, truth_at
from bench.sensors.base import SensorModel
from bench.sensors.imu.grade import ImuGrade, load_grade
from bench.sensors.imu.model import LaserImu
from bench.sensors.suite import SensorSuite, build_suite, fault_schedule
from bench.units import quantity

__all__ = ["SynthOptions", "SynthSummary", "synthesize", "epoch_of", "git_commit", "imu_from_scenario"]

DEFAULT_EPOCH = "2025-06-01T00:00:00Z"


@dataclass
class SynthOptions:
    """What to synthesize besides the scenario's own settings.

    ``imu_rate_hz`` and ``imu_grade`` override the scenario's ``[imu]`` table.
    """

    seed: int = 0
    imu_rate_hz: float | None = None
    imu_grade: str | None = None
    truth_rate_hz: float = 100.0
    display_rate_hz: float = 5.0
    write_ideal: bool = True
    window_s: float = 10.0
    #: Fault files (``[[fault]]`` tables) added to the scenario's own ``[[fault]]`` tables.
    fault_files: tuple[str, ...] = ()


@dataclass
class SynthSummary:
    """What a synthesis produced."""

    path: Path
    scenario: str
    duration_s: float
    distance_m: float
    max_speed: float
    counts: dict[str, int] = field(default_factory=dict)
    elapsed_s: float = 0.0


def epoch_of(scenario: Scenario) -> int:
    """UTC of bench time zero, ns since 1970 (``[scenario] start_utc``)."""
    text = scenario.meta.get("start_utc", DEFAULT_EPOCH)
    try:
        when = _dt.datetime.fromisoformat(str(text).replace("Z", "+00:00"))
    except ValueError:
        raise ConfigError(
            f"expected an ISO 8601 time such as {DEFAULT_EPOCH!r}, found {text!r}",
            file=str(scenario.path),
            key="scenario.start_utc",
        ) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=_dt.UTC)
    return round(when.timestamp()) * 1_000_000_000 + when.microsecond * 1000


def git_commit() -> str:
    """Commit of the project checkout, or 'unknown'."""
    try:
        out = subprocess.run(
            ["git", "-C", str(project_root()), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
        dirty = subprocess.run(
            ["git", "-C", str(project_root()), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    commit = out.stdout.strip() or "unknown"
    return commit + ("+dirty" if dirty.stdout.strip() else "")


def imu_from_scenario(scenario: Scenario, options: SynthOptions) -> tuple[ImuGrade, float]:
    """The IMU grade and rate: CLI options first, then the scenario's ``[imu]`` table."""
    table = scenario.doc.get("imu", {})
    file = str(scenario.path)
    for k in table:
        if k not in ("grade", "rate"):
            raise ConfigError(f"unknown key {k!r}; expected grade, rate", file=file, key=f"imu.{k}")
    grade = load_grade(options.imu_grade or table.get("grade", "navigation"))
    if options.imu_rate_hz is not None:
        rate = float(options.imu_rate_hz)
    else:
        rate = quantity(table.get("rate", 200.0), "frequency", "Hz", file=file, key="imu.rate")
    if not 1.0 <= rate <= 1000.0 or abs(1e9 / rate - round(1e9 / rate)) > 1e-6:
        raise ConfigError(
            f"expected an IMU rate of 1..1000 Hz dividing a second into whole nanoseconds, found {rate:g} Hz",
            file=file,
            key="imu.rate",
        )
    return grade, rate


def _grid(rate_hz: float, t0_ns: int, t1_ns: int, include_start: bool) -> np.ndarray:
    """Times k / rate in (t0, t1] (or [t0, t1]) as integer ns."""
    period = 1e9 / rate_hz
    k0 = math.floor(t0_ns / period) + (0 if include_start and t0_ns % period == 0 else 1)
    k1 = math.floor(t1_ns / period + 1e-9)
    return np.round(np.arange(k0, k1 + 1) * period).astype(np.int64)


def synthesize(
    scenario: Scenario,
    out: str | Path,
    options: SynthOptions | None = None,
    *,
    sensors: Sequence[SensorModel] | None = None,
    trajectory: Trajectory | None = None,
    faults: FaultSchedule | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> SynthSummary:
    """Synthesize a scenario into an MCAP recording.

    Parameters
    ----------
    scenario:
        The loaded scenario.
    out:
        Output MCAP path.
    options:
        Seed, rates, IMU grade.
    sensors:
        Sensor models to run beside the IMU; by default the aiding sensors the
        scenario's ``[doppler]``, ``[odometer]``, ``[bds]`` and ``[driver]`` tables enable.
    trajectory:
        A trajectory already built from the scenario (built here otherwise); the
        schedule's body motions (odometer sideslip, bump) are added to it.
    faults:
        The fault schedule; by default the scenario's ``[[fault]]`` tables and
        ``options.fault_files``. Every window is recorded on ``/faults``.
    progress:
        Called with (bench seconds done, total) after each window.
    """
    options = options or SynthOptions()
    started = time.perf_counter()
    grade, imu_rate = imu_from_scenario(scenario, options)
    file = str(scenario.path)
    schedule = faults if faults is not None else fault_schedule(scenario.doc, file=file, extra=options.fault_files)
    traj = with_motion_faults(trajectory or scenario.trajectory(), schedule)
    epoch = epoch_of(scenario)
    imu = LaserImu(grade, options.seed, imu_rate, write_ideal=options.write_ideal)
    if sensors is None:
        suite = build_suite(scenario.doc, seed=options.seed, file=file, schedule=schedule, imu_name=imu.name)
    else:
        suite = SensorSuite(list(sensors), schedule)
    models: list[SensorModel] = [suite.wrap_imu(imu), *suite.models]
    counts: dict[str, int] = {}
    total_ns = traj.duration_ns
    window_ns = int(options.window_s * 1e9)
    t_first = truth_at(traj, np.array([0], dtype=np.int64))
    lat0, lon0, h0 = float(t_first.lat[0]), float(t_first.lon[0]), float(t_first.h[0])
    max_speed = 0.0
    distance = 0.0
    last_vel: np.ndarray | None = None
    last_t: int | None = None
    with RecordingWriter(out, epoch_ns=epoch) as rec:
        rec.metadata(
            "run_start",
            {
                "kind": "synth",
                "scenario": scenario.id,
                "scenario_title": scenario.title,
                "seed": str(options.seed),
                "imu_rate_hz": f"{imu_rate:g}",
                "imu_grade": grade.name,
                "truth_rate_hz": f"{options.truth_rate_hz:g}",
                "epoch_utc_ns": str(epoch),
                "duration_s": f"{traj.duration_s:.9g}",
                "bench_version": __version__,
                "git_commit": git_commit(),
                "host": platform.node(),
                "python": platform.python_version(),
                "numpy": np.__version__,
            },
        )
        rec.attach(f"scenario/{scenario.path.name}", scenario.text().encode(), "application/toml")
        if grade.source:
            rec.attach(f"models/imu/{Path(grade.source).name}", Path(grade.source).read_bytes(), "application/toml")
        rec.metadata(
            "imu_realised", {k: {kk: vv.tolist() for kk, vv in v.items()} for k, v in imu.errors.realised.items()}
        )
        if suite.params:
            rec.metadata("sensors", suite.record())
        for src in suite.sources():
            rec.attach(f"models/sensors/{src.parent.name}/{src.name}", src.read_bytes(), "application/toml")
        for ff in options.fault_files:
            rec.attach(f"faults/{Path(ff).name}", Path(ff).read_bytes(), "application/toml")
        rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
        for w in schedule:
            rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
        counts[FAULT_TOPIC] = len(schedule)
        rec.json_topic("/scenario/segments", "bench.Segments", {"type": "object"})
        rec.write_json(
            "/scenario/segments",
            0,
            {
                "segments": [
                    {
                        "index": s.index,
                        "kind": s.kind,
                        "start_s": s.start_s,
                        "end_s": s.end_s,
                        "gnss": s.gnss,
                        "surface": s.surface,
                        "label": s.label,
                    }
                    for s in traj.segments()
                ]
            },
        )
        specs = [TRUTH_TOPIC] + [spec for m in models for spec in m.topics()]
        for spec in specs:
            rec.columnar_topic(spec.topic, spec.schema, spec.dtype, description=spec.description, units=spec.units)
            counts[spec.topic] = 0
        rec.json_topic("/truth/location", "foxglove.LocationFix", LOCATION_FIX)
        rec.json_topic("/truth/pose", "foxglove.PoseInFrame", POSE_IN_FRAME)
        t0 = 0
        while t0 < total_ns:
            t1 = min(t0 + window_ns, total_ns)
            t_truth = _grid(options.truth_rate_hz, t0, t1, include_start=t0 == 0)
            if len(t_truth):
                tr = truth_at(traj, t_truth)
                rec.write_block(TRUTH_TOPIC.topic, truth_records(tr, traj.segment_at(t_truth * 1e-9)))
                counts[TRUTH_TOPIC.topic] += len(t_truth)
                speed = np.linalg.norm(tr.vel_n, axis=1)
                max_speed = max(max_speed, float(speed.max()))
                vel = tr.vel_n
                if last_vel is not None and last_t is not None:
                    vel = np.vstack([last_vel, vel])
                    tt = np.concatenate([[last_t], t_truth])
                else:
                    tt = t_truth
                sp = np.linalg.norm(vel, axis=1)
                distance += float(np.sum(0.5 * (sp[1:] + sp[:-1]) * np.diff(tt) * 1e-9))
                last_vel, last_t = tr.vel_n[-1:].copy(), int(t_truth[-1])
            t_disp = _grid(options.display_rate_hz, t0, t1, include_start=t0 == 0)
            if len(t_disp):
                td = truth_at(traj, t_disp)
                xyz = earth.geodetic_to_ecef(td.lat, td.lon, td.h)
                enu = earth.ecef_to_enu(xyz, lat0, lon0, h0)
                rec.write_json_many("/truth/location", t_disp, location_fixes(epoch, t_disp, td.lat, td.lon, td.h))
                rec.write_json_many("/truth/pose", t_disp, poses_in_frame(epoch, t_disp, enu, td.q_bn))
            for m in models:
                for topic, records in m.run(traj, t0, t1).items():
                    rec.write_block(topic, records)
                    counts[topic] = counts.get(topic, 0) + len(records)
            t0 = t1
            if progress is not None:
                progress(t0 * 1e-9, total_ns * 1e-9)
        rec.metadata(
            "synth_summary",
            {
                "duration_s": f"{traj.duration_s:.9g}",
                "distance_m": f"{distance:.3f}",
                "max_speed_mps": f"{max_speed:.6f}",
                "counts": counts,
            },
        )
    return SynthSummary(
        path=Path(out),
        scenario=scenario.id,
        duration_s=traj.duration_s,
        distance_m=distance,
        max_speed=max_speed,
        counts=counts,
        elapsed_s=time.perf_counter() - started,
    )
