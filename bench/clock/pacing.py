"""Clocks of a run: lockstep (simulated time) and real time (optionally scaled).

Real-time pacing sleeps until shortly before the due time and spins for the rest on the
monotonic clock, then reports the lateness of the emission. The lateness of every
emission is kept (:class:`TimingLog`) so a run can show its timing quality and end as
ERROR when it misses its budget.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

__all__ = ["Clock", "LockstepClock", "RealTimeClock", "TimingLog", "TimingBudget", "TimingSummary"]


class Clock(ABC):
    """Maps bench time to wall time."""

    #: True when bench time advances only as the bench says (lockstep).
    lockstep: bool

    @abstractmethod
    def start(self, origin_ns: int = 0) -> None:
        """Bench time ``origin_ns`` is now."""

    @abstractmethod
    def wait_until(self, t_ns: int) -> int:
        """Block until bench time ``t_ns``; return the lateness (ns, >= 0 when on time or late)."""

    @abstractmethod
    def now_ns(self) -> int:
        """Current bench time, ns."""


class LockstepClock(Clock):
    """Simulated time: bench time is whatever the bench has reached; nothing waits."""

    lockstep = True

    def __init__(self) -> None:
        self._t = 0

    def start(self, origin_ns: int = 0) -> None:
        self._t = int(origin_ns)

    def wait_until(self, t_ns: int) -> int:
        self._t = max(self._t, int(t_ns))
        return 0

    def now_ns(self) -> int:
        return self._t


class RealTimeClock(Clock):
    """Wall-clock pacing, ``speed`` times real time (0.5: half speed, 2: twice as fast).

    Parameters
    ----------
    speed:
        Bench seconds per wall second.
    spin_ns:
        The last part of every wait is spent spinning, not sleeping: a sleeping thread is
        woken late by the scheduler, and on a virtual machine whose CPU halts while it
        sleeps by the host too (measured here, 1 kHz, 30 s: 16-25 emissions more than 1 ms
        late spinning the last 300 us, 1-4 spinning the last 850 us). Spinning longer
        starves the kernel's work on that core: the pty's bytes reach the DUT later (with
        two busy loops beside it, 800 us made the measured DUT latency 0.9 ms longer than
        the DUT's own), so the default stays 300 us.
    spin_share:
        At most this share of the time between two waits is spun, so a loop of closely
        spaced emissions still sleeps (a ``SCHED_FIFO`` thread that never sleeps is stopped
        by the kernel's real-time throttling for 50 ms a second). A wait shorter than
        :data:`SLEEP_MIN_NS` is spun whole (a sleep that short is no more precise).
    """

    lockstep = False

    def __init__(self, speed: float = 1.0, spin_ns: int = 300_000, spin_share: float = 0.8):
        if speed <= 0.0:
            raise ValueError(f"speed must be positive, found {speed}")
        if not 0.0 <= spin_share <= 1.0:
            raise ValueError(f"spin_share must be within 0 .. 1, found {spin_share}")
        self.speed = float(speed)
        self._num, self._den = self.speed.as_integer_ratio()  # exact: never early by a rounding
        self.spin_ns = int(spin_ns)
        self.spin_share = float(spin_share)
        self._t0 = 0
        self._origin = 0
        self._back = 0  # when the last wait returned (monotonic ns)

    def start(self, origin_ns: int = 0, lead_ns: int = 0) -> None:
        """Bench time ``origin_ns`` is ``lead_ns`` from now."""
        self._back = time.monotonic_ns()
        self._t0 = self._back + int(lead_ns)
        self._origin = int(origin_ns)

    def anchor(self) -> dict[str, str]:
        """Where bench time sits on the host's ``CLOCK_MONOTONIC`` (after :meth:`start`):
        bench time ``origin_ns`` at monotonic ``monotonic_ns``, ``speed`` bench s per s."""
        return {"origin_ns": str(self._origin), "monotonic_ns": str(self._t0), "speed": f"{self.speed!r}"}

    def _wall(self, t_ns: int) -> int:
        return self._t0 - (self._origin - t_ns) * self._den // self._num  # rounded up

    def now_ns(self) -> int:
        return self._origin + (time.monotonic_ns() - self._t0) * self._num // self._den  # rounded down

    def at_monotonic(self, monotonic_ns: int) -> int:
        """Bench time at the host's ``CLOCK_MONOTONIC`` instant ``monotonic_ns``."""
        return self._origin + (monotonic_ns - self._t0) * self._num // self._den

    def wait_until(self, t_ns: int) -> int:
        due = self._wall(t_ns)
        now = time.monotonic_ns()
        left = due - now
        if left > SLEEP_MIN_NS:
            spin = min(self.spin_ns, int((due - self._back) * self.spin_share))
            if left > spin:
                time.sleep((left - spin) * 1e-9)
        now = time.monotonic_ns()
        while now < due:
            now = time.monotonic_ns()
        self._back = now
        return now - due


#: A wait shorter than this is spun whole (ns).
SLEEP_MIN_NS = 150_000


@dataclass(frozen=True)
class TimingBudget:
    """Limits on emission lateness of a real-time run (ns)."""

    p99_ns: int = 50_000
    max_ns: int = 2_000_000


@dataclass(frozen=True)
class TimingSummary:
    """Lateness statistics of a run, ns."""

    count: int
    p50_ns: float
    p99_ns: float
    p999_ns: float
    max_ns: float

    def within(self, budget: TimingBudget) -> bool:
        """Whether the run met the budget."""
        return self.p99_ns <= budget.p99_ns and self.max_ns <= budget.max_ns

    def text(self) -> str:
        """One line in microseconds."""
        return (f"{self.count} emissions, lateness p50 {self.p50_ns / 1e3:.1f} us, p99 {self.p99_ns / 1e3:.1f} us, "
                f"p99.9 {self.p999_ns / 1e3:.1f} us, max {self.max_ns / 1e3:.1f} us")


class TimingLog:
    """Scheduled bench times and measured lateness of every emission."""

    def __init__(self, capacity: int = 1 << 16):
        self._t = np.empty(capacity, dtype=np.int64)
        self._late = np.empty(capacity, dtype=np.int64)
        self._n = 0

    def add(self, t_ns: int, lateness_ns: int) -> None:
        """Record one emission."""
        if self._n == len(self._t):
            self._t = np.resize(self._t, 2 * len(self._t))
            self._late = np.resize(self._late, 2 * len(self._late))
        self._t[self._n] = t_ns
        self._late[self._n] = lateness_ns
        self._n += 1

    def reserve(self, n: int) -> None:
        """Room for ``n`` more entries, allocated and touched now (before a real-time loop:
        growing the log inside it copied the arrays and faulted in fresh pages, a 6-13 ms
        stall at the 65 536th emission)."""
        need = self._n + int(n)
        if need > len(self._t):
            t, late = np.zeros(need, np.int64), np.zeros(need, np.int64)
            t[: self._n], late[: self._n] = self._t[: self._n], self._late[: self._n]
            self._t, self._late = t, late
        self._t[self._n :].fill(0)  # touched: the pages are there
        self._late[self._n :].fill(0)

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """The entries recorded since the last take (for the recording)."""
        t, late = self._t[: self._n].copy(), self._late[: self._n].copy()
        self._n = 0
        return t, late

    @staticmethod
    def summarize(lateness_ns: np.ndarray) -> TimingSummary:
        """Percentiles of a lateness array."""
        if len(lateness_ns) == 0:
            return TimingSummary(0, 0.0, 0.0, 0.0, 0.0)
        p = np.percentile(lateness_ns, [50, 99, 99.9])
        return TimingSummary(len(lateness_ns), float(p[0]), float(p[1]), float(p[2]), float(np.max(lateness_ns)))
