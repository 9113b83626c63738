"""One run's state and its set-up: the recording opened and declared, the DUT adapter
made, the production windows cut (:func:`open_session`, :meth:`RunSession.begin`).

The engine (:mod:`bench.run.engine`) opens a :class:`RunSession`, hands it to the
lockstep loop (:mod:`bench.run.lockstep_loop`) or the real-time loop
(:mod:`bench.run.realtime_loop`), and finishes it (:mod:`bench.run.finish`) whatever
happened. Everything a loop or the finish needs is an attribute of the session.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.clock.pacing import Clock, LockstepClock, RealTimeClock, TimingLog
from bench.dut.estimator import Estimator, create_estimator
from bench.errors import BenchError, ConfigError, DutError
from bench.faults.wire import WIRE_EVENTS_TOPIC
from bench.record.mcap_io import RecordingWriter
from bench.record.wire_topics import CAN_TX, SERIAL_RX, SERIAL_TX, declare_wire_topics, write_can, write_serial
from bench.run.external import ExternalDut
from bench.run.inprocess import InProcessDut, traceback_lines
from bench.run.output import DutOutputRecorder
from bench.run.provider import TrafficProvider
from bench.run.result import RunResult
from bench.run.spec import ClockSpec, DutSpec, LinkSpec
from bench.run.traffic import Traffic
from bench.runinfo import host_metadata
from bench.wire.dbc import dbc_path

__all__ = ["RunSession", "open_session", "TIMING_TOPIC", "TIMING_DTYPE"]

TIMING_TOPIC = "/bench/timing"
TIMING_DTYPE = np.dtype([("t_ns", "<i8"), ("lateness_ns", "<i8")])


@dataclass
class RunSession:
    """The state of one run between its set-up and its finish."""

    provider: TrafficProvider
    dut: DutSpec
    links: LinkSpec
    clock_spec: ClockSpec
    rec: RecordingWriter
    result: RunResult
    clock: Clock
    started: float
    progress: Callable[[float, float], None] | None = None
    #: length of the production windows, ns
    window_ns: int = 10_000_000_000
    timing: TimingLog = field(default_factory=TimingLog)
    estimator: Estimator | None = None
    start_error: DutError | None = None
    dut_in: InProcessDut | None = None
    dut_ext: ExternalDut | None = None
    out: DutOutputRecorder | None = None
    windows: list[tuple[int, int]] = field(default_factory=list)
    start_ns: int = 0
    total_ns: int = 0
    #: the lateness of every emission written so far (real time)
    lateness: list[np.ndarray] = field(default_factory=list)
    #: bench time reached (the end of the last window run)
    t_done: int = 0

    @property
    def lockstep(self) -> bool:
        """True in lockstep mode."""
        return self.clock_spec.lockstep

    @property
    def step_ns(self) -> int:
        """The scheduler step."""
        return self.clock_spec.step_ns

    # ------------------------------------------------------------------ set-up
    def begin(self, run_start: dict | None, attachments: list[tuple[str, bytes, str]] | None) -> None:
        """Write ``run_start``, the attachments and the topics, make the DUT adapter and
        cut the windows (inside the engine's guard: a failure here is recorded)."""
        rec, dut, clock_spec, provider = self.rec, self.dut, self.clock_spec, self.provider
        rec.metadata(
            "run_start",
            {
                "kind": "run",
                **(run_start or {}),
                **provider.metadata(),
                "clock": clock_spec.mode,
                "clock_step_ms": f"{clock_spec.step_ns / 1e6:g}",
                "speed": f"{clock_spec.speed:g}",
                "dut": dut.name or dut.command or dut.kind,
                "dut_kind": dut.kind,
                "epoch_utc_ns": str(provider.epoch_ns),
                **host_metadata(),
            },
        )
        for name, data, media in attachments or []:
            rec.attach(name, data, media)
        provider.declare(rec)
        rec.attach(f"models/can/{dbc_path().name}", dbc_path().read_bytes(), "text/plain")
        declare_wire_topics(rec)
        rec.columnar_topic(
            WIRE_EVENTS_TOPIC.topic,
            WIRE_EVENTS_TOPIC.schema,
            WIRE_EVENTS_TOPIC.dtype,
            description=WIRE_EVENTS_TOPIC.description,
            units=WIRE_EVENTS_TOPIC.units,
        )
        if not self.lockstep:
            rec.columnar_topic(
                TIMING_TOPIC,
                "bench.Timing",
                TIMING_DTYPE,
                description="scheduled bench time of each emission and its lateness",
                units={"t_ns": "ns", "lateness_ns": "ns"},
            )
        out = self.out = DutOutputRecorder(rec)
        if self.start_error is not None:
            if self.start_error.__cause__ is not None:  # the estimator's traceback, as a DUT's stderr
                out.log(traceback_lines(self.start_error.__cause__), provider.start_ns)
            raise self.start_error
        if dut.kind == "in_process":
            assert self.estimator is not None
            self.dut_in = InProcessDut(self.estimator, provider.epoch_ns, on_lines=out.log,
                                       step_timeout_s=self.clock_spec.timeout_s, step_ns=self.step_ns,
                                       flood_frames_per_s=dut.flood_frames_per_s)
        else:
            self.dut_ext = ExternalDut(
                dut,
                self.links,
                lockstep=self.lockstep,
                on_lines=out.log,
                on_serial=lambda name, chunks: write_serial(rec, SERIAL_RX[name], chunks),
            )
        self._cut_windows()

    def _cut_windows(self) -> None:
        provider, step = self.provider, self.step_ns
        start_ns = provider.start_ns
        total = provider.duration_ns - provider.duration_ns % step  # the run ends on a step
        if start_ns % step or not 0 <= start_ns < total:
            raise ConfigError(
                f"the start {start_ns / 1e9:g} s must be a whole number of steps within the run "
                f"(0 .. {total / 1e9:g} s)",
                key="start",
            )
        self.start_ns, self.total_ns = start_ns, total
        self.windows = []
        t0 = start_ns
        while t0 < total:
            t1 = min(t0 + self.window_ns, total)
            self.windows.append((t0, t1))
            t0 = t1

    # ------------------------------------------------------------------ per window
    def produce(self, t0: int, t1: int) -> tuple[Traffic, np.ndarray]:
        """The traffic of window ``(t0, t1]`` (its samples recorded by the provider) and
        the times of its steps."""
        traffic = self.provider.window(self.rec, t0, t1)
        step = self.step_ns
        k0 = t0 // step if t0 == self.start_ns else t0 // step + 1
        return traffic, np.arange(k0, t1 // step + 1, dtype=np.int64) * step

    def record_traffic(self, traffic: Traffic) -> None:
        """Record what the bench sends of ``traffic`` (CAN, serial, wire fault events)."""
        rec = self.rec
        write_can(rec, CAN_TX, traffic.can)
        write_serial(rec, SERIAL_TX["imu"], traffic.imu)
        write_serial(rec, SERIAL_TX["gnss"], traffic.gnss)
        if len(traffic.events):
            rec.write_block(WIRE_EVENTS_TOPIC.topic, traffic.events)

    def prepare(self, t0: int, t1: int) -> tuple[Traffic, np.ndarray]:
        """:meth:`produce` and :meth:`record_traffic` of one window."""
        traffic, step_times = self.produce(t0, t1)
        self.record_traffic(traffic)
        return traffic, step_times

    def report(self, t1: int) -> None:
        """Window ``(.., t1]`` done: the progress callback, if any."""
        self.t_done = t1
        if self.progress is not None:
            self.progress((t1 - self.start_ns) * 1e-9, (self.total_ns - self.start_ns) * 1e-9)

    def write_timing(self) -> None:
        """Record the lateness measured since the last call on ``/bench/timing`` (the one
        place it is written: after the real-time loop and in the finish)."""
        t_late, late_ns = self.timing.take()
        if len(t_late):
            block = np.zeros(len(t_late), TIMING_DTYPE)
            block["t_ns"], block["lateness_ns"] = t_late, late_ns
            self.rec.write_block(TIMING_TOPIC, block)
            self.lateness.append(late_ns)


def open_session(
    provider: TrafficProvider,
    dut: DutSpec,
    links: LinkSpec,
    clock_spec: ClockSpec,
    out_path: Path,
    *,
    window_ns: int,
    progress: Callable[[float, float], None] | None,
    overwrite: bool,
) -> RunSession:
    """Check the specs, make the estimator of an in-process DUT and open the recording.

    An estimator that fails to start is not raised here: the session keeps the error and
    :meth:`RunSession.begin` raises it once the recording can say so.

    Raises
    ------
    ConfigError
        For specs that cannot be run and outputs the bench may not write, before anything
        is written.
    """
    started = time.perf_counter()
    dut.check()
    clock_spec.check()
    estimator: Estimator | None = None
    start_error: DutError | None = None
    if dut.kind == "in_process":
        try:
            estimator = create_estimator(str(dut.name), dut.config, search=[dut.cwd])  # beside the case first
            estimator.warm_up()  # kernels compiled before the run's clock starts, not in its first steps
        except BenchError:
            raise
        except (Exception, SystemExit) as exc:  # the estimator under test failed to start: its run records that
            start_error = DutError(f"the estimator {dut.name!r} failed to start: {type(exc).__name__}: {exc}")
            start_error.__cause__ = exc
    clock = LockstepClock() if clock_spec.lockstep else RealTimeClock(clock_spec.speed)
    rec = RecordingWriter(out_path, epoch_ns=provider.epoch_ns, overwrite=overwrite)
    session = RunSession(
        provider,
        dut,
        links,
        clock_spec,
        rec,
        RunResult(Path(out_path), "complete"),
        clock,
        started,
        progress=progress,
        window_ns=window_ns,
        estimator=estimator,
        start_error=start_error,
    )
    return session
