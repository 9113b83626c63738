"""How a run is finished, whatever ended it: the ending noted (:func:`note_ending`), then
every cleanup step guarded (:func:`finish`): the scheduling policy given back, the DUT
shut down, its output, the timing and the run summary recorded, the Foxglove views derived
from the recording (:mod:`bench.scoring.viewwrite`; not after an interrupt), and ``run_end``
written.
A failing step is noted in the reason and the others still run; an interrupt during the
cleanup (a third signal: the DUT is killed at once) is raised once the file is finished.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable

import numpy as np

from bench.clock import realtime_priority
from bench.clock.pacing import TimingLog
from bench.crashlog import write_traceback
from bench.errors import BenchError, DutError
from bench.run.result import reason_of, status_of
from bench.run.session import RunSession
from bench.scoring.viewwrite import add_views

__all__ = ["note_ending", "finish"]


def note_ending(s: RunSession, exc: BaseException) -> KeyboardInterrupt | None:
    """The run's status and reason from the exception that ended it (with its traceback
    where that helps); the interrupt to raise again, if it was one."""
    s.result.status = status_of(exc)
    s.result.reason = reason_of(exc)
    if isinstance(exc, KeyboardInterrupt):
        return exc
    if not isinstance(exc, BenchError):
        s.rec.metadata("run_traceback", {"traceback": traceback.format_exc()})
    elif isinstance(exc, DutError) and exc.__cause__ is not None and not isinstance(exc.__cause__, BenchError):
        # an in-process estimator raised: its traceback in the recording (and on /dut/log,
        # written where it raised) and in the crash log beside the recording
        tb = "".join(traceback.format_exception(exc.__cause__))
        s.rec.metadata("dut_traceback", {"traceback": tb})
        log = write_traceback(exc.__cause__, s.result.path.parent, context=f"DUT error (not the bench's): {exc}")
        if log is not None:
            s.result.reason += f" (traceback in {log})"
    return None


def finish(s: RunSession, interrupt: KeyboardInterrupt | None) -> KeyboardInterrupt | None:
    """Every cleanup step of the run, guarded, then ``run_end``; the interrupt to raise
    (``interrupt``, or one that came during the cleanup)."""
    result, rec = s.result, s.rec
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

    if not s.lockstep:  # a real-time run that failed in its emission loop still holds them
        guarded("restoring the scheduling policy and the garbage collector", realtime_priority.release)
    dut_in, dut_ext, out = s.dut_in, s.dut_ext, s.out
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
        s.write_timing()
        if s.lateness:
            result.timing = t = TimingLog.summarize(np.concatenate(s.lateness))
            rec.metadata(
                "timing_summary",
                {"count": t.count, "p50_ns": t.p50_ns, "p99_ns": t.p99_ns, "p999_ns": t.p999_ns, "max_ns": t.max_ns},
            )

    guarded("recording the timing", finish_timing)

    def finish_summary() -> None:
        result.counts = s.provider.counts()
        result.bench_s = s.t_done * 1e-9
        result.elapsed_s = time.perf_counter() - s.started
        rec.metadata(
            "run_summary",
            {"bench_s": f"{result.bench_s:.3f}", "elapsed_s": f"{result.elapsed_s:.3f}", "counts": result.counts},
        )

    guarded("run_summary", finish_summary)
    if result.status != "interrupted" and not late:  # derived from what was recorded, so last
        guarded("writing the Foxglove views", lambda: add_views(rec))
    if late and interrupt is None:
        interrupt = late[0]
        if result.status == "complete":
            result.status, result.reason = "interrupted", reason_of(interrupt) + " while finishing the run"
    rec.close(result.status, result.reason)
    return interrupt
