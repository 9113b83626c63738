"""The lockstep loop of a run: window after window, every step handed to the DUT and its
answer awaited (ICD 6), or the in-process estimator called once per step."""

from __future__ import annotations

import numpy as np

from bench.record.wire_topics import CAN_TX, write_can
from bench.run.session import RunSession
from bench.run.traffic import BENCH_TIME_ID

__all__ = ["run_lockstep"]


def run_lockstep(s: RunSession) -> None:
    """Run every window of ``s`` in lockstep (the DUT's start-up handshake first)."""
    out = s.out
    assert out is not None
    s.clock.start(s.start_ns)
    for t0, t1 in s.windows:
        traffic, step_times = s.prepare(t0, t1)
        if s.dut_ext is not None:
            if t0 == s.start_ns:
                first = traffic.can.take(np.flatnonzero(traffic.can.can_id == BENCH_TIME_ID)[:1])
                s.dut_ext.start(first, out.feed, lambda frames: write_can(s.rec, CAN_TX, frames))
            s.dut_ext.exchange_lockstep(traffic, step_times, s.clock_spec.timeout_s, out.feed)
        else:
            assert s.dut_in is not None
            out.feed(s.dut_in.exchange(traffic, step_times, t0))
        s.report(t1)
