"""The udp_multicast CAN link alone, in a network namespace: where it listens, what it
filters and counts, and that nothing arriving on its socket can raise or hold it."""

from __future__ import annotations

import socket

import can
import pytest
from can.interfaces.udp_multicast.utils import pack_message

from bench.errors import ConfigError, LinkError
from bench.frames import CanFrame
from bench.transport.can_link import CanConfig, open_can_link
from bench.transport.udp import UdpMulticastCanLink
from tests.transport import netns

GROUP = "239.74.168.1"


def _link(ns: str, port: int, *, run_tag: str | None = None, group: str = GROUP, **options) -> UdpMulticastCanLink:
    cfg = CanConfig(interface="udp_multicast", channel=group, options={"port": port, **options})
    return netns.call_in(ns, lambda: UdpMulticastCanLink(cfg, run_tag=run_tag))


def _send_raw(ns: str, payloads: list[bytes], dest: tuple[str, int]) -> None:
    """Datagrams from a socket of no bench (any process on the host could send them)."""

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
            for p in payloads:
                s.sendto(p, dest)

    netns.call_in(ns, send)


def _packed(can_id: int = 0x300, channel: str | None = None, **kw) -> bytes:
    msg = can.Message(arbitration_id=can_id, data=bytes(8), is_extended_id=False, channel=channel, **kw)
    return pack_message(msg)


def _all(link: UdpMulticastCanLink, want: int) -> list[CanFrame]:
    """Frames until ``want`` arrived (or a second passes without one)."""
    got: list[CanFrame] = []
    while len(got) < want:
        f = link.recv(1.0)
        if f is None:
            break
        got.append(f)
    return got


def test_bound_to_the_group_on_the_loopback_not_to_every_address(ns):
    link = _link(ns, 43500)
    try:
        assert link.bus.sock.getsockname() == (GROUP, 43500)  # python-can binds ("", port)
        _send_raw(ns, [_packed(0x101)], ("127.0.0.1", 43500))  # a unicast to the port
        _send_raw(ns, [_packed(0x102)], ("239.74.168.2", 43500))  # another group, same port
        _send_raw(ns, [_packed(0x103)], (GROUP, 43500))  # the group: the only one taken
        got = _all(link, 3)
        assert [f.can_id for f in got] == [0x103]
        assert link.stats()["untagged"] == 1 and link.stats()["foreign"] == 0
    finally:
        link.close()


def test_stray_datagrams_are_counted_foreign_and_never_raise(ns):
    link = _link(ns, 43501)
    try:
        strays = [b"", b"\x00", b"hello", bytes(range(256)) * 3, b"\x81\xa3foo\x01", _packed()[:-3]]
        not_a_message = [pack_message(can.Message(arbitration_id=1))[:1] + b"\xc0"]  # msgpack, not a message
        bad_tag = [_packed(channel="bench:only:three"), _packed(channel="bench:r:s:x:1")]
        _send_raw(ns, [*strays, *not_a_message, *bad_tag, _packed(0x120)], (GROUP, 43501))
        got = _all(link, 1)
        assert [f.can_id for f in got] == [0x120]  # the frame after them still arrives
        s = link.stats()
        assert s["foreign"] == len(strays) + len(not_a_message) + len(bad_tag) and s["received"] == 1
    finally:
        link.close()


def test_another_benchs_frames_are_dropped_and_counted(ns):
    bench_a, dut_a, bench_b = _link(ns, 43502, run_tag="runA"), _link(ns, 43502, run_tag="runA"), None
    try:
        bench_b = _link(ns, 43502, run_tag="runB")
        runless = _link(ns, 43502, run_tag="")  # a harness started by hand: no run
        try:
            bench_b.send_many([CanFrame(i, 0x120, bytes(8)) for i in range(5)])
            dut_a.send(CanFrame(7, 0x300, bytes(48), True))
            runless.send(CanFrame(8, 0x301, bytes(8)))
            got = _all(bench_a, 2)
            assert [f.can_id for f in got] == [0x300, 0x301]  # its run's and the run-less frames
            s = bench_a.stats()
            assert s["other_bench"] == 5 and s["senders"] == 2 and s["drops"] == 0
            assert len(_all(runless, 7)) == 6  # a link without a run takes every run's frames
        finally:
            runless.close()
    finally:
        for link in (bench_a, dut_a, bench_b):
            if link is not None:
                link.close()


def test_remote_and_error_frames_are_counted_and_a_flood_cannot_hold_the_receiver(ns):
    link = _link(ns, 43503)
    try:
        link.drain_limit = 1000
        rtr = _packed(0x300, is_remote_frame=True)
        err = _packed(0x080, is_error_frame=True)
        _send_raw(ns, [rtr] * 1500 + [err] * 5, (GROUP, 43503))
        assert link.recv(1.0) is None  # remote frames carry no ICD message
        assert link.peer_frames == 1000 and link.remote == 1000  # at most drain_limit per call
        assert len(link.drain(timeout=1.0)) == 0
        s = link.stats()
        assert s["remote"] == 1500 and s["error_frames"] == 5 and link.peer_frames == 1505
    finally:
        link.close()


def test_port_zero_takes_a_free_port_a_python_can_dut_can_join(ns):
    a, b = _link(ns, 0, run_tag="r"), _link(ns, 0, run_tag="r")
    try:
        assert a.port != b.port and 0 not in (a.port, b.port)
        dut = netns.call_in(ns, lambda: can.Bus(interface="udp_multicast", channel=GROUP, port=a.port))
        try:
            a.send(CanFrame(1, 0x120, bytes(8)))
            m = dut.recv(2.0)
            assert m is not None and m.arbitration_id == 0x120 and m.channel.startswith("bench:r:")
            dut.send(can.Message(arbitration_id=0x300, data=bytes(48), is_fd=True, is_extended_id=False))
            assert [f.can_id for f in _all(a, 1)] == [0x300] and len(_all(b, 1)) == 0  # b is on another port
        finally:
            dut.shutdown()
    finally:
        a.close()
        b.close()


def test_an_interface_address_that_is_not_here_names_the_fix(ns):
    with pytest.raises(LinkError, match=r"on the interface 192\.0\.2\.1: .*ip link set lo multicast on"):
        _link(ns, 43504, interface_address="192.0.2.1")


@pytest.mark.parametrize(
    ("table", "key", "words"),
    [
        ({"channel": "10.1.2.3"}, "can.channel", "expected an IPv4 multicast group"),
        ({"channel": "ff15::1"}, "can.channel", "expected an IPv4 multicast group"),
        ({"port": 70000}, "can.port", "expected an integer 0 .. 65535"),
        ({"port": "43113"}, "can.port", "expected an integer 0 .. 65535"),
        ({"port": True}, "can.port", "expected an integer 0 .. 65535"),
        ({"interface_address": "lo"}, "can.interface_address", "expected the IPv4 address of an interface"),
        ({"hop_limit": 300}, "can.hop_limit", "expected an integer 0 .. 255"),
        ({"group": "239.1.1.1"}, "can.group", "unknown udp_multicast option 'group'"),
    ],
)
def test_bad_udp_settings_are_config_errors_naming_the_key(table, key, words):
    with pytest.raises(ConfigError) as e:
        CanConfig.from_mapping({"interface": "udp_multicast", **table}, file="case.toml")
    assert e.value.key == key and words in str(e.value) and "case.toml" in str(e.value)


def test_open_can_link_gives_udp_links_their_run_tag(ns):
    cfg = CanConfig(interface="udp_multicast", channel=GROUP, options={"port": 0})
    link = netns.call_in(ns, lambda: open_can_link(cfg, run_tag="abc"))
    try:
        assert isinstance(link, UdpMulticastCanLink) and link.run_tag == "abc" and link.tag.startswith("abc:")
    finally:
        link.close()


def test_own_frames_never_reach_the_socket_and_a_receive_thread_decodes_when_taken(ns):
    """The link's own frames are dropped in the kernel (the socket filter on its sending
    port); a receive thread only reads and stamps the datagrams, which are unpacked when
    taken: the peers' frames, in order, stamped with the kernel's arrival time, strays
    told apart from a peer's frames."""
    import time

    from bench.transport.can_rx import CanReceiveThread

    bench, dut = _link(ns, 43506, run_tag="runA"), _link(ns, 43506, run_tag="runA")
    bench.arrival_clock = lambda realtime_ns: realtime_ns  # bench time: the kernel's stamp itself
    rx = CanReceiveThread(bench, poll_s=0.01)
    try:
        assert bench.defers_decoding and bench.bus.own_filtered
        bench.send_many([CanFrame(i, 0x101, bytes(8)) for i in range(20)])  # its own: never come back
        before = time.time_ns()
        dut.send_many([CanFrame(i, 0x300 + i % 4, bytes([i]) * 8) for i in range(30)])
        after = time.time_ns()
        _send_raw(ns, [b"stray"] * 10, (GROUP, 43506))
        while rx.arrived < 40:  # a hang guard: the test timeout
            time.sleep(0.01)
        assert bench.peer_frames == 0 and bench.foreign == 0  # read, not unpacked yet
        assert rx.settle(40) == 30  # of the last 40 datagrams, 30 are the DUT's, 10 strays
        assert bench.foreign == 10 and bench.peer_frames == 30
        frames = rx.stop().frames()
    finally:
        rx.stop()
        bench.close()
        dut.close()
    assert [f.data[0] for f in frames] == list(range(30))  # every DUT frame, in order
    assert [f.can_id for f in frames[:4]] == [0x300, 0x301, 0x302, 0x303]
    assert all(before <= f.t_ns <= after for f in frames)  # stamped on arrival, not when unpacked
    assert bench.stats()["own"] == 0 and bench.received == 30
