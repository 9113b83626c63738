"""A lockstep DUT written from the ICD text alone (docs: /ICD 1.0, sections 1, 2, 3, 6),
with no bench code: its own CRCs, its own 42-byte IMU frame parser, CAN through
python-can, and ONE select loop over its serial lines and the CAN bus with no waiting of
its own.

    python icd_select.py --can-interface I --can-channel C [--can-port P] --imu PORT --gnss PORT

On every wake-up of ``select`` it first reads whatever the serial lines hold (as many
bytes as ``FIONREAD`` says are readable, the count pyserial's ``in_waiting`` gives), then
handles the CAN frames pending on the bus, reading the serial lines again (the same way,
without waiting) before each BENCH_TIME, as ICD 6 asks ("reads all pending serial input
before it handles BENCH_TIME(T)"). It answers every BENCH_TIME(T) with the
lockstep bit by DUT_READY(T) (ICD 6) and checks, as a third-party DUT would:

* ``late``: IMU frames received with a time of validity <= a BENCH_TIME already handled
  (ICD 6: every serial byte due by T is readable before BENCH_TIME(T));
* ``counter_errors``: BENCH_TIME and BENCH_EPOCH frames whose alive counter is not the
  previous one +1 modulo 16 (ICD 1: +1 for every transmission);
* ``epoch_after_time``: the first BENCH_EPOCH came after the first BENCH_TIME (ICD 6:
  every frame with time <= 0, BENCH_EPOCH(0) included, before BENCH_TIME(0));
* bad CRCs of CAN and IMU frames, IMU frame counter gaps.

On SIGTERM it prints one JSON line with these figures on stdout and exits 0.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import select
import signal
import struct
import sys
import termios
import tty

import can

BENCH_TIME, BENCH_EPOCH, DUT_READY = 0x010, 0x011, 0x3F0
SYNC = b"\xaa\x55"


def crc8(data: bytes) -> int:
    """CRC-8/SAE-J1850: poly 0x1D, init 0xFF, no reflection, xorout 0xFF (ICD 1)."""
    crc = 0xFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, xorout 0 (ICD 1)."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def open_serial(path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    return fd


def readable(fd: int) -> int:
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


class Dut:
    def __init__(self, bus: can.BusABC):
        self.bus = bus
        self.imu_buf = bytearray()
        self.stats = {"imu_frames": 0, "late": 0, "imu_crc": 0, "imu_counter_gaps": 0, "can_crc": 0,
                      "counter_errors": 0, "bench_time": 0, "bench_epoch": 0, "epoch_after_time": False,
                      "gnss_bytes": 0, "first_late": None, "ready_sent": 0}
        self.handled_t = -1  # the latest BENCH_TIME handled, us
        self.alive: dict[int, int] = {}
        self.imu_counter: int | None = None
        self.ready_alive = 0

    # -- serial (ICD 3) --------------------------------------------------------------
    def feed_imu(self, data: bytes) -> None:
        buf = self.imu_buf
        buf += data
        i = 0
        while True:
            j = buf.find(SYNC, i)
            if j < 0:
                i = max(i, len(buf) - 1)
                break
            if len(buf) - j < 42:
                i = j
                break
            frame = bytes(buf[j : j + 42])
            if frame[2] != 36 or crc16(frame[2:40]) != int.from_bytes(frame[40:42], "little"):
                self.stats["imu_crc"] += 1
                i = j + 1
                continue
            self.imu_frame(frame)
            i = j + 42
        del buf[:i]

    def imu_frame(self, frame: bytes) -> None:
        s = self.stats
        s["imu_frames"] += 1
        counter, t_us = frame[3], int.from_bytes(frame[4:12], "little")
        if self.imu_counter is not None and counter != (self.imu_counter + 1) % 256:
            s["imu_counter_gaps"] += 1
        self.imu_counter = counter
        if t_us <= self.handled_t:  # due by a BENCH_TIME already handled: it came late
            s["late"] += 1
            if s["first_late"] is None:
                s["first_late"] = [t_us, self.handled_t]


    # -- CAN (ICD 2) -----------------------------------------------------------------
    def can_frame(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame or msg.is_fd or msg.dlc != 8:
            return
        cid, d = msg.arbitration_id, bytes(msg.data)
        if cid not in (BENCH_TIME, BENCH_EPOCH):
            return
        s = self.stats
        if crc8(bytes([cid & 0xFF]) + d[:7]) != d[7]:
            s["can_crc"] += 1
            return
        alive = d[6] & 0x0F
        if cid in self.alive and alive != (self.alive[cid] + 1) % 16:
            s["counter_errors"] += 1
        self.alive[cid] = alive
        if cid == BENCH_EPOCH:
            s["bench_epoch"] += 1
            return
        if s["bench_epoch"] == 0:
            s["epoch_after_time"] = True
        s["bench_time"] += 1
        t_us = int.from_bytes(d[:6], "little")
        self.handled_t = max(self.handled_t, t_us)
        if d[6] & 0x10:  # lockstep: everything up to T is processed
            payload = t_us.to_bytes(6, "little") + bytes([self.ready_alive])
            self.ready_alive = (self.ready_alive + 1) % 16
            data = payload + bytes([crc8(bytes([DUT_READY & 0xFF]) + payload)])
            self.bus.send(can.Message(arbitration_id=DUT_READY, data=data, is_extended_id=False))
            s["ready_sent"] += 1


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--can-interface", required=True)
    p.add_argument("--can-channel", required=True)
    p.add_argument("--can-port", type=int)
    p.add_argument("--imu", required=True)
    p.add_argument("--gnss", required=True)
    a = p.parse_args()
    stop_r, stop_w = os.pipe()
    signal.signal(signal.SIGTERM, lambda *_: os.write(stop_w, b"x"))
    kw = {"port": a.can_port} if a.can_port else {}
    bus = can.Bus(interface=a.can_interface, channel=a.can_channel, fd=True, **kw)
    imu, gnss = open_serial(a.imu), open_serial(a.gnss)
    dut = Dut(bus)
    can_fd = bus.fileno()

    def read_serial() -> None:
        """Whatever the serial lines hold now: FIONREAD bytes, no waiting."""
        for fd in (imu, gnss):
            n = readable(fd)
            if n:
                data = os.read(fd, n)
                if fd == imu:
                    dut.feed_imu(data)
                else:
                    dut.stats["gnss_bytes"] += len(data)

    print("icd_select: listening", flush=True)
    while True:
        ready, _, _ = select.select([imu, gnss, can_fd, stop_r], [], [])
        if stop_r in ready:
            break
        read_serial()  # first whatever the serial lines hold
        while True:  # then the CAN frames
            msg = bus.recv(0.0)
            if msg is None:
                break
            if msg.arbitration_id == BENCH_TIME:  # ICD 6: all pending serial input before BENCH_TIME
                read_serial()
            dut.can_frame(msg)
    print(json.dumps(dut.stats), flush=True)
    bus.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
