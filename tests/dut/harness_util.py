"""The reference harness driven in this process: python-can's virtual bus as the bench's
side, two pty pairs as its serial lines, lockstep BENCH_TIMEs sent by hand."""

from __future__ import annotations

import os
import tty
import uuid
from dataclasses import dataclass, field

import can
import numpy as np

from bench.dut.harness import EstimatorError, Harness
from bench.frames import CanBatch, CanFrame
from bench.transport.can_link import CanConfig
from bench.wire.can import CanEncoder
from bench.wire.receive import NavOutput, NavReceiver

__all__ = ["HarnessRun", "drive_harness"]


@dataclass
class HarnessRun:
    """What the harness answered: decoded NAV output and DUT_READY times, and the error
    it ended with (None if it served every step)."""

    nav: NavOutput
    error: EstimatorError | None
    rejected: dict = field(default_factory=dict)


def drive_harness(name: str, config: dict, steps: int, extra: CanBatch | None = None) -> HarnessRun:
    """Send BENCH_EPOCH, then BENCH_TIME(k * 10 ms) with the lockstep bit for ``k < steps``
    (``extra`` frames before the first) to a harness around estimator ``name``; poll it
    until it has answered every step or ended with an :class:`EstimatorError`."""
    channel = f"harness-{uuid.uuid4().hex[:8]}"
    ptys = [os.openpty() for _ in range(2)]
    for _, slave in ptys:
        tty.setraw(slave)
    bench = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    h = None
    error = None
    answers: list[CanFrame] = []
    try:
        h = Harness(name, config, can=CanConfig(interface="virtual", channel=channel),
                    imu_port=os.ttyname(ptys[0][1]), gnss_port=os.ttyname(ptys[1][1]))
        enc = CanEncoder()
        times = np.arange(steps, dtype=np.int64) * 10_000_000
        parts = [enc.encode("BENCH_EPOCH", [0], epoch_utc_ns=[1_772_352_000 * 10**9])]
        if extra is not None:
            parts.append(extra)
        parts.append(enc.encode("BENCH_TIME", times, time_ns=times, lockstep=1))
        frames = CanBatch.concat(parts)
        for k in range(len(frames)):
            f = frames.frame(k)
            bench.send(can.Message(arbitration_id=f.can_id, data=f.data, is_extended_id=False))
        for _ in range(2000):  # a hang guard: each poll returns when frames are pending
            try:
                h.poll(timeout=0.05)
            except EstimatorError as exc:
                error = exc
            while (msg := bench.recv(0.0)) is not None:
                answers.append(CanFrame(len(answers), msg.arbitration_id, bytes(msg.data), msg.is_fd))
            ready = sum(f.can_id == 0x3F0 for f in answers)
            if error is not None or ready >= steps:
                break
    finally:
        if h is not None:
            h.close()
        bench.shutdown()
        for master, slave in ptys:
            os.close(master)
            os.close(slave)
    receiver = NavReceiver()
    nav = receiver.feed(CanBatch.from_frames(answers)) if answers else NavOutput()
    receiver.finish()
    return HarnessRun(nav, error, receiver.tally.as_dict())
