"""Draining what the far end writes on a serial link (bench.transport.serial_reader).

A write on a pty slave returns before the bytes are readable at the master (the kernel
hands them over a moment later), so the tests wait until the reader has read what they
wrote (a hang guard of 60 s, never a speed bound) or until the bytes are readable
(``FIONREAD``) before they look.
"""

from __future__ import annotations

import fcntl
import os
import struct
import termios
import threading
import time
from collections.abc import Callable

from bench.transport.serial_link import SerialConfig, open_serial_link
from bench.transport.serial_reader import SerialReader

PATTERN = bytes((i * 7 + 3) % 251 for i in range(1 << 20))  # 1 MiB, no period of a power of two


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view[:4096]) :]


def _until(cond: Callable[[], bool], what: str) -> None:
    """Poll ``cond`` until it holds; a hang guard of 60 s, not a speed bound."""
    deadline = time.monotonic() + 60.0
    while not cond():
        assert time.monotonic() < deadline, f"still waiting after 60 s for {what}"
        time.sleep(0.001)


def _readable(fd: int) -> int:
    """Bytes waiting to be read on ``fd``."""
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


def test_a_writer_on_the_pty_slave_never_blocks_and_every_byte_is_kept_in_order():
    now = [0]
    with open_serial_link(SerialConfig(port="pty")) as link:
        fd = os.open(link.dut_port, os.O_WRONLY | os.O_NOCTTY)
        reader = SerialReader(link, lambda: now[0], name="imu")
        try:
            done = threading.Event()
            writer = threading.Thread(target=lambda: (_write_all(fd, PATTERN), done.set()), daemon=True)
            writer.start()
            writer.join(timeout=60)  # a blocked writer would still be alive here
            assert done.is_set(), "the DUT side blocked: nobody read the pty"
            _until(lambda: reader.bytes_read == len(PATTERN), "the reader to read the pattern")
            now[0] = 5
            _write_all(fd, b"tail")
            _until(lambda: reader.bytes_read == len(PATTERN) + 4, "the reader to read the tail")
        finally:
            got = [reader.take(), reader.close()]
            os.close(fd)
    data = b"".join(b.tobytes() for b in got)
    assert data == PATTERN + b"tail"
    assert reader.bytes_read == len(PATTERN) + 4 and reader.error is None
    times = [int(t) for b in got for t in b.t_ns]
    assert times == sorted(times) and set(times) == {0, 5}  # stamped with the clock when read
    assert reader.close().buf.size == 0  # idempotent


def test_a_full_reader_waits_for_its_chunks_to_be_taken_and_loses_nothing():
    data = PATTERN[: 256 << 10]
    with open_serial_link(SerialConfig(port="pty")) as link:
        fd = os.open(link.dut_port, os.O_WRONLY | os.O_NOCTTY)
        reader = SerialReader(link, lambda: 0, max_pending=4096)
        batches = []
        try:
            done = threading.Event()
            writer = threading.Thread(target=lambda: (_write_all(fd, data), done.set()), daemon=True)
            writer.start()
            taken = 0
            deadline = time.monotonic() + 60.0  # a hang guard: the reader stopped for good
            while taken < len(data) and time.monotonic() < deadline:  # the run takes what was read at every step
                done.wait(0.005)
                batches.append(reader.take())
                taken += batches[-1].buf.size
            writer.join(timeout=60)
            assert done.is_set(), "the writer is blocked: the full reader never read on after a take"
        finally:
            batches.append(reader.close())
            os.close(fd)
    assert batches[-1].buf.size == 0  # everything was taken while the writer wrote
    assert b"".join(b.tobytes() for b in batches) == data
    assert max(b.buf.size for b in batches) <= 4096 + 65536  # the cap and at most one read beyond it


def test_close_reads_what_is_still_on_the_line_even_when_the_reader_is_full():
    data = PATTERN[:5000]
    with open_serial_link(SerialConfig(port="pty")) as link:
        fd = os.open(link.dut_port, os.O_WRONLY | os.O_NOCTTY)
        reader = SerialReader(link, lambda: 0, max_pending=4096)
        try:
            _write_all(fd, data[:4500])
            _until(lambda: reader.pending >= 4096, "the reader to fill up")  # now it waits for a take
            _write_all(fd, data[4500:])
            left = len(data) - reader.bytes_read
            _until(lambda: _readable(link.fileno()) == left, f"{left} bytes readable on the line")
            got = reader.close()
        finally:
            os.close(fd)
    assert got.tobytes() == data  # the bytes still on the line are read at the close, not dropped
    assert reader.bytes_read == len(data)


def test_an_idle_line_gives_empty_batches_and_closes_at_once():
    with open_serial_link(SerialConfig(port="pty")) as link:
        reader = SerialReader(link, lambda: 0)
        assert len(reader.take()) == 0
        assert len(reader.close()) == 0 and reader.error is None


def test_a_link_without_a_descriptor_is_polled():
    with open_serial_link(SerialConfig(port="loop://")) as link:  # what the bench writes comes back
        reader = SerialReader(link, lambda: 7)
        link.write(b"echo" * 1000)
        first = reader.take()  # whatever the thread read so far; close reads the rest
        assert first.tobytes() + reader.close().tobytes() == b"echo" * 1000
        assert reader.error is None
