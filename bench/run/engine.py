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
``dut_failed``      the DUT failed: it crashed or exited, hung past the timeout, never
                    started, stopped reading its lines, flooded the bus, or (in process)
                    raised, hung or returned what no NAV frame carries -- judged FAIL;
``dut_error``       the DUT ended in a way the bench cannot pin on it: killed by a SIGKILL
                    the bench did not send (the OOM killer, an operator), a MemoryError in
                    process (:class:`~bench.errors.DutError` ``certain=False``);
``link_lost``       a link failed;
``timing_budget``   a real-time run missed its lateness budget;
``interrupted``     Ctrl-C or SIGTERM;
``error``           the bench failed (the reason says how).

``complete`` is judged on the recording; ``dut_failed`` makes the verdict FAIL with the
reason; every other ending makes it ERROR: the bench could not judge the DUT.

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

The parts: :mod:`bench.run.session` (set-up and the run's state),
:mod:`bench.run.lockstep_loop`, :mod:`bench.run.realtime_loop` and
:mod:`bench.run.finish` (the guarded cleanup and ``run_end``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from bench.errors import RecordingError
from bench.run.finish import finish, note_ending
from bench.run.lockstep_loop import run_lockstep
from bench.run.provider import COMMANDS_TOPIC, SynthProvider, TrafficProvider
from bench.run.realtime_loop import run_realtime
from bench.run.result import RunResult, TimingBudgetError
from bench.run.session import TIMING_DTYPE, TIMING_TOPIC, open_session
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec

__all__ = [
    "RunResult",
    "run",
    "execute",
    "TrafficProvider",
    "SynthProvider",
    "TimingBudgetError",
    "TIMING_TOPIC",
    "TIMING_DTYPE",
    "COMMANDS_TOPIC",
]


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
    s = open_session(
        provider, dut, links, clock_spec, out_path, window_ns=window_ns, progress=progress, overwrite=overwrite
    )
    interrupt: KeyboardInterrupt | None = None
    try:
        s.begin(run_start, attachments)
        if s.lockstep:
            run_lockstep(s)
        else:
            run_realtime(s)
    except BaseException as exc:  # the recording must say how the run ended, whatever happened
        interrupt = note_ending(s, exc)
    finally:
        interrupt = finish(s, interrupt)
    if interrupt is not None:
        raise interrupt
    if s.rec.error is not None:
        raise RecordingError(f"{out_path}: {s.rec.error}")
    return s.result
