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
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.clock.pacing import LockstepClock, RealTimeClock, TimingLog, TimingSummary
from bench.dut.estimator import create_estimator
from bench.errors import BenchError, DutError, LinkError
from bench.faults.wire import WIRE_EVENTS_TOPIC
from bench.record.mcap_io import RecordingWriter
from bench.record.wire_topics import CAN_TX, SERIAL_TX, declare_wire_topics, write_can, write_serial
from bench.run.external import ExternalDut
from bench.run.inprocess import InProcessDut
from bench.run.output import DutOutputRecorder
from bench.run.source import RunSource
from bench.run.spec import RunSpec
from bench.run.traffic import BENCH_TIME_ID, Traffic, TrafficEncoder
from bench.runinfo import host_metadata, parse_epoch

__all__ = ["RunResult", "run", "TimingBudgetError", "TIMING_TOPIC", "COMMANDS_TOPIC"]

TIMING_TOPIC = "/bench/timing"
COMMANDS_TOPIC = "/bench/commands"
TIMING_DTYPE = np.dtype([("t_ns", "<i8"), ("lateness_ns", "<i8")])
_COMMAND_NAMES = {1: "grid", 2: "geographic", 3: "reset"}


class TimingBudgetError(BenchError):
    """A real-time run was later than its budget allows."""


@dataclass
class RunResult:
    """How a run ended and what it produced."""

    path: Path
    status: str
    reason: str = ""
    elapsed_s: float = 0.0
    bench_s: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)
    timing: TimingSummary | None = None
    dut_exit: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when the run went to its end."""
        return self.status == "complete"


def _status_of(exc: BaseException) -> str:
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    if isinstance(exc, DutError):
        return "dut_error"
    if isinstance(exc, LinkError):
        return "link_lost"
    if isinstance(exc, TimingBudgetError):
        return "timing_budget"
    return "error"


def run(spec: RunSpec, progress: Callable[[float, float], None] | None = None) -> RunResult:
    """Execute one run (see the module docstring); never raises for a failed DUT or link.

    Raises
    ------
    ConfigError
        Before any recording is written, when the spec cannot be run as written.
    """
    started = time.perf_counter()
    spec.check()
    source = RunSource(
        spec.scenario,
        spec.tables,
        spec.seed,
        spec.schedule,
        trajectory=spec.trajectory,
        truth_rate_hz=spec.truth_rate_hz,
        duration_ns=spec.duration_ns,
        write_ideal=spec.write_ideal,
    )
    if spec.dut.kind == "in_process":
        estimator = create_estimator(str(spec.dut.name), spec.dut.config)
    epoch = parse_epoch(spec.scenario.meta.get("start_utc"), file=str(spec.scenario.path))
    lockstep = spec.clock.lockstep
    enc = TrafficEncoder(
        source.models,
        epoch_ns=epoch,
        lockstep=lockstep,
        schedule=spec.schedule,
        seed=spec.seed,
        commands=spec.commands,
        talker=spec.links.talker,
    )
    clock = LockstepClock() if lockstep else RealTimeClock(spec.clock.speed)
    timing = TimingLog()
    result = RunResult(Path(spec.out), "complete")
    rec = RecordingWriter(spec.out, epoch_ns=epoch)
    dut_in: InProcessDut | None = None
    dut_ext: ExternalDut | None = None
    out: DutOutputRecorder | None = None
    lateness: list[np.ndarray] = []
    t_done = 0
    try:
        rec.metadata(
            "run_start",
            {
                "kind": "run",
                **spec.run_start,
                **source.metadata(),
                "clock": spec.clock.mode,
                "clock_step_ms": f"{spec.clock.step_ns / 1e6:g}",
                "speed": f"{spec.clock.speed:g}",
                "dut": spec.dut.name or spec.dut.command or spec.dut.kind,
                "dut_kind": spec.dut.kind,
                "epoch_utc_ns": str(epoch),
                **host_metadata(),
            },
        )
        for name, data, media in spec.attachments:
            rec.attach(name, data, media)
        source.declare(rec, attach_scenario=not any(a[0].startswith("scenario/") for a in spec.attachments))
        declare_wire_topics(rec)
        rec.columnar_topic(
            WIRE_EVENTS_TOPIC.topic,
            WIRE_EVENTS_TOPIC.schema,
            WIRE_EVENTS_TOPIC.dtype,
            description=WIRE_EVENTS_TOPIC.description,
            units=WIRE_EVENTS_TOPIC.units,
        )
        rec.json_topic(COMMANDS_TOPIC, "bench.Command", {"type": "object"})
        for t, c in spec.commands:
            rec.write_json(COMMANDS_TOPIC, t, {"t_ns": t, "command": _COMMAND_NAMES.get(c, str(c)), "code": c})
        if not lockstep:
            rec.columnar_topic(
                TIMING_TOPIC,
                "bench.Timing",
                TIMING_DTYPE,
                description="scheduled bench time of each emission and its lateness",
                units={"t_ns": "ns", "lateness_ns": "ns"},
            )
        out = DutOutputRecorder(rec)
        if spec.dut.kind == "in_process":
            dut_in = InProcessDut(estimator, epoch)
        else:
            dut_ext = ExternalDut(spec.dut, spec.links, enc.encoder, lockstep=lockstep, on_lines=out.log)
        step = spec.clock.step_ns
        total = source.duration_ns - source.duration_ns % step  # the run ends on a step
        clock.start()
        t0 = 0
        while t0 < total:
            t1 = min(t0 + spec.window_ns, total)
            records = source.produce(rec, t0, t1)
            traffic = enc.window(records, t0, t1)
            write_can(rec, CAN_TX, traffic.can)
            write_serial(rec, SERIAL_TX["imu"], traffic.imu)
            write_serial(rec, SERIAL_TX["gnss"], traffic.gnss)
            if len(traffic.events):
                rec.write_block(WIRE_EVENTS_TOPIC.topic, traffic.events)
            if dut_ext is not None and t0 == 0:
                first = traffic.can.take(np.flatnonzero(traffic.can.can_id == BENCH_TIME_ID)[:1])
                dut_ext.start(first, out.feed, lambda frames: write_can(rec, CAN_TX, frames))
            k0 = 0 if t0 == 0 else t0 // step + 1
            step_times = np.arange(k0, t1 // step + 1, dtype=np.int64) * step
            if dut_in is not None:
                if lockstep:
                    out.feed(dut_in.exchange(traffic, step_times, t0))
                else:
                    for k, part in enumerate(_steps_of(traffic, step_times)):
                        t = int(step_times[k])
                        timing.add(t, clock.wait_until(t))
                        out.feed(dut_in.exchange(part, step_times[k : k + 1], int(step_times[k - 1]) + 1 if k else t0))
            elif lockstep:
                assert dut_ext is not None
                dut_ext.exchange_lockstep(traffic, step_times, spec.clock.timeout_s, out.feed)
            else:
                assert dut_ext is not None
                dut_ext.exchange_realtime(traffic, clock, timing, t1, out.feed)
            if not lockstep:
                t_late, late = timing.take()
                if len(t_late):
                    block = np.zeros(len(t_late), TIMING_DTYPE)
                    block["t_ns"], block["lateness_ns"] = t_late, late
                    rec.write_block(TIMING_TOPIC, block)
                    lateness.append(late)
            t_done = t1
            t0 = t1
            if progress is not None:
                progress(t0 * 1e-9, total * 1e-9)
        if not lockstep and spec.clock.budget is not None:
            summary = TimingLog.summarize(np.concatenate(lateness) if lateness else np.zeros(0, np.int64))
            if not summary.within(spec.clock.budget):
                raise TimingBudgetError(
                    f"real-time budget missed: {summary.text()} (budget p99 "
                    f"{spec.clock.budget.p99_ns / 1e3:g} us, max {spec.clock.budget.max_ns / 1e3:g} us)"
                )
    except BaseException as exc:  # the recording must say how the run ended, whatever happened
        result.status = _status_of(exc)
        result.reason = f"{type(exc).__name__}: {exc}" if not isinstance(exc, BenchError) else str(exc)
        if result.status == "error" and not isinstance(exc, BenchError):
            result.reason += " | " + traceback.format_exc(limit=4).strip().splitlines()[-3].strip()
        if not isinstance(exc, (BenchError, KeyboardInterrupt)):
            rec.metadata("run_traceback", {"traceback": traceback.format_exc()})
    finally:
        if dut_in is not None:
            try:
                dut_in.close()
            except Exception as exc:
                result.reason += f" (estimator close failed: {exc})"
            rec.metadata("dut_input_tally", dut_in.decoder.tally.as_dict())
        if dut_ext is not None:
            result.dut_exit = dut_ext.close()
            rec.metadata("dut_exit", result.dut_exit)
        if out is not None:
            out.write_bad()
            rec.metadata(
                "dut_output",
                {"solutions": out.solutions, "qualities": out.qualities, "bad_frames": out.tally.as_dict()},
            )
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
        result.counts = dict(source.stats.counts)
        result.bench_s = t_done * 1e-9
        result.elapsed_s = time.perf_counter() - started
        rec.metadata(
            "run_summary",
            {"bench_s": f"{result.bench_s:.3f}", "elapsed_s": f"{result.elapsed_s:.3f}", "counts": result.counts},
        )
        rec.close(result.status, result.reason)
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
