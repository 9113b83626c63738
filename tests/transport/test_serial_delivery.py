"""SerialLink.deliver: what the bench wrote is readable at the far end before it goes on
(lockstep: before BENCH_TIME(T), ICD 6).

The far end here reads the way a DUT using pyserial's ``in_waiting`` does: as many bytes
as ``FIONREAD`` counts, which does not include what the tty layer has not moved into the
line discipline yet.
"""

from __future__ import annotations

import fcntl
import os
import struct
import termios
import threading
import tty

import pytest

from bench.errors import LinkError
from bench.transport.serial_link import SerialConfig, open_serial_link


def _open_dut(path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd, termios.TCSANOW)
    return fd


def _readable(fd: int) -> int:
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


def test_the_pty_line_discipline_capacity_is_measured_and_left_empty():
    with open_serial_link(SerialConfig(port="pty")) as link:
        assert link.pair.ldisc_capacity == 4095  # N_TTY_BUF_SIZE - 1 on Linux
        dut = _open_dut(link.dut_port)
        try:
            assert _readable(dut) == 0  # the measurement's bytes were read back
        finally:
            os.close(dut)


def test_every_byte_written_is_counted_readable_once_delivered():
    """2000 steps of 10 IMU frames: after each write and delivery the DUT's FIONREAD
    counts every byte (without the delivery a good share of them is not counted yet)."""
    with open_serial_link(SerialConfig(port="pty")) as link:
        dut = _open_dut(link.dut_port)
        try:
            short = 0
            for k in range(2000):
                data = bytes([k % 251]) * 420
                link.write(data)
                link.deliver()
                n = _readable(dut)
                short += n < len(data)
                got = b""
                while len(got) < len(data):  # the DUT reads its step (a read flushes itself)
                    try:
                        got += os.read(dut, 65536)
                    except BlockingIOError:
                        continue
                assert got == data
            assert short == 0
        finally:
            os.close(dut)


def test_a_step_larger_than_the_line_discipline_waits_until_the_dut_has_it_all():
    """8400 bytes a step (a 200 Hz IMU at 1 s steps): the DUT's buffer holds 4095; delivery
    returns only when everything is read or readable, while the DUT reads as it goes."""
    lock = threading.Lock()
    with open_serial_link(SerialConfig(port="pty")) as link:
        dut = _open_dut(link.dut_port)
        consumed = [0]
        stop = threading.Event()

        def reader() -> None:  # a DUT reading FIONREAD bytes whenever there are some
            while not stop.is_set():
                with lock:
                    n = _readable(dut)
                    if n:
                        consumed[0] += len(os.read(dut, n))

        t = threading.Thread(target=reader, daemon=True)
        t.start()
        try:
            written = 0
            for k in range(200):
                data = bytes([k % 251]) * 8400
                link.write(data)
                written += len(data)
                link.deliver()
                with lock:  # the DUT holds still: what it read plus what it can read
                    assert consumed[0] + _readable(dut) == written, f"step {k}"
        finally:
            stop.set()
            t.join()
            os.close(dut)


def test_a_dut_that_reads_nothing_of_a_large_step_is_a_link_error_naming_its_port():
    with open_serial_link(SerialConfig(port="pty", write_timeout=0.2)) as link:
        dut = _open_dut(link.dut_port)
        try:
            link.write(bytes(6000))
            with pytest.raises(LinkError, match=f"the DUT on {link.dut_port} took no bytes for 0.2 s"):
                link.deliver()
        finally:
            os.close(dut)


def test_delivery_on_a_pyserial_url_and_a_closed_link():
    with open_serial_link(SerialConfig(port="loop://")) as link:
        link.write(b"abc")
        link.deliver()  # flush(): transmitted
        assert link.read(1.0, 16) == b"abc"
    with pytest.raises(LinkError, match="is closed"):
        link.deliver()
