"""The real-time side of the external DUT adapter (:class:`~bench.run.external.ExternalDut`
inherits it): emission on the clock, receiving on arrival, the end of the run.

* **Before the clock starts** (:meth:`RealtimeExchange.await_listening`): the DUT has
  opened the slave end of every pty line (its process group holds it open, seen in
  ``/proc``), within the start-up timeout. Until then nobody reads those lines, the
  first emissions fill the ptys and the bench's writes would wait for the DUT.
* **Emission** (:meth:`RealtimeExchange.exchange_realtime`): every frame and byte group
  at its time on the clock; the loop waits, sends and measures the lateness, and does
  nothing else but a flood check per emission and a look at the DUT process every 100 ms
  of bench time. It never waits on the DUT: bytes a full pty does not take (a DUT that
  lags) are kept, in order, and written as the DUT takes them; a line that takes nothing
  for its ``write_timeout`` is a DUT that stopped reading. How often and how long each
  line was held is in ``dut_exit`` (``serial_held``).
* **Receiving** (:class:`~bench.transport.can_link.CanReceiveThread`): every DUT frame is
  stamped with the bench time it arrives at by a thread, whatever the emission loop is
  doing; nothing is decoded or recorded while the clock runs.
* **The end** (:meth:`RealtimeExchange.end_realtime`): after the last emission the bench
  keeps receiving until the DUT's answer to the end of the run has come (a NAV_SOLUTION
  valid at the run's end or later), at most :data:`LINGER_S`, then hands everything
  received over to be decoded and recorded.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench.clock.pacing import Clock, RealTimeClock, TimingLog
from bench.errors import DutError, LinkError
from bench.frames import CanBatch
from bench.run.realtime_plan import EMIT_CAN, EMIT_GNSS, EMIT_IMU, RealtimePlan, plan_emissions
from bench.run.traffic import Traffic
from bench.shield import shielded
from bench.transport.can_rx import CanReceiveThread
from bench.wire.can import codec

__all__ = ["RealtimeExchange", "LINGER_S"]

_SOLUTION = codec("NAV_SOLUTION")
#: Real time: how long (wall seconds) the bench waits after its last emission for the
#: DUT's answer to the end of the run.
LINGER_S = 2.0
#: Real time: how many emissions ahead of the clock the emission loop keeps the plan
#: touched (about 2 s of 1 kHz traffic).
WARM_AHEAD = 2048
#: ... in the steps followed by at least this much time before the next emission (ns).
WARM_SLACK_NS = 300_000


def _opened_by_group(pgid: int, paths: set[str]) -> set[str]:
    """Which of ``paths`` a process of process group ``pgid`` holds open (Linux ``/proc``)."""
    found: set[str] = set()
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            if os.getpgid(int(entry.name)) != pgid:
                continue
            for fd in os.scandir(f"/proc/{entry.name}/fd"):
                with contextlib.suppress(OSError):
                    target = os.readlink(fd.path)
                    if target in paths:
                        found.add(target)
        except OSError:  # gone meanwhile, or not ours to look at
            continue
    return found


class RealtimeExchange:
    """The real-time methods of :class:`~bench.run.external.ExternalDut` (see the module
    docstring); the attributes they use are set up there."""

    def _bench_now(self) -> int:
        """Bench time now: the run's clock in real time, the step reached in lockstep."""
        clock = self._rt_clock
        return clock.now_ns() if clock is not None else self.now_ns

    def _bench_at(self, realtime_ns: int) -> int:
        """Bench time of an arrival the kernel stamped (CLOCK_REALTIME ns), so the stamp does
        not depend on when the receive thread got to run; in lockstep the step reached.

        The realtime clock's offset to the monotonic one is bounded from below by a read
        of the realtime clock followed by one of the monotonic clock (their difference: a
        pause between them only lowers it), and the largest such bound over the last second is
        used, so a stamp is never put before the frame arrived (a pause makes it at most
        that pause late, never early) and the host clock's slewing cannot accumulate."""
        clock = self._rt_clock
        if not isinstance(clock, RealTimeClock):
            return self._bench_now()
        r = time.time_ns()
        mono = time.monotonic_ns()
        low = r - mono
        best, since = self._rt_offset
        if low >= best or mono - since > 1_000_000_000:
            best, since = low, mono
            self._rt_offset = (best, since)
        arrival = realtime_ns - best
        if not mono - 1_000_000_000 < arrival <= mono:  # the host clock stepped meanwhile: now is all we know
            arrival = mono
        return clock.at_monotonic(arrival)

    def plan_realtime(self, traffic: Traffic) -> RealtimePlan:
        """Prepare one window's emissions before the clock starts (real time)."""
        return plan_emissions(traffic, self.imu_baud, self.gnss_baud)

    def await_listening(self, poll_s: float = 0.01) -> float:
        """Real time, before the clock starts: wait until the DUT process (any process of
        its group) has opened the slave end of every pty line, within the start-up timeout
        (ICD 5: listening within 5 s); returns the seconds waited. Until it has, nobody
        reads those lines: the first emissions would fill the pty and the bench's writes
        would block for as long as the DUT takes to start (measured: 100-800 ms stalls of
        the emission loop at the start of a run). Lines that are no ptys, hardware DUTs and
        hosts without ``/proc`` are not waited for."""
        ptys = {os.path.realpath(link.dut_port) for link in self.serial.values() if link.dut_port}
        if self.process is None or not ptys or not Path("/proc/self/fd").is_dir():
            return 0.0
        t0 = time.monotonic()
        deadline = t0 + self.spec.startup_timeout_s
        pgid = self.process.pid  # the DUT leads its own session and group
        while True:
            missing = ptys - _opened_by_group(pgid, ptys)
            if not missing:
                return time.monotonic() - t0
            self._check_process("during start-up")
            if time.monotonic() > deadline:
                raise DutError(
                    f"the DUT did not open {', '.join(sorted(missing))} within {self.spec.startup_timeout_s:g} s "
                    "of its start (ICD 5: listening within 5 s)" + self._tail()
                )
            time.sleep(poll_s)

    def begin_realtime(self, clock: Clock, received: Callable[[CanBatch], None]) -> None:
        """The clock has started: from now on every frame the DUT sends is stamped with the
        bench time it arrives at, by a thread, and handed to ``received`` after the last
        emission (:meth:`end_realtime`), or at :meth:`close` if the run stopped before."""
        assert self.can is not None
        self._rt_clock = clock
        self._rx_to = received
        self._rx = CanReceiveThread(self.can)

    def exchange_realtime(self, plan: RealtimePlan, clock: Clock, timing: TimingLog, start_ns: int) -> None:
        """Emit the run's traffic on the clock (after :meth:`begin_realtime`): wait, send,
        measure the lateness; nothing else but a flood check per emission (per window of
        ``plan``, a joined plan: :func:`~bench.run.realtime_plan.join_plans`) and a look at
        the DUT process every 100 ms of bench time."""
        starts = [start_ns, *plan.window_t1[:-1]]
        floods = [
            int(self.spec.flood_frames_per_s * max(1e-9 * (t1 - t0), 0.01)) + 100
            for t0, t1 in zip(starts, plan.window_t1, strict=True)
        ]
        with self._dut_side():
            self._emit(plan, clock, timing, floods)
        self.now_ns = plan.window_t1[-1] if plan.window_t1 else start_ns

    def _emit(self, plan: RealtimePlan, clock: Clock, timing: TimingLog, floods: list[int]) -> None:
        """The emission loop, once over the whole run. Memory idle for seconds is slow to
        touch on a virtual machine (:mod:`bench.run.realtime_plan`), and the plan was made
        before the clock started: after each step's sends the loop touches the plan up to
        :data:`WARM_AHEAD` emissions ahead (a few emissions per step, so the slow first
        touch falls in the slack after a send, not between a wait and its send), and before
        each wait the emissions it is about to make. The lateness is recorded after the
        sends."""
        assert self.can is not None and self._rx is not None
        can, rx = self.can, self._rx
        send_can = can.send
        writes = (None, self.serial["imu"].write_some, self.serial["gnss"].write_some)
        held = self._held
        times, kinds, index = plan.times, plan.kinds, plan.index
        payloads = (plan.can, plan.imu, plan.gnss)
        on_can = EMIT_CAN  # locals: no global lookups per emission
        wait_until, add = clock.wait_until, timing.add
        n = len(times)
        ends, t1s = plan.ends or [n], plan.window_t1 or [self.now_ns]
        w, end, flood = 0, ends[0], floods[0] if floods else 1 << 62
        n0, odd0 = rx.arrived, can.remote + can.error_frames  # every frame counts
        k = warm = 0
        next_check = self.now_ns  # the DUT process is checked every 100 ms of bench time
        while k < n:
            t = times[k]
            j = k
            while j < n and times[j] == t:  # touch what is sent at t, before the wait
                data = payloads[kinds[j]][index[j]]
                if kinds[j] == on_can:
                    data = data.data
                data[-1:]
                j += 1
            late = wait_until(t)
            while k < j:
                kind = kinds[k]
                data = payloads[kind][index[k]]
                if kind == on_can:
                    send_can(data)
                elif held[kind]:  # the DUT has not taken the line's earlier bytes yet: after them
                    held[kind].extend(data)
                else:
                    m = writes[kind](data)  # never waits
                    if m < len(data):
                        self._hold(kind, data[m:])
                k += 1
            add(t, late)
            if held[1] or held[2]:
                self._retry_held()
            if rx.arrived - n0 > flood or rx.full:
                n0 = self._flood_check(rx, t, n0, flood, odd0)
            if k >= end and w + 1 < len(ends):  # the next window: its own flood count
                self.now_ns = t1s[w]
                w += 1
                end, flood = ends[w], floods[w]
                n0, odd0 = rx.arrived, can.remote + can.error_frames
            if warm < k:
                warm = k
            # keep the next seconds of the plan warm, 4 emissions per step with time to spare
            stop = min(n, k + WARM_AHEAD, warm + 4) if k < n and times[k] - t > WARM_SLACK_NS else warm
            while warm < stop:
                data = payloads[kinds[warm]][index[warm]]
                if kinds[warm] == on_can:
                    data = data.data
                data[-1:]
                warm += 1
            if t >= next_check:  # a few microseconds every 100 ms, late or not
                next_check = t + 100_000_000
                self.now_ns = t
                self._check_process()
                if rx.error is not None:
                    raise LinkError(f"receiving from the DUT failed: {rx.error}") from rx.error

    def _flood_check(self, rx: CanReceiveThread, t: int, n0: int, flood: int, odd0: int) -> int:
        """More than ``flood`` frames arrived in this window (counted from ``n0``): a
        :class:`DutError` if they are the DUT's (decoded now, where decoding is deferred:
        stray datagrams do not count); else the count to go on from."""
        got = rx.arrived - n0
        peers = rx.settle(got)
        if peers > flood or rx.full:
            self.now_ns = t
            self._flush_lines()
            raise DutError(
                f"the DUT floods the bus: {peers} frames{self._odd_frames(odd0)} in one window (limit {flood})"
            )
        return n0 + got - peers  # the strays do not count

    def _hold(self, kind: int, rest: bytes) -> None:
        """A pty line is full (its DUT has not read): keep the bytes, in order, for later."""
        name = "imu" if kind == EMIT_IMU else "gnss"
        self._held[kind].extend(rest)
        self._held_since[kind] = self._held_start[kind] = time.monotonic()
        st = self.held_stats.setdefault(name, {"episodes": 0, "max_bytes": 0, "longest_s": 0.0})
        st["episodes"] += 1

    def _retry_held(self) -> None:
        """Write what the full lines take now; a line whose DUT takes nothing for its
        ``write_timeout`` is a DUT that stopped reading."""
        now = time.monotonic()
        for kind in (EMIT_IMU, EMIT_GNSS):
            buf = self._held[kind]
            if not buf:
                continue
            name = "imu" if kind == EMIT_IMU else "gnss"
            link = self.serial[name]
            st = self.held_stats[name]
            st["max_bytes"] = max(st["max_bytes"], len(buf))
            m = link.write_some(bytes(buf))
            if m:
                del buf[:m]
                if not buf:
                    st["longest_s"] = max(st["longest_s"], round(now - self._held_start[kind], 6))
                    continue
                self._held_since[kind] = now  # progress: the DUT reads, slowly
            elif now - self._held_since[kind] > link.config.write_timeout:
                raise LinkError(
                    f"{link!r}: the DUT on {link.dut_port} took no bytes for {link.config.write_timeout:g} s "
                    f"({len(buf)} bytes waiting)"
                )

    def end_realtime(self, end_ns: int, linger_s: float = LINGER_S) -> None:
        """After the last emission: receive until the DUT's answer to ``end_ns`` (a
        NAV_SOLUTION valid at ``end_ns`` or later) has come, at most ``linger_s`` wall
        seconds, then stop the receive thread and hand over everything it received."""
        assert self._rx is not None
        with self._dut_side():
            for kind, name in ((EMIT_IMU, "imu"), (EMIT_GNSS, "gnss")):
                if self._held[kind]:  # the bytes a lagging DUT has not taken yet
                    self.serial[name].write(bytes(self._held[kind]))
                    self._held[kind].clear()
        deadline = time.monotonic() + linger_s
        got = self._lingered  # close() hands them over too if a signal ends the wait
        while True:
            with shielded():  # taken is kept
                batch = self._rx.take()
                if len(batch):
                    got.append(batch)
                sel = np.flatnonzero(batch.can_id == _SOLUTION.frame_id)
                if sel.size:
                    values, status = _SOLUTION.decode(batch.take(sel))
                    if np.any(values["t_ns"][status == 0] >= end_ns):
                        break
            if time.monotonic() >= deadline or self._rx.error is not None:
                break
            self._check_process()
            time.sleep(0.005)
        self.now_ns = end_ns
        self._stop_receiving(got)
        self._check_process()
        self._flush_lines()

    def _stop_receiving(self, got: list[CanBatch] | None = None, *, check: bool = True) -> None:
        """Stop the real-time receive thread and hand over what it received (idempotent);
        ``check``: raise :class:`LinkError` if receiving had failed."""
        with shielded():  # what was received is recorded, whenever a signal comes
            rx, self._rx = self._rx, None
            if rx is None:
                return
            frames = CanBatch.concat([*(self._lingered if got is None else got), rx.stop()])
            self._lingered = []
            if len(frames) and self._rx_to is not None:
                self._rx_to(frames)
        if check and rx.error is not None:
            raise LinkError(f"receiving from the DUT failed: {rx.error}") from rx.error
