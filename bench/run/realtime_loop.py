"""The real-time loop of a run: every window prepared (and its samples recorded) before
the clock starts, then every emission at its time on the clock, the DUT's frames
received as they come, the lateness of each emission measured, and the run's budget
checked at the end.

The emission loop does nothing but wait and send, once over the whole run (the windows
joined: :func:`~bench.run.realtime_plan.join_plans`; progress is reported at the end, as
anything else run between windows would stall the next emissions): an external DUT's frames are stamped
on arrival by a receive thread and decoded and recorded after the last emission
(:meth:`ExternalDut.end_realtime <bench.run.external.ExternalDut.end_realtime>`, which
also waits for the DUT's answer to the end of the run); nothing is written to the
recording while the clock runs. The clock's anchor (bench time at a ``CLOCK_MONOTONIC``
instant) is recorded as ``realtime_clock`` metadata, so stamps taken by another process
on the same host can be put on the bench's time axis.
"""

from __future__ import annotations

import numpy as np

from bench.clock import realtime_priority
from bench.clock.pacing import RealTimeClock, TimingLog
from bench.run.realtime_plan import join_plans
from bench.run.result import TimingBudgetError
from bench.run.session import RunSession
from bench.run.traffic import Traffic

__all__ = ["run_realtime", "steps_of", "START_LEAD_NS"]

#: Real time: the run's first instant (its first emissions) is this long after the clock
#: is started, so what is set up at the start (the receive thread, the recording's
#: metadata) does not make them late.
START_LEAD_NS = 50_000_000


def run_realtime(s: RunSession) -> None:
    """Run every window of ``s`` in real time, then check the timing budget."""
    out = s.out
    assert out is not None
    ext = s.dut_ext
    plans = []
    for t0, t1 in s.windows:
        traffic, step_times = s.prepare(t0, t1)
        if ext is not None:
            plans.append((t0, t1, ext.plan_realtime(traffic), step_times))
        else:
            plans.append((t0, t1, steps_of(traffic, step_times), step_times))
    if ext is not None:
        ext.start(None, out.feed)
        waited = ext.await_listening()
        s.rec.metadata("realtime_start", {"waited_for_dut_s": f"{waited:.3f}"})
    else:
        out.deferred = True  # the in-process DUT's output is recorded after the loop
    joined = join_plans([(t1, plan) for _, t1, plan, _ in plans]) if ext is not None else None
    clock, timing = s.clock, s.timing
    timing.reserve(len(joined.times) if joined is not None else sum(len(p[3]) for p in plans))
    s.rec.metadata("realtime_scheduling", realtime_priority.acquire())
    if isinstance(clock, RealTimeClock):  # the receive thread starts before the first emission is due
        clock.start(s.start_ns, lead_ns=START_LEAD_NS)
        s.rec.metadata("realtime_clock", clock.anchor())
    else:
        clock.start(s.start_ns)
    if ext is not None:
        assert joined is not None
        ext.begin_realtime(clock, out.feed)
        ext.exchange_realtime(joined, clock, timing, s.start_ns)
        ext.end_realtime(s.windows[-1][1] if s.windows else s.start_ns)
    else:
        for t0, t1, plan, step_times in plans:
            assert s.dut_in is not None
            for k, part in enumerate(plan):
                t = int(step_times[k])
                timing.add(t, clock.wait_until(t))
                lo = int(step_times[k - 1]) + 1 if k else t0
                out.feed(s.dut_in.exchange(part, step_times[k : k + 1], lo))
            s.report(t1)
    if ext is not None:
        s.report(s.windows[-1][1] if s.windows else s.start_ns)
    realtime_priority.release()
    out.deferred = False
    out.process()
    s.write_timing()
    budget = s.clock_spec.budget
    if budget is not None:
        summary = TimingLog.summarize(np.concatenate(s.lateness) if s.lateness else np.zeros(0, np.int64))
        if not summary.within(budget):
            raise TimingBudgetError(
                f"real-time budget missed: {summary.text()} (budget p99 {budget.p99_ns / 1e3:g} us, "
                f"max {budget.max_ns / 1e3:g} us)"
            )


def steps_of(traffic: Traffic, step_times: np.ndarray) -> list[Traffic]:
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
