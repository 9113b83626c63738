"""Real-time scheduling of the emission loop: every thread of the process gets the policy
(a helper thread under the normal policy holding the interpreter lock would stop the loop
whenever an ordinary process preempts it) and gets its own back; the clock's anchor puts
monotonic stamps on bench time."""

from __future__ import annotations

import os
import threading

import pytest

from bench.clock import pacing, realtime_priority
from bench.clock.pacing import RealTimeClock


def test_every_thread_gets_the_policy_and_gets_its_own_back(monkeypatch):
    monkeypatch.delenv("BENCH_RT_PRIORITY", raising=False)
    stop = threading.Event()
    helper = threading.Thread(target=stop.wait, daemon=True)
    helper.start()
    before = os.sched_getscheduler(helper.native_id), os.sched_getscheduler(0)
    try:
        got = realtime_priority.acquire(10)
        if got["policy"] != "SCHED_FIFO":
            pytest.skip(f"SCHED_FIFO not permitted here: {got}")
        assert os.sched_getscheduler(0) == os.SCHED_FIFO
        assert os.sched_getscheduler(helper.native_id) == os.SCHED_FIFO  # the helper too
        assert os.sched_getparam(helper.native_id).sched_priority == 10
        assert int(got["threads"]) >= 2
        late = threading.Thread(target=lambda: None)  # a thread started now inherits it
        late.start()
        late.join()
    finally:
        realtime_priority.release()
    assert (os.sched_getscheduler(helper.native_id), os.sched_getscheduler(0)) == before
    stop.set()
    helper.join()


def test_the_anchor_puts_monotonic_stamps_on_bench_time(monkeypatch):
    class Fake:
        now = 5_000_000_000_000

        def monotonic_ns(self) -> int:
            return self.now

    fake = Fake()
    monkeypatch.setattr(pacing, "time", fake)
    clock = RealTimeClock(speed=2.0)
    clock.start(7_000_000_000)
    a = clock.anchor()
    assert a == {"origin_ns": "7000000000", "monotonic_ns": str(fake.now), "speed": "2.0"}
    fake.now += 1_000_000  # 1 ms of wall time later: 2 ms of bench time
    stamp = int(a["origin_ns"]) + round((fake.now - int(a["monotonic_ns"])) * float(a["speed"]))
    assert clock.now_ns() == stamp == 7_002_000_000
