"""CAN links: virtual (in-process), socketcan on vcan where it exists, udp_multicast in a netns."""

from __future__ import annotations

import sys

import can
import numpy as np
import pytest

from bench.errors import ConfigError, LinkError
from bench.frames import CanBatch, CanFrame
from bench.transport.can_link import CanConfig, CanLink, socketcan_unavailable
from bench.transport.udp import UdpMulticastCanLink
from tests.transport import netns


def _traffic(n: int = 50) -> CanBatch:
    rng = np.random.default_rng(n)
    classic = CanBatch(
        np.arange(n) * 1_000_000 + 7, rng.choice([0x010, 0x120, 0x130], n), rng.integers(0, 256, (n, 8), dtype=np.uint8)
    )
    fd = CanBatch(np.arange(n) * 1_000_000 + 500_007, 0x300, rng.integers(0, 256, (n, 48), dtype=np.uint8), 48, True)
    return CanBatch.concat([classic, fd]).sorted()


def _same(a: CanBatch, b: CanBatch, times: bool = True) -> None:
    assert len(a) == len(b)
    if times:
        np.testing.assert_array_equal(a.t_ns, b.t_ns)
    np.testing.assert_array_equal(a.can_id, b.can_id)
    np.testing.assert_array_equal(a.length, b.length)
    np.testing.assert_array_equal(a.fd, b.fd)
    for i in range(len(a)):
        assert a.frame(i).data == b.frame(i).data


def test_virtual_round_trip_keeps_bench_times():
    frames = _traffic()
    with CanLink(CanConfig(channel="t-rt")) as tx, CanLink(CanConfig(channel="t-rt")) as rx:
        assert tx.send_many(frames) == len(frames)
        got = rx.drain()
        assert tx.drain().t_ns.size == 0  # no own frames unless asked
    _same(got, frames)
    assert tx.stats() == {"sent": len(frames), "received": 0, "remote": 0, "error_frames": 0}


def test_receive_own_messages_and_clock_stamping():
    now = [123_000]
    with CanLink(CanConfig(channel="t-own", receive_own_messages=True), clock=lambda: now[0]) as link:
        link.send(CanFrame(5, 0x121, bytes(range(8))))
        got = link.recv(1.0)
    assert got == CanFrame(123_000, 0x121, bytes(range(8)), False)


def test_close_is_idempotent_and_closed_links_refuse():
    link = CanLink(CanConfig(channel="t-close"))
    link.close()
    link.close()
    assert link.closed
    with pytest.raises(LinkError, match="closed"):
        link.send(CanFrame(0, 1, b""))
    with pytest.raises(LinkError, match="closed"):
        link.recv()


def test_config_from_a_table():
    cfg = CanConfig.from_mapping(
        {"interface": "socketcan", "channel": "vcan1", "fd": True, "ignore_rx_error_frames": 1}
    )
    assert cfg.bus_kwargs()["channel"] == "vcan1"
    assert cfg.options == {"ignore_rx_error_frames": 1}
    with pytest.raises(ConfigError, match="unknown python-can interface 'vcna'"):
        CanConfig.from_mapping({"interface": "vcna"}, file="case.toml")
    with pytest.raises(ConfigError, match="bitrate"):
        CanConfig.from_mapping({"bitrate": "fast"})
    assert CanConfig(interface="virtual").bus_kwargs()["preserve_timestamps"] is True
    assert CanConfig(interface=None, channel=None).bus_kwargs().get("interface") is None


def test_socketcan_missing_names_the_fix():
    reason = socketcan_unavailable("vcan9")
    if reason is None:
        pytest.skip("vcan9 exists on this machine")
    assert "vcan9" in reason
    if "does not exist" in reason:
        assert "ip link add dev vcan9 type vcan; ip link set up vcan9" in reason
    with pytest.raises(LinkError) as e:
        CanLink(CanConfig(interface="socketcan", channel="vcan9"))
    assert str(e.value) == reason


@pytest.mark.hardware
def test_socketcan_vcan_round_trip():
    reason = socketcan_unavailable("vcan0")
    if reason:
        pytest.skip(reason)
    frames = _traffic(20)
    cfg = CanConfig(interface="socketcan", channel="vcan0")
    with CanLink(cfg) as tx, CanLink(cfg) as rx:
        tx.send_many(frames)
        got = rx.drain(timeout=1.0)
        while len(got) < len(frames):
            more = rx.drain(timeout=1.0)
            if not len(more):
                break
            got = CanBatch.concat([got, more])
    _same(got, frames, times=False)


def _udp(ns_name: str, port: int, **kw) -> UdpMulticastCanLink:
    """A link of the run ``run1`` (two links of one run: the bench and a DUT that tags)."""
    cfg = CanConfig(interface="udp_multicast", channel="239.74.163.2", options={"port": port}, **kw)
    return netns.call_in(ns_name, lambda: UdpMulticastCanLink(cfg, run_tag="run1"))


def test_udp_multicast_sequence_numbers_count_drops(ns):
    frames = _traffic(40)
    a, b = _udp(ns, 43200), _udp(ns, 43200)
    try:
        assert isinstance(a, UdpMulticastCanLink)
        a.send_many(frames.take(slice(0, 30)))
        a._seq += 7  # seven datagrams lost on the way
        a.send_many(frames.take(slice(30, 80)))
        got = b.drain(timeout=2.0)
        while len(got) < 80:
            more = b.drain(timeout=1.0)
            if not len(more):
                break
            got = CanBatch.concat([got, more])
        _same(got, frames)  # the sender's bench times travel with the frames
        assert b.stats()["drops"] == 7 and b.stats()["senders"] == 1 and b.stats()["reordered"] == 0
        # own frames never come back: dropped in the kernel by the socket filter (Linux), or
        # seen and skipped
        assert len(a.drain(timeout=0.2)) == 0
        assert a.bus.own_filtered == sys.platform.startswith("linux")
        assert a.stats()["own"] == (0 if a.bus.own_filtered else 80)
        # a sender that does not tag (a DUT on plain python-can) is delivered and counted
        plain = netns.call_in(ns, lambda: can.Bus(interface="udp_multicast", channel="239.74.163.2", port=43200))
        try:
            plain.send(can.Message(arbitration_id=0x300, data=bytes(48), is_fd=True, is_extended_id=False))
        finally:
            plain.shutdown()
        f = b.recv(2.0)
        assert f is not None and f.can_id == 0x300 and f.fd and b.stats()["untagged"] == 1
    finally:
        a.close()
        b.close()


def test_udp_multicast_reordered_frames(ns):
    a, b = _udp(ns, 43201), _udp(ns, 43201)
    try:
        a.send(CanFrame(1, 0x10, bytes(8)))
        a._seq = 5
        a.send(CanFrame(2, 0x10, bytes(8)))
        a._seq = 3
        a.send(CanFrame(3, 0x10, bytes(8)))  # older than the one before: late, not a drop
        got = [b.recv(2.0) for _ in range(3)]
        assert [f.t_ns for f in got] == [1, 2, 3]
        assert b.stats()["drops"] == 4 and b.stats()["reordered"] == 1
    finally:
        a.close()
        b.close()
