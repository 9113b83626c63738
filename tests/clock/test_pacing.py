import numpy as np

from bench.clock.pacing import LockstepClock, RealTimeClock, TimingBudget, TimingLog


def test_lockstep_never_waits():
    c = LockstepClock()
    c.start()
    assert c.wait_until(10**12) == 0 and c.now_ns() == 10**12


def test_real_time_clock_is_never_early():
    c = RealTimeClock(speed=4.0)
    c.start()
    for t in range(0, 40_000_000, 4_000_000):  # 40 ms of bench time at 4x: 10 ms wall
        assert c.wait_until(t) >= 0
        assert c.now_ns() >= t


def test_timing_log_and_budget():
    log = TimingLog(capacity=2)
    for i in range(1000):
        log.add(i, 1000 if i < 980 else 100_000)
    t, late = log.take()
    assert len(t) == 1000 and log.take()[0].size == 0
    s = TimingLog.summarize(late)
    assert s.p50_ns == 1000 and s.max_ns == 100_000
    assert not s.within(TimingBudget(p99_ns=50_000, max_ns=2_000_000))
    assert s.within(TimingBudget(p99_ns=200_000, max_ns=2_000_000))
    assert TimingLog.summarize(np.array([], dtype=np.int64)).count == 0
