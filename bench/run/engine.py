"""The run engine: one scheduler over bench time, the DUT on its links, one MCAP per run.

For each production window (10 s of bench time by default) the engine produces the truth
and the sensor samples (:class:`~bench.run.source.RunSource`), encodes them onto the ICD
links with the wire faults (:class:`~bench.run.traffic.TrafficEncoder`), records every
frame and byte it sends, hands the traffic to the DUT step by step (in-process: direct
calls; external: the ICD lockstep protocol or real-time emission) and records every frame
the DUT sends back, decoded and checked. The recording is finished in ``finally``: a run
that fails, is interrupted or is killed between chunks still leaves a readable file whose
``run_end`` record says how it ended:

``complete``        the run went to the end;
``dut_error``       the DUT crashed, hung, never started, flooded the bus, or raised;
``link_lost``       a link failed;
``timing_budget``   a real-time run missed its lateness budget;
``interrupted``     Ctrl-C or SIGTERM;
``error``           the bench failed (the reason says how).

All but ``complete`` make the verdict ERROR: the bench could not judge the DUT.

A recording that cannot be written (a full disk, a file size limit) ends the run with
``error``: the file keeps what reached it (an unfinished recording) and, once the DUT
is shut down, :class:`~bench.errors.RecordingError` is raised (``recording could not be
written: No space left on device``). An output the bench may not write (a folder, a
read-only one, an existing recording without ``overwrite``, one another bench is
writing) is a :class:`~bench.errors.ConfigError` before anything starts.

Whatever the ending, the DUT is shut down (an external DUT's whole process group: SIGTERM,
the shutdown timeout, SIGKILL) and its last output lines, ``dut_exit``, the output tally
and the run summary are recorded before ``run_end``; each of these cleanup steps is
guarded, so one failing does not lose the others or the file. An interrupt
(:class:`KeyboardInterrupt`, which ``bench`` also raises on SIGTERM) is raised again once
the recording is finished, so the caller stops too.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench.clock import realtime_priority
from bench.clock.pacing import LockstepClock, RealTimeClock, TimingLog
from bench.dut.estimator import create_estimator
from bench.errors import BenchError, ConfigError, DutError, RecordingError
from bench.faults.wire import WIRE_EVENTS_TOPIC
from bench.frames import CanBatch
from bench.record.mcap_io import RecordingWriter
from bench.record.wire_topics import CAN_TX, SERIAL_RX, SERIAL_TX, declare_wire_topics, write_can, write_serial
from bench.run.external import ExternalDut
from bench.run.inprocess import InProcessDut
from bench.run.output import DutOutputRecorder
from bench.run.provider import COMMANDS_TOPIC, SynthProvider, TrafficProvider
from bench.run.result import RunResult, TimingBudgetError, reason_of, status_of
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.run.traffic import BENCH_TIME_ID, Traffic
from bench.runinfo import host_metadata
from bench.wire.dbc import dbc_path

__all__ = [
    "RunResult",
    "run",
    "execute",
    "TrafficProvider",
    "SynthProvider",
    "TimingBudgetError",
    "TIMING_TOPIC",
    "COMMANDS_TOPIC",
]

TIMING_TOPIC = "/bench/timing"
TIMING_DTYPE = np.dtype([("t_ns", "<i8"), ("lateness_ns", "<i8")])


def run(spec: RunSpec, progress: Callable[[float, float], None] | None = None) -> RunResult:
    """Execute one synthesized run (see the module docstring); never raises for a failed
    DUT or link.

    Raises
    ------
    ConfigError
        Before any recording is written, when the spec cannot be run as written.
    KeyboardInterrupt
        Again, after the recording of an interrupted run was finished (status ``interrupted``).
    """
    spec.check()
    provider = SynthProvider(spec)
    return execute(
        provider,
        spec.dut,
        spec.links,
        spec.clock,
        spec.out,
        run_start=spec.run_start,
        attachments=spec.attachments,
        window_ns=spec.window_ns,
        progress=progress,
    )


def execute(
    provider: TrafficProvider,
    dut: DutSpec,
    links: LinkSpec,
    clock_spec: ClockSpec,
    out_path: Path,
    *,
    run_start: dict | None = None,
    attachments: list[tuple[str, bytes, str]] | None = None,
    window_ns: int = 10_000_000_000,
    progress: Callable[[float, float], None] | None = None,
    overwrite: bool = True,
) -> RunResult:
    """The engine loop: traffic from ``provider`` to the DUT, everything recorded.

    The run starts at ``provider.start_ns`` (a whole number of steps; a replay may seek),
    where the DUT's first step and its start-up handshake are. Never raises for a failed
    DUT or link (the result and the recording say how the run ended); an interrupt is
    raised again once the recording is finished, a recording that could not be written
    as :class:`~bench.errors.RecordingError` (``overwrite``: replace an existing file).
    """
    started = time.perf_counter()
    dut.check()
    clock_spec.check()
    start_error: DutError | None = None
    if dut.kind == "in_process":
        try:
            estimator = create_estimator(str(dut.name), dut.config)
        except BenchError:
            raise
        except Exception as exc:  # the estimator under test failed to start: its run records that
            start_error = DutError(f"the estimator {dut.name!r} failed to start: {type(exc).__name__}: {exc}")
            start_error.__cause__ = exc
    epoch = provider.epoch_ns
    lockstep = clock_spec.lockstep
    clock = LockstepClock() if lockstep else RealTimeClock(clock_spec.speed)
    timing = TimingLog()
    result = RunResult(Path(out_path), "complete")
    rec = RecordingWriter(out_path, epoch_ns=epoch, overwrite=overwrite)
    dut_in: InProcessDut | None = None
    dut_ext: ExternalDut | None = None
    out: DutOutputRecorder | None = None
    lateness: list[np.ndarray] = []
    t_done = 0
    interrupt: KeyboardInterrupt | None = None
    try:
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
                "epoch_utc_ns": str(epoch),
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
        if not lockstep:
            rec.columnar_topic(
                TIMING_TOPIC,
                "bench.Timing",
                TIMING_DTYPE,
                description="scheduled bench time of each emission and its lateness",
                units={"t_ns": "ns", "lateness_ns": "ns"},
            )
        out = DutOutputRecorder(rec)
        if start_error is not None:
            raise start_error
        if dut.kind == "in_process":
            dut_in = InProcessDut(estimator, epoch)
        else:
            dut_ext = ExternalDut(dut, links, lockstep=lockstep, on_lines=out.log,
                                  on_serial=lambda name, chunks: write_serial(rec, SERIAL_RX[name], chunks))
        start_ns = provider.start_ns
        step = clock_spec.step_ns
        total = provider.duration_ns - provider.duration_ns % step  # the run ends on a step
        if start_ns % step or not 0 <= start_ns < total:
            raise ConfigError(
                f"the start {start_ns / 1e9:g} s must be a whole number of steps within the run "
                f"(0 .. {total / 1e9:g} s)",
                key="start",
            )
        windows = []
        t0 = start_ns
        while t0 < total:
            t1 = min(t0 + window_ns, total)
            windows.append((t0, t1))
            t0 = t1

        def prepare(t0: int, t1: int) -> tuple[Traffic, np.ndarray]:
            traffic = provider.window(rec, t0, t1)
            write_can(rec, CAN_TX, traffic.can)
            write_serial(rec, SERIAL_TX["imu"], traffic.imu)
            write_serial(rec, SERIAL_TX["gnss"], traffic.gnss)
            if len(traffic.events):
                rec.write_block(WIRE_EVENTS_TOPIC.topic, traffic.events)
            k0 = t0 // step if t0 == start_ns else t0 // step + 1
            return traffic, np.arange(k0, t1 // step + 1, dtype=np.int64) * step

        def report(t1: int) -> None:
            if progress is not None:
                progress((t1 - start_ns) * 1e-9, (total - start_ns) * 1e-9)

        if lockstep:
            clock.start(start_ns)
            for t0, t1 in windows:
                traffic, step_times = prepare(t0, t1)
                if dut_ext is not None:
                    if t0 == start_ns:
                        first = traffic.can.take(np.flatnonzero(traffic.can.can_id == BENCH_TIME_ID)[:1])
                        dut_ext.start(first, out.feed, lambda frames: write_can(rec, CAN_TX, frames))
                    dut_ext.exchange_lockstep(traffic, step_times, clock_spec.timeout_s, out.feed)
                else:
                    assert dut_in is not None
                    out.feed(dut_in.exchange(traffic, step_times, t0))
                t_done = t1
                report(t1)
        else:
            # real time: everything is prepared (and its samples recorded) before the clock
            # starts, and the DUT's frames are decoded and recorded when there is slack, so
            # the emission loop does nothing but wait and send
            plans = []
            for t0, t1 in windows:
                traffic, step_times = prepare(t0, t1)
                if dut_ext is not None:
                    plans.append((t0, t1, dut_ext.plan_realtime(traffic), step_times))
                else:
                    plans.append((t0, t1, _steps_of(traffic, step_times), step_times))
            if dut_ext is not None:
                dut_ext.start(CanBatch.empty(), out.feed, lambda frames: None)
            out.deferred = True
            idle = lambda slack: out.process(4)  # noqa: E731 - a few batches per slack moment
            rec.metadata("realtime_scheduling", realtime_priority.acquire())
            clock.start(start_ns)
            for t0, t1, plan, step_times in plans:
                if dut_ext is not None:
                    dut_ext.exchange_realtime(plan, clock, timing, t1, out.feed, idle)
                else:
                    assert dut_in is not None
                    for k, part in enumerate(plan):
                        t = int(step_times[k])
                        timing.add(t, clock.wait_until(t))
                        lo = int(step_times[k - 1]) + 1 if k else t0
                        out.feed(dut_in.exchange(part, step_times[k : k + 1], lo))
                t_done = t1
                report(t1)
            realtime_priority.release()
            out.deferred = False
            out.process()
            t_late, late = timing.take()
            if len(t_late):
                block = np.zeros(len(t_late), TIMING_DTYPE)
                block["t_ns"], block["lateness_ns"] = t_late, late
                rec.write_block(TIMING_TOPIC, block)
                lateness.append(late)
        if not lockstep and clock_spec.budget is not None:
            summary = TimingLog.summarize(np.concatenate(lateness) if lateness else np.zeros(0, np.int64))
            if not summary.within(clock_spec.budget):
                raise TimingBudgetError(
                    f"real-time budget missed: {summary.text()} (budget p99 {clock_spec.budget.p99_ns / 1e3:g} us, "
                    f"max {clock_spec.budget.max_ns / 1e3:g} us)"
                )
    except BaseException as exc:  # the recording must say how the run ended, whatever happened
        result.status = status_of(exc)
        result.reason = reason_of(exc)
        if isinstance(exc, KeyboardInterrupt):
            interrupt = exc
        elif not isinstance(exc, BenchError):
            rec.metadata("run_traceback", {"traceback": traceback.format_exc()})
        elif isinstance(exc, DutError) and exc.__cause__ is not None and not isinstance(exc.__cause__, BenchError):
            tb = "".join(traceback.format_exception(exc.__cause__))
            rec.metadata("dut_traceback", {"traceback": tb})
    finally:
        late: list[KeyboardInterrupt] = []

        def guarded(what: str, fn: Callable[[], object]) -> None:
            """One cleanup step: a failure is noted in the reason, an interrupt (a third
            signal: the DUT was killed at once) after the file is finished."""
            try:
                fn()
            except KeyboardInterrupt as e:
                late.append(e)
            except Exception as e:  # a cleanup step must not lose the recording
                result.reason += f" ({what} failed: {type(e).__name__}: {e})"

        if not lockstep:  # a real-time run that failed in its emission loop still holds them
            guarded("restoring the scheduling policy and the garbage collector", realtime_priority.release)
        if dut_in is not None:
            if dut_in.partial is not None and out is not None:  # its output before it failed
                guarded("recording the DUT output", lambda: out.feed(dut_in.partial))
            guarded("closing the estimator", dut_in.close)
            guarded("dut_input_tally", lambda: rec.metadata("dut_input_tally", dut_in.decoder.tally.as_dict()))
        if dut_ext is not None:

            def close_external() -> None:
                result.dut_exit = dut_ext.close()
                rec.metadata("dut_exit", result.dut_exit)

            guarded("shutting the DUT down", close_external)
        if out is not None:

            def finish_output() -> None:
                out.deferred = False
                out.process()  # frames received before a real-time run stopped
                out.write_bad()
                rec.metadata(
                    "dut_output",
                    {"solutions": out.solutions, "qualities": out.qualities, "bad_frames": out.tally.as_dict()},
                )

            guarded("recording the DUT output", finish_output)

        def finish_timing() -> None:
            t_late, late_ns = timing.take()
            if len(t_late):
                block = np.zeros(len(t_late), TIMING_DTYPE)
                block["t_ns"], block["lateness_ns"] = t_late, late_ns
                rec.write_block(TIMING_TOPIC, block)
                lateness.append(late_ns)
            if lateness:
                result.timing = TimingLog.summarize(np.concatenate(lateness))
                rec.metadata(
                    "timing_summary",
                    {
                        "count": result.timing.count,
                        "p50_ns": result.timing.p50_ns,
                        "p99_ns": result.timing.p99_ns,
                        "p999_ns": result.timing.p999_ns,
                        "max_ns": result.timing.max_ns,
                    },
                )

        guarded("recording the timing", finish_timing)

        def finish_summary() -> None:
            result.counts = provider.counts()
            result.bench_s = t_done * 1e-9
            result.elapsed_s = time.perf_counter() - started
            rec.metadata(
                "run_summary",
                {"bench_s": f"{result.bench_s:.3f}", "elapsed_s": f"{result.elapsed_s:.3f}", "counts": result.counts},
            )

        guarded("run_summary", finish_summary)
        if late and interrupt is None:
            interrupt = late[0]
            if result.status == "complete":
                result.status, result.reason = "interrupted", reason_of(interrupt) + " while finishing the run"
        rec.close(result.status, result.reason)
    if interrupt is not None:
        raise interrupt
    if rec.error is not None:
        raise RecordingError(f"{out_path}: {rec.error}")
    return result


def _steps_of(traffic: Traffic, step_times: np.ndarray) -> list[Traffic]:
    """The traffic of each step of a window (real-time in-process runs)."""
    cuts = [np.searchsorted(b.t_ns, step_times, side="right") for b in (traffic.can, traffic.imu, traffic.gnss)]
    out = []
    lo = [0, 0, 0]
    for k in range(len(step_times)):
        hi = [int(c[k]) for c in cuts]
        out.append(
            Traffic(
                traffic.can.take(np.arange(lo[0], hi[0])),
                traffic.imu.take(np.arange(lo[1], hi[1])),
                traffic.gnss.take(np.arange(lo[2], hi[2])),
                traffic.events[:0],
            )
        )
        lo = hi
    return out
