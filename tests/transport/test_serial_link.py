"""Serial links (pty pairs, loop://) and real-time pacing at baud and framing."""

from __future__ import annotations

import os

import numpy as np
import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, LinkError
from bench.frames import SerialBatch, SerialChunk
from bench.transport.pacing import PacedWriter, bits_per_byte, byte_groups, byte_time_ns, parse_framing, wire_times
from bench.transport.serial_link import PtyLink, PySerialLink, SerialConfig, open_serial_link


def _read_exactly(port: serial.Serial, n: int) -> bytes:
    port.timeout = 60.0  # a hang guard: the read returns as soon as the n bytes are there
    out = b""
    while len(out) < n:
        part = port.read(n - len(out))
        if not part:
            break
        out += part
    return out


def test_pty_pair_carries_bytes_unchanged_both_ways():
    payload = bytes(range(256)) * 40 + b"$GBZDA,1*00\r\n\r\x11\x13\x03"  # every byte value, CR LF, XON/XOFF, ^C
    with open_serial_link(SerialConfig(port="pty", baudrate=115_200)) as link:
        assert isinstance(link, PtyLink) and link.dut_port.startswith("/dev/pts/")
        dut = serial.Serial(link.dut_port, 115_200, timeout=2.0)  # (pyserial flushes input when it opens)
        try:
            link.write_many([SerialChunk(0, payload[:100]), SerialChunk(1, payload[100:])])
            assert _read_exactly(dut, len(payload)) == payload
            dut.write(b"nav\r\n" * 3)
            dut.flush()
            got = b""
            while len(got) < 15:
                got += link.read(timeout=60.0)  # returns at the first byte; 60 s: a hang guard
                assert got, "nothing came back within 60 s"
            assert got == b"nav\r\n" * 3
            assert link.read(timeout=0.0) == b""
        finally:
            dut.close()
        assert link.bytes_written == len(payload) and link.bytes_read == 15


def test_a_batch_is_one_write():
    batch = SerialBatch.from_fixed(np.arange(200), np.random.default_rng(1).integers(0, 256, (200, 42), np.uint8))
    calls = []
    with PtyLink(SerialConfig()) as link:
        real = link._write
        link._write = lambda data, timeout: (calls.append(len(data)), real(data, timeout))
        dut = os.open(link.dut_port, os.O_RDWR | os.O_NOCTTY)
        try:
            assert link.write_many(batch) == 8400
            got = b""
            while len(got) < 8400:
                got += os.read(dut, 65536)
            assert got == batch.tobytes()
        finally:
            os.close(dut)
    assert calls == [8400]


def test_a_dut_that_does_not_read_times_out_the_write():
    with PtyLink(SerialConfig(write_timeout=0.2)) as link, pytest.raises(LinkError, match="took no bytes"):
        link.write(bytes(4 << 20))


def test_loop_url_and_lifetime():
    link = open_serial_link(SerialConfig(port="loop://", baudrate=460_800))
    assert isinstance(link, PySerialLink) and link.dut_port is None
    link.write(b"\xaa\x55\x24abc")
    assert link.read(timeout=1.0) == b"\xaa\x55\x24abc"
    chunk = link.read_chunk()
    assert chunk == SerialChunk(0, b"")
    link.close()
    link.close()
    with pytest.raises(LinkError, match="closed"):
        link.read()
    with pytest.raises(LinkError, match="cannot open serial port"):
        PySerialLink(SerialConfig(port="/dev/does-not-exist"))


def test_serial_config_checks():
    assert SerialConfig.from_mapping({"port": "loop://", "baudrate": 115200, "framing": "8N1"}).baudrate == 115200
    with pytest.raises(ConfigError, match="framing"):
        SerialConfig.from_mapping({"framing": "9X1"}, file="case.toml", key="serial.imu")
    with pytest.raises(ConfigError, match="unknown key"):
        SerialConfig.from_mapping({"baud": 9600})
    with pytest.raises(ConfigError, match="positive integer"):
        SerialConfig.from_mapping({"baudrate": 0})


def test_bits_per_byte():
    assert bits_per_byte("8N1") == 10
    assert bits_per_byte("8E1") == 11
    assert bits_per_byte("7O2") == 11
    assert bits_per_byte("8N1.5") == 10.5
    assert parse_framing("8n1") == (8, "N", 1.0)
    assert byte_time_ns(460_800) == pytest.approx(1e10 / 460_800)
    for bad in ("8X1", "9N1", "8N3", "N81"):
        with pytest.raises(ValueError):
            parse_framing(bad)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 10_000_000), st.integers(0, 100)), min_size=1, max_size=40),
    st.floats(100.0, 30_000.0),
)
def test_wire_times_are_first_in_first_out(chunks, byte_ns):
    t = np.cumsum([dt for dt, _ in chunks])
    n = np.array([k for _, k in chunks])
    start, end = wire_times(t, n, byte_ns)
    prev = -np.inf
    for i in range(len(chunks)):  # the line, one chunk after the other
        s = max(t[i], prev)
        prev = s + n[i] * byte_ns
        assert start[i] == pytest.approx(s, abs=1e-3) and end[i] == pytest.approx(prev, abs=1e-3)


def test_byte_groups_never_deliver_a_byte_early():
    rng = np.random.default_rng(4)
    chunks = [SerialChunk(int(t), rng.integers(0, 256, 42, np.uint8).tobytes()) for t in np.arange(50) * 5_000_000]
    chunks.append(SerialChunk(chunks[-1].t_ns, b"$GBGGA" * 10))  # a burst behind a frame: it waits its turn
    batch = SerialBatch.from_chunks(chunks)
    byte_ns = byte_time_ns(460_800)
    times, offsets = byte_groups(batch, byte_ns, group_ns=1_000_000)
    assert offsets[0] == 0 and offsets[-1] == batch.buf.size and np.all(np.diff(offsets) > 0)
    start, _ = wire_times(batch.t_ns, batch.lengths, byte_ns)
    chunk_of = np.repeat(np.arange(len(batch)), batch.lengths)
    k = np.arange(batch.buf.size) - np.repeat(batch.offsets[:-1], batch.lengths)
    byte_end = start[chunk_of] + (k + 1) * byte_ns
    group_of = np.searchsorted(offsets, np.arange(batch.buf.size), side="right") - 1
    assert np.all(times[group_of] >= byte_end - 1)  # written no earlier than the line delivers it
    assert np.all(times[group_of] - byte_end <= 1_000_000 + 1)  # and held back at most one group


def test_paced_writer_on_a_simulated_clock():
    now = [0]
    written: list[tuple[int, bytes]] = []

    def sleep(s):
        now[0] += round(s * 1e9)

    frames = np.random.default_rng(5).integers(0, 256, (20, 42), np.uint8)
    batch = SerialBatch.from_fixed(np.arange(20) * 2_500_000, frames)  # 400 Hz: 0.9 of a 460800 baud line
    w = PacedWriter(lambda b: written.append((now[0], b)), 460_800, lambda: now[0], sleep=sleep, group_ns=500_000)
    w.write_batch(batch)
    assert b"".join(b for _, b in written) == batch.tobytes()
    sent = 0
    byte_ns = byte_time_ns(460_800)
    for t, b in written:  # a group is out when its last byte would have arrived
        sent += len(b)
        first_free = np.searchsorted(np.arange(20) * 42, sent, side="left") - 1
        assert t >= first_free * 2_500_000 + (sent - first_free * 42) * byte_ns - 1
    assert w.lag_ns == 0 and w.backlog_ns == 0
    w.write_batch(SerialBatch.from_fixed(np.full(3, now[0]), frames[:3]))  # three at once: they queue
    assert w.backlog_ns == pytest.approx(2 * 42 * byte_ns, abs=1)
