"""Clocks: lockstep never waits; real-time pacing sleeps, then spins, never returns early,
and reports how late it returned.

The real-time clock is driven here by a fake monotonic clock (every read advances it by
a tick, every sleep by the time asked plus an oversleep), so what is asserted is the
mechanism, never how fast this machine is (the figures are in benchmarks/bench_run.py).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.clock import pacing
from bench.clock.pacing import LockstepClock, RealTimeClock, TimingBudget, TimingLog


class FakeTime:
    """``time`` as the clock uses it: ``monotonic_ns`` advances ``tick`` ns per read,
    ``sleep(s)`` advances ``s`` plus ``oversleep`` ns (a late wake-up)."""

    def __init__(self, start: int = 10**15, tick: int = 1, oversleep: int = 0):
        self.now, self.tick, self.oversleep = start, tick, oversleep
        self.sleeps: list[float] = []

    def monotonic_ns(self) -> int:
        self.now += self.tick
        return self.now

    def sleep(self, s: float) -> None:
        assert s >= 0, s
        self.sleeps.append(s)
        self.now += round(s * 1e9) + self.oversleep


@pytest.fixture
def fake(monkeypatch) -> FakeTime:
    t = FakeTime()
    monkeypatch.setattr(pacing, "time", t)
    return t


def test_lockstep_never_waits():
    c = LockstepClock()
    c.start()
    assert c.wait_until(10**12) == 0 and c.now_ns() == 10**12
    assert c.wait_until(5) == 0 and c.now_ns() == 10**12  # bench time never goes back


def test_a_far_emission_is_slept_for_up_to_the_spin_window_then_spun_for(fake):
    c = RealTimeClock(speed=1.0, spin_ns=300_000)
    fake.tick = 1_000
    c.start()
    t0 = fake.now
    late = c.wait_until(10_000_000)  # 10 ms ahead
    assert len(fake.sleeps) == 1 and fake.sleeps[0] * 1e9 == pytest.approx(10_000_000 - 300_000, abs=2 * fake.tick)
    assert fake.now >= t0 + 10_000_000 and late == fake.now - (t0 + 10_000_000)
    assert late < fake.tick  # the first read at or past the due time ends the spin
    fake.sleeps.clear()
    c.wait_until(10_100_000)  # shorter than a sleep worth taking: spun whole
    assert fake.sleeps == [] and fake.now >= t0 + 10_100_000


def test_closely_spaced_waits_spin_at_most_their_share_and_sleep_the_rest(fake):
    """A long spin window never makes a loop of emissions spin all the time (SCHED_FIFO
    would be throttled by the kernel): of each 500 us between two waits, 80 % is spun."""
    c = RealTimeClock(speed=1.0, spin_ns=800_000, spin_share=0.8)
    fake.tick = 1_000
    c.start()
    for k in range(1, 21):
        fake.sleeps.clear()
        back = fake.now
        c.wait_until(k * 500_000)
        if k > 1:  # each wait begins where the last one returned
            assert len(fake.sleeps) == 1
            assert fake.sleeps[0] * 1e9 == pytest.approx(0.2 * 500_000, abs=3 * fake.tick)
        assert fake.now >= back
    fake.sleeps.clear()
    c.wait_until(20 * 500_000 + 5_000_000)  # a far one: sleeps all but the spin window
    assert fake.sleeps[0] * 1e9 == pytest.approx(5_000_000 - 800_000, abs=3 * fake.tick)


def test_a_late_wake_up_is_reported_as_lateness_not_hidden(fake):
    c = RealTimeClock(speed=1.0, spin_ns=300_000)
    fake.tick, fake.oversleep = 1_000, 2_000_000  # the kernel wakes us 2 ms late
    c.start()
    t0 = fake.now
    late = c.wait_until(50_000_000)
    assert late == fake.now - (t0 + 50_000_000)
    assert 1_700_000 - fake.tick <= late <= 1_700_000 + fake.tick  # 2 ms over, 0.3 ms of it the spin window
    assert c.wait_until(0) == fake.now - t0  # a time long past: returns at once with its lateness


@settings(max_examples=150, deadline=None)
@given(
    speed=st.sampled_from([1.0, 2.0, 4.0, 0.5, 3.0, 0.3, 7.3, 1 / 3, 0.1, 1.7]),
    origin=st.integers(-(10**12), 10**12),
    steps=st.lists(st.integers(0, 30_000_000), min_size=1, max_size=8),
    tick=st.integers(1, 50_000),
    oversleep=st.integers(0, 3_000_000),
)
def test_real_time_clock_is_never_early_at_any_speed(speed, origin, steps, tick, oversleep):
    fake = FakeTime(tick=tick, oversleep=oversleep)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pacing, "time", fake)
        _never_early(RealTimeClock(speed=speed, spin_ns=300_000), fake, speed, origin, steps, tick, oversleep)


def _never_early(c: RealTimeClock, fake: FakeTime, speed: float, origin: int, steps: list[int], tick: int,
                 oversleep: int) -> None:
    c.start(origin)
    t0 = fake.now
    t = origin
    for dt in steps:
        t += dt
        due = t0 + Fraction(t - origin) / Fraction(speed)  # exact wall time of bench time t
        entry = fake.now
        late = c.wait_until(t)
        back = fake.now
        assert back >= due, f"returned {float(due - back)} ns early"
        assert late >= 0 and abs(late - (back - due)) < 1  # the lateness it reports is how late it was
        if oversleep == 0:
            assert back - max(due, entry) < 2 * tick + 1  # spun to it, not slept past it (two reads)
        assert c.now_ns() >= t  # bench time read after the wait has reached t


def test_timing_log_and_budget():
    log = TimingLog(capacity=2)
    for i in range(1000):
        log.add(i, 1000 if i < 980 else 100_000)
    t, late = log.take()
    assert len(t) == 1000 and log.take()[0].size == 0
    assert t.tolist() == list(range(1000))  # grown past its capacity, nothing lost
    s = TimingLog.summarize(late)
    assert s.p50_ns == 1000 and s.max_ns == 100_000 and s.count == 1000
    assert not s.within(TimingBudget(p99_ns=50_000, max_ns=2_000_000))
    assert s.within(TimingBudget(p99_ns=200_000, max_ns=2_000_000))
    assert not s.within(TimingBudget(p99_ns=200_000, max_ns=99_999))  # the max alone can miss it
    assert TimingLog.summarize(np.array([], dtype=np.int64)).count == 0


def test_a_start_with_a_lead_puts_the_origin_that_far_ahead(fake):
    c = RealTimeClock(speed=1.0, spin_ns=300_000)
    fake.tick = 1_000
    c.start(5_000_000_000, lead_ns=50_000_000)
    t0 = fake.now
    assert c.now_ns() < 5_000_000_000 - 49_000_000  # the run's first instant is 50 ms away
    assert int(c.anchor()["monotonic_ns"]) == t0 + 50_000_000
    late = c.wait_until(5_000_000_000)
    assert fake.now >= t0 + 50_000_000 and late < fake.tick


def test_a_reserved_timing_log_never_grows_inside_the_loop():
    log = TimingLog(capacity=4)
    log.add(1, 10)
    log.reserve(100_000)
    arrays = log._t, log._late
    for i in range(100_000):
        log.add(i + 2, i)
    assert log._t is arrays[0] and log._late is arrays[1]  # no copy, no new pages while it ran
    t, late = log.take()
    assert t[0] == 1 and late[0] == 10 and len(t) == 100_001 and late[-1] == 99_999
