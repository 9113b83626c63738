"""The reference harness (bench.dut.harness) and the lockstep start-up rounds: each round
repeats BENCH_TIME(0) as a new transmission (its own alive counter), so the harness sees
several BENCH_TIME(0) when it answers slower than a round. It answers each with
DUT_READY(0) but steps its estimator once per bench time: one solution per epoch (two
runs side by side in tests/transport/test_udp_runs.py showed ten solutions at 0 s).
"""

from __future__ import annotations

import os
import tty
import typing
import uuid

import can
import numpy as np

from bench.dut.estimator import DutInputs, Estimator, EstimatorOutput, register_estimator
from bench.dut.harness import Harness
from bench.frames import CanBatch
from bench.topics import NAV_SOLUTION_DTYPE
from bench.transport.can_link import CanConfig
from bench.wire.can import CanEncoder, codec


class _OnePerStep(Estimator):
    name = "one_per_step_startup_test"
    stepped: typing.ClassVar[list[int]] = []

    def configure(self, config):
        _OnePerStep.stepped = []

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        _OnePerStep.stepped.append(inputs.t_ns)
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol)


def test_repeated_bench_time_of_the_start_up_is_answered_but_stepped_once():
    register_estimator(_OnePerStep.name, _OnePerStep)
    channel = f"harness-{uuid.uuid4().hex[:8]}"
    ptys = [os.openpty() for _ in range(2)]
    for _, slave in ptys:
        tty.setraw(slave)
    bench = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    h = Harness(_OnePerStep.name, {}, can=CanConfig(interface="virtual", channel=channel),
                imu_port=os.ttyname(ptys[0][1]), gnss_port=os.ttyname(ptys[1][1]))
    try:
        enc = CanEncoder()
        parts = []
        for i in range(3):  # three start-up rounds, the counters advancing
            parts.append(enc.encode("BENCH_EPOCH", [0], epoch_utc_ns=[1_772_352_000 * 10**9], alive=[i]))
            parts.append(enc.encode("BENCH_TIME", [0], time_ns=[0], lockstep=1, alive=[i]))
        parts.append(enc.encode("BENCH_TIME", [10_000_000], time_ns=[10_000_000], lockstep=1, alive=[3]))
        frames = CanBatch.concat(parts)
        for k in range(len(frames)):
            f = frames.frame(k)
            bench.send(can.Message(arbitration_id=f.can_id, data=f.data, is_extended_id=False))
        answers = []
        for _ in range(400):  # a hang guard: each poll returns when frames are pending
            h.poll(timeout=0.05)
            while (msg := bench.recv(0.0)) is not None:
                answers.append(msg)
            if sum(m.arbitration_id == codec("DUT_READY").frame_id for m in answers) >= 4:
                break
    finally:
        h.close()
        bench.shutdown()
        for master, slave in ptys:
            os.close(master)
            os.close(slave)
    ready = [int.from_bytes(bytes(m.data[:6]), "little") for m in answers if m.arbitration_id == 0x3F0]
    nav = [m for m in answers if m.arbitration_id == codec("NAV_SOLUTION").frame_id]
    assert ready == [0, 0, 0, 10_000], ready  # every BENCH_TIME with the lockstep bit answered
    assert _OnePerStep.stepped == [0, 10_000_000]  # but the estimator stepped once per bench time
    assert len(nav) == 2
