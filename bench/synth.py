"""``bench synth``: truth and sensor streams of a scenario, written to one MCAP file.

The run is processed in windows of bench time (:class:`bench.run.source.RunSource`, the
same producer the run engine uses); in each window the truth is sampled at the truth rate
and every sensor model produces its samples, so memory stays bounded on long drives and
the progress can be reported. The output is a deterministic function of the scenario, the
sensor parameters and the seed: the same seed gives byte-identical message payloads.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingWriter
from bench.run.source import RunSource
from bench.runinfo import git_commit, host_metadata, parse_epoch
from bench.scenario.loader import Scenario
from bench.scenario.trajectory import Trajectory
from bench.scoring.views import check_rate
from bench.scoring.viewwrite import add_views
from bench.sensors.base import SensorModel
from bench.sensors.suite import fault_schedule

__all__ = ["SynthOptions", "SynthSummary", "synthesize", "epoch_of", "git_commit"]


@dataclass
class SynthOptions:
    """What to synthesize besides the scenario's own settings.

    ``imu_rate_hz`` and ``imu_grade`` override the scenario's ``[imu]`` table.
    """

    seed: int = 0
    imu_rate_hz: float | None = None
    imu_grade: str | None = None
    truth_rate_hz: float = 100.0
    #: Rate of the Foxglove views written when the file is finished (10..50 Hz).
    display_rate_hz: float = 10.0
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
    return parse_epoch(scenario.meta.get("start_utc"), file=str(scenario.path))


def synthesize(
    scenario: Scenario,
    out: str | Path,
    options: SynthOptions | None = None,
    *,
    sensors: Sequence[SensorModel] | None = None,
    trajectory: Trajectory | None = None,
    faults: FaultSchedule | None = None,
    progress: Callable[[float, float], None] | None = None,
    overwrite: bool = True,
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
    overwrite:
        Replace an existing file at ``out`` (``bench synth`` passes ``--force``).

    Raises
    ------
    ConfigError
        ``out`` cannot be written (a folder, read-only, exists without ``overwrite``,
        another bench is writing it).
    RecordingError
        Writing failed part way (a full disk); the file keeps what was written.
    """
    options = options or SynthOptions()
    check_rate(options.display_rate_hz)
    started = time.perf_counter()
    file = str(scenario.path)
    schedule = faults if faults is not None else fault_schedule(scenario.doc, file=file, extra=options.fault_files)
    source = RunSource(scenario, scenario.doc, options.seed, schedule, trajectory=trajectory,
                       imu_grade=options.imu_grade, imu_rate_hz=options.imu_rate_hz,
                       truth_rate_hz=options.truth_rate_hz,
                       write_ideal=options.write_ideal, sensors=sensors)
    epoch = epoch_of(scenario)
    total_ns = source.duration_ns
    window_ns = int(options.window_s * 1e9)
    with RecordingWriter(out, epoch_ns=epoch, overwrite=overwrite) as rec:
        rec.metadata("run_start", {"kind": "synth", **source.metadata(), "epoch_utc_ns": str(epoch),
                                   **host_metadata()})
        source.declare(rec)
        for ff in options.fault_files:
            rec.attach(f"faults/{Path(ff).name}", Path(ff).read_bytes(), "application/toml")
        t0 = 0
        while t0 < total_ns:
            t1 = min(t0 + window_ns, total_ns)
            source.produce(rec, t0, t1)
            t0 = t1
            if progress is not None:
                progress(t0 * 1e-9, total_ns * 1e-9)
        stats = source.stats
        rec.metadata("synth_summary", {"duration_s": f"{total_ns / 1e9:.9g}", "distance_m": f"{stats.distance_m:.3f}",
                                       "max_speed_mps": f"{stats.max_speed:.6f}", "counts": stats.counts})
        add_views(rec, options.display_rate_hz)
    return SynthSummary(
        path=Path(out),
        scenario=scenario.id,
        duration_s=total_ns / 1e9,
        distance_m=stats.distance_m,
        max_speed=stats.max_speed,
        counts=dict(stats.counts),
        elapsed_s=time.perf_counter() - started,
    )
