"""The lockstep start-up per the ICD (bench.run.startup): rounds of the first step until the
DUT answers, alive counters advanced by every transmission and continued by the run and
by replays, the recording in wire order.

The DUT here is a thread of the test on the bench's links (a ``hardware`` DUT: nothing is
started): a virtual CAN bus and two pty pairs the test makes, whose slaves the bench opens
as serial ports. It ignores the first BENCH_TIMEs it sees (as a DUT that is not listening
yet) and checks every BENCH_TIME and BENCH_EPOCH it gets, as ICD 1 and 6 ask.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import threading
import tty
import uuid
from pathlib import Path

import can
import numpy as np
import pytest

from bench.faults.schedule import FaultSchedule
from bench.frames import CanBatch
from bench.record.mcap_io import RecordingReader
from bench.record.wire_topics import CAN_TX_DTYPE, can_batch, can_records
from bench.run.engine import execute, run
from bench.run.replay import RecordingReplay
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.run.startup import EPOCH_ID, advance_alive, drop_handshake_copies
from bench.run.traffic import BENCH_TIME_ID
from bench.scenario.loader import load_scenario
from bench.wire.can import CanEncoder, codec
from bench.wire.crc import crc8_can

DATA = Path(__file__).parent.parent / "data"
TABLES = {"imu": {"grade": "navigation", "rate": "200 Hz"}, "doppler": {"model": "seed000"},
          "odometer": {"model": "typical_wheeled"}, "bds": {"model": "seed001", "latency": "80 ms"},
          "driver": {"vehicle": "wheeled"}}


# ---------------------------------------------------------------- counters


def test_advancing_a_counter_keeps_a_good_crc_good_and_a_broken_one_broken_alike():
    enc = CanEncoder()
    bt = enc.encode("BENCH_TIME", [0, 10, 20], time_ns=[0, 10, 20], lockstep=1)
    data = bt.data.copy()
    data[1, 7] ^= 0x5A  # a wire fault's CRC error
    bt = CanBatch(bt.t_ns, bt.can_id, data, bt.length, bt.fd)
    out = advance_alive(bt, (BENCH_TIME_ID,), 7)
    values, status = codec("BENCH_TIME").decode(out)
    assert values["alive"].tolist() == [7, 8, 9] and values["lockstep"].tolist() == [1, 1, 1]
    assert status[0] == 0 and status[2] == 0 and status[1] != 0
    back = advance_alive(out, (BENCH_TIME_ID,), -7)
    assert np.array_equal(back.data, bt.data)  # the error pattern too
    assert advance_alive(bt, (EPOCH_ID,), 3) is bt  # other messages untouched


def _rounds_recording(rounds: int, *, advanced: bool) -> CanBatch:
    """A start-up of ``rounds`` rounds and the first 20 ms after it, as recorded."""
    enc = CanEncoder()
    parts = []
    for i in range(rounds):
        alive = i % 16 if advanced else 0
        parts.append(enc.encode("BENCH_EPOCH", [0], epoch_utc_ns=[1_700_000_000 * 10**9], alive=[alive]))
        parts.append(enc.encode("BENCH_TIME", [0], time_ns=[0], lockstep=1, alive=[alive]))
    base = rounds if advanced else 1
    parts.append(enc.encode("ODOMETER", [10_000_000], pulse_count=[1], speed=[1.0], reverse=[0], valid=[1]))
    parts.append(enc.encode("BENCH_TIME", [10_000_000, 20_000_000], time_ns=[10_000_000, 20_000_000], lockstep=1,
                            alive=[base % 16, (base + 1) % 16]))
    return CanBatch.concat(parts)


@pytest.mark.parametrize(("rounds", "advanced"), [(5, True), (5, False), (17, True), (33, True), (17, False)],
                         ids=["rounds advance the counter", "older byte-for-byte copies",
                              "17 rounds: the 16th copy has the first's bytes", "33 rounds", "17 older copies"])
def test_a_recorded_start_up_is_kept_as_one_round_and_the_counters_after_it_moved_back(rounds, advanced):
    kept = drop_handshake_copies(_rounds_recording(rounds, advanced=advanced))
    assert kept.can_id.tolist() == [EPOCH_ID, BENCH_TIME_ID, 0x120, BENCH_TIME_ID, BENCH_TIME_ID]
    values, status = codec("BENCH_TIME").decode(kept.take(np.flatnonzero(kept.can_id == BENCH_TIME_ID)))
    assert values["alive"].tolist() == [0, 1, 2] and np.all(status == 0)


# ---------------------------------------------------------------- runs


class ThreadDut:
    """A lockstep DUT on a virtual CAN channel and the masters of two pty pairs."""

    def __init__(self, channel: str, *, deaf_for: int):
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        self.ptys = [os.openpty() for _ in range(2)]
        for master, slave in self.ptys:
            tty.setraw(slave)
            os.set_blocking(master, False)
        self.paths = [os.ttyname(slave) for _, slave in self.ptys]
        self.deaf_for = deaf_for
        self.seen: list[tuple[int, int, int]] = []  # (id, alive, time us or -1) of BENCH_EPOCH/TIME, in order
        self.serial_bytes = 0
        self.bad_crc = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _loop(self) -> None:
        enc = CanEncoder()
        while not self.stop.is_set():
            for master, _ in self.ptys:
                with contextlib.suppress(BlockingIOError):
                    self.serial_bytes += len(os.read(master, 1 << 16))
            msg = self.bus.recv(0.005)
            if msg is None or msg.arbitration_id not in (BENCH_TIME_ID, EPOCH_ID):
                continue
            if self.deaf_for:  # not listening yet: this round is lost
                self.deaf_for -= msg.arbitration_id == BENCH_TIME_ID
                continue
            d = bytes(msg.data)
            if len(d) != 8 or crc8_can(msg.arbitration_id, d[:7]) != d[7]:
                self.bad_crc += 1  # ICD 1: a frame with a bad CRC is discarded
                continue
            t_us = int.from_bytes(d[:6], "little") if msg.arbitration_id == BENCH_TIME_ID else -1
            self.seen.append((msg.arbitration_id, d[6] & 0x0F, t_us))
            if t_us >= 0 and d[6] & 0x10:
                ready = enc.encode("DUT_READY", [t_us * 1000], time_ns=[t_us * 1000])
                f = ready.frame(0)
                self.bus.send(can.Message(arbitration_id=f.can_id, data=f.data, is_extended_id=False))

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.bus.shutdown()
        for master, slave in self.ptys:
            os.close(master)
            os.close(slave)

    def links(self, channel: str) -> LinkSpec:
        return LinkSpec(can={"interface": "virtual", "channel": channel},
                        imu={"port": self.paths[0], "baud": 460800}, gnss={"port": self.paths[1], "baud": 115200})

    def problems(self) -> list[str]:
        out = []
        for cid in (BENCH_TIME_ID, EPOCH_ID):
            alive = [a for i, a, _ in self.seen if i == cid]
            bad = sum((b - a) % 16 != 1 for a, b in itertools.pairwise(alive))
            if bad:
                out.append(f"0x{cid:03X}: {bad} alive counter errors")
        if self.seen and self.seen[0][0] != EPOCH_ID:
            out.append("BENCH_TIME came before any BENCH_EPOCH")
        return out


def _can_tx(path: Path) -> CanBatch:
    return can_batch(RecordingReader(path).read_columnar("/wire/can/tx"))


def _recorded_problems(can: CanBatch) -> list[str]:
    out = []
    if np.any(np.diff(can.t_ns) < 0):
        out.append("/wire/can/tx is not in wire order")
    for cid in (BENCH_TIME_ID, EPOCH_ID):
        alive = can.data[can.can_id == cid, 6].astype(np.int64) & 0x0F
        if not np.all(np.diff(alive) % 16 == 1):
            out.append(f"/wire/can/tx: 0x{cid:03X} counters not continuous")
    return out


def _hardware_run(tmp_path: Path, name: str, deaf_for: int, provider=None, schedule: FaultSchedule | None = None):
    channel = f"startup-{uuid.uuid4().hex[:8]}"
    dut = ThreadDut(channel, deaf_for=deaf_for)
    try:
        spec = DutSpec("hardware", startup_timeout_s=5.0)
        if provider is None:
            res = run(RunSpec(scenario=load_scenario(DATA / "short_drive.toml"), tables=TABLES,
                              schedule=schedule or FaultSchedule(), dut=spec, out=tmp_path / name, seed=4,
                              duration_ns=3_000_000_000, window_ns=1_000_000_000, links=dut.links(channel)))
        else:
            res = execute(provider, spec, dut.links(channel), ClockSpec(), tmp_path / name, window_ns=1_000_000_000)
    finally:
        dut.close()
    return res, dut


def test_the_start_up_goes_out_in_rounds_with_the_counters_running_and_is_recorded_in_wire_order(tmp_path):
    res, dut = _hardware_run(tmp_path, "run.mcap", deaf_for=2)
    assert res.ok, res.reason
    assert dut.problems() == [] and dut.serial_bytes > 0
    can = _can_tx(res.path)
    assert _recorded_problems(can) == []
    # three rounds (two unanswered), each BENCH_EPOCH(0) then BENCH_TIME(0), nothing before them
    head = can.take(np.arange(6))
    assert head.can_id.tolist() == [EPOCH_ID, BENCH_TIME_ID] * 3 and np.all(head.t_ns == 0)
    assert (head.data[:, 6] & 0x0F).tolist() == [0, 0, 1, 1, 2, 2]
    values, _ = codec("BENCH_TIME").decode(can.take(np.flatnonzero(can.can_id == BENCH_TIME_ID)))
    assert values["time_ns"].tolist()[:4] == [0, 0, 0, 10_000_000] and len(values["time_ns"]) == 303
    assert [a for i, a, _ in dut.seen if i == BENCH_TIME_ID][:2] == [2, 3]  # what the DUT heard first


def test_a_replay_continues_the_counters_after_its_own_start_up(tmp_path):
    source, _ = _hardware_run(tmp_path, "src.mcap", deaf_for=3)
    res, dut = _hardware_run(tmp_path, "replay.mcap", deaf_for=0, provider=RecordingReplay(source.path, lockstep=True))
    assert res.ok, res.reason
    assert dut.problems() == []
    src, rep = _can_tx(source.path), _can_tx(res.path)
    assert _recorded_problems(rep) == []
    # one round each: the same frames, frame for frame
    a = can_records(drop_handshake_copies(src), CAN_TX_DTYPE)
    b = can_records(drop_handshake_copies(rep), CAN_TX_DTYPE)
    assert np.array_equal(a, b)
    assert len(rep) == len(src) - 6  # its start-up took one round, the source's four
