"""The lockstep loop of a run: window after window, every step handed to the DUT and its
answer awaited (ICD 6), or the in-process estimator called once per step.

An external DUT's first step is its start-up (:mod:`bench.run.startup`): sent in rounds
until the DUT answers, each part recorded as it goes out, so ``/wire/can/tx`` holds the
frames in the order they went out; the run's later BENCH_EPOCH and BENCH_TIME frames
continue the counters the rounds advanced.
"""

from __future__ import annotations

from bench.run.session import RunSession
from bench.run.startup import AliveShift, split_first_step

__all__ = ["run_lockstep"]


def run_lockstep(s: RunSession) -> None:
    """Run every window of ``s`` in lockstep (an external DUT's start-up first)."""
    out = s.out
    assert out is not None
    s.clock.start(s.start_ns)
    alive = AliveShift()
    for t0, t1 in s.windows:
        traffic, step_times = s.produce(t0, t1)
        if s.dut_ext is not None:
            if t0 == s.start_ns:
                first, traffic = split_first_step(traffic, s.start_ns)
                alive.started(s.dut_ext.start(first, out.feed, s.record_traffic))
                step_times = step_times[1:]
            traffic = alive.apply(traffic)
            s.record_traffic(traffic)
            s.dut_ext.exchange_lockstep(traffic, step_times, s.clock_spec.timeout_s, out.feed)
        else:
            s.record_traffic(traffic)
            assert s.dut_in is not None
            out.feed(s.dut_in.exchange(traffic, step_times, t0))
        s.report(t1)
