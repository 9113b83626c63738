"""CAN over UDP multicast (python-can's ``udp_multicast`` wire format), isolated per run.

The frames are python-can's msgpack-packed messages, so a DUT on plain python-can
(``can.Bus(interface="udp_multicast", channel=GROUP, port=PORT)``) talks to the bench
unchanged. The bench's own socket differs from python-can's in where it listens:

* **bound to the group, on one interface**: the socket is bound to ``(group, port)``, not
  to every address, joins the group on ``interface_address`` only (127.0.0.1, the
  loopback, by default) with ``IP_MULTICAST_ALL`` off, and sends there
  (``IP_MULTICAST_IF``, hop limit 1). A datagram from the network, a unicast to the port
  or another group on the same port never reaches it.
* **port**: ``port`` of the link's options; 43113 (python-can's default) when none is
  given; 0 asks the kernel for a free one (bound without address reuse first, so no
  other socket holds it, then opened to the DUT's python-can socket, which reuses
  addresses); :attr:`UdpMulticastCanLink.port` is the one in use (the DUT's ``{can_port}``).
* **nothing on the socket is fatal**: a datagram that does not unpack as a message
  (stray bytes from any process that can reach the group) is dropped and counted
  ``foreign``; it never raises.

The ICD payloads must stay untouched, so the bench carries its bookkeeping in the one
message field python-can's packing transmits and CAN does not, ``Message.channel``:
``"bench:<run>:<sender>:<sequence>:<t_ns>"``:

* ``run``: the run tag (:attr:`UdpMulticastCanLink.run_tag`, random per bench run; the
  external DUT gets it in the environment variable ``BENCH_CAN_RUN_TAG``). Frames tagged
  with another run are another bench's: dropped and counted ``other_bench``. A link
  without a run (``run_tag=""``: the harness started by hand) accepts every run and
  tags its frames with an empty run, which every run accepts.
* ``sender``: unique per link (process id and random bits): a link skips its own frames
  (multicast loops them back) unless ``receive_own_messages``, and tells its peers apart
  (``senders``). On Linux the link sends from a socket of its own (an ephemeral port on
  the same interface) and a socket filter drops the datagrams from that port in the
  kernel, so own frames never reach the receiver; elsewhere they are skipped after
  unpacking and counted ``own``.
* ``sequence``: +1 per frame sent by that link; per peer a receiver expects the next
  number: a gap of k counts ``k`` ``drops``, a number below the expected one a
  ``reordered`` frame (delivered late).
* ``t_ns``: the sender's bench time of the frame, used as the frame's time when the
  receiving link has no bench clock.

A frame without a tag (a DUT on plain python-can) is the DUT's: delivered and counted
``untagged`` (its losses show only in the ICD alive and epoch counters); a channel that
starts with ``bench:`` but is not a tag is ``foreign`` (dropped). The receive buffer is
enlarged (8 MiB by default, ``SO_RCVBUFFORCE`` when permitted) to make overflow rare.
"""

from __future__ import annotations

import ipaddress
import os
import secrets
import time
from collections.abc import Callable, Mapping
from typing import Any

import can
from can.interfaces.udp_multicast.utils import pack_message, unpack_message

from bench.errors import ConfigError, LinkError
from bench.frames import CanFrame
from bench.transport.can_link import SKIPPED, CanConfig, CanLink
from bench.transport.udp_socket import MulticastSocket

__all__ = [
    "UdpMulticastCanLink",
    "TAG_PREFIX",
    "RUN_TAG_ENV",
    "DEFAULT_PORT",
    "DEFAULT_INTERFACE_ADDRESS",
    "UDP_OPTIONS",
    "check_udp_config",
]

TAG_PREFIX = "bench"
#: The environment variable that hands an external DUT the run tag of its bench.
RUN_TAG_ENV = "BENCH_CAN_RUN_TAG"
#: python-can's default port: what a DUT told nothing else listens on.
DEFAULT_PORT = 43113
DEFAULT_INTERFACE_ADDRESS = "127.0.0.1"
#: The options of a udp_multicast link besides python-can's common ones.
UDP_OPTIONS = ("port", "interface_address", "hop_limit")


def check_udp_config(channel: Any, options: Mapping[str, Any], *, file: str | None = None, key: str = "can") -> None:
    """Raise :class:`ConfigError` (naming ``key.<name>``) for a udp_multicast channel that is
    not an IPv4 multicast group, or a bad ``port``, ``interface_address`` or ``hop_limit``."""
    if channel is not None:
        try:
            group = ipaddress.ip_address(channel) if isinstance(channel, str) else None
        except ValueError:
            group = None
        if not isinstance(group, ipaddress.IPv4Address) or not group.is_multicast:
            raise ConfigError(
                f"expected an IPv4 multicast group (224.0.0.0/4, e.g. 239.74.163.2), found {channel!r}",
                file=file,
                key=f"{key}.channel",
            )
    for name in options:
        if name not in UDP_OPTIONS:
            known = ", ".join(UDP_OPTIONS)
            raise ConfigError(f"unknown udp_multicast option {name!r}; known: {known}", file=file, key=f"{key}.{name}")
    for name, low, high in (("port", 0, 65_535), ("hop_limit", 0, 255)):
        v = options.get(name)
        if v is not None and (not isinstance(v, int) or isinstance(v, bool) or not low <= v <= high):
            raise ConfigError(f"expected an integer {low} .. {high}, found {v!r}", file=file, key=f"{key}.{name}")
    addr = options.get("interface_address")
    if addr is not None:
        try:
            ok = isinstance(addr, str) and isinstance(ipaddress.ip_address(addr), ipaddress.IPv4Address)
        except ValueError:
            ok = False
        if not ok:
            raise ConfigError(
                f"expected the IPv4 address of an interface (127.0.0.1 for the loopback), found {addr!r}",
                file=file,
                key=f"{key}.interface_address",
            )


class UdpMulticastCanLink(CanLink):
    """A :class:`~bench.transport.can_link.CanLink` on UDP multicast, isolated per run.

    Parameters
    ----------
    config, clock:
        As for :class:`CanLink`; ``config.options`` may hold ``port`` (0: a free one),
        ``interface_address`` and ``hop_limit``.
    run_tag:
        The run this link belongs to; None: a new run (a bench); ``""``: no run (accept
        every run's frames).
    recv_buffer:
        Socket receive buffer, bytes (0: the system's).

    ``stats()`` adds ``port``, ``drops`` (frames missing from tagged peers), ``reordered``,
    ``untagged``, ``own`` (own frames seen and skipped; 0 where the kernel drops them), ``senders``, ``foreign``
    (datagrams that are no message, or carry a malformed tag) and ``other_bench``
    (frames of another run).
    """

    def __init__(
        self,
        config: CanConfig | None = None,
        *,
        clock: Callable[[], int] | None = None,
        run_tag: str | None = None,
        recv_buffer: int = 8 << 20,
    ):
        config = config or CanConfig(interface="udp_multicast")
        check_udp_config(config.resolved_channel, config.options)
        self.run_tag = secrets.token_hex(4) if run_tag is None else run_tag
        if ":" in self.run_tag:
            raise ValueError(f"a run tag holds no ':', found {self.run_tag!r}")
        self.sender = f"{os.getpid():x}{secrets.token_hex(3)}"
        self.recv_buffer = recv_buffer
        self._seq = 0
        self._expected: dict[str, int] = {}
        self.drops = 0
        self.reordered = 0
        self.untagged = 0
        self.own = 0
        self.foreign = 0
        self.other_bench = 0
        self.port = 0
        super().__init__(config, clock=clock)

    @property
    def tag(self) -> str:
        """``<run>:<sender>``: what this link's frames carry after ``bench:``."""
        return f"{self.run_tag}:{self.sender}"

    def _open(self) -> MulticastSocket:  # type: ignore[override]
        opts = self.config.options
        port = DEFAULT_PORT if opts.get("port") is None else int(opts["port"])
        iface = str(opts.get("interface_address") or DEFAULT_INTERFACE_ADDRESS)
        group = str(self.config.resolved_channel)
        try:
            sock = MulticastSocket(
                group, port, iface, int(opts.get("hop_limit", 1)), self.recv_buffer,
                skip_own=not self.config.receive_own_messages,
            )
        except OSError as exc:
            raise LinkError(
                f"cannot open CAN over UDP multicast: group {group} port {port or '(a free one)'} on the "
                f"interface {iface}: {exc} (the loopback needs multicast on and a route: ip link set lo "
                "multicast on; ip route add 239.0.0.0/8 dev lo; see docs/run_engine.md, cross-process CAN)"
            ) from exc
        self.port = sock.port
        return sock

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return f"{type(self).__name__}({self.config.resolved_channel}:{self.port}, {state})"

    def _send_message(self, msg: can.Message, timeout: float | None) -> None:
        self._check_open()
        if msg.is_fd and not self.config.fd:
            raise LinkError(f"{self!r}: cannot send the CAN FD frame 0x{msg.arbitration_id:03X} (fd is off)")
        try:
            self.bus.send(pack_message(msg), timeout)
        except (can.CanError, OSError) as exc:
            raise LinkError(f"{self!r}: sending 0x{msg.arbitration_id:03X} failed: {exc}") from exc
        self.sent += 1

    def _receive(self, timeout: float | None) -> can.Message | object | None:
        try:
            data = self.bus.recv(timeout)
        except OSError as exc:
            raise LinkError(f"{self!r}: receiving failed: {exc}") from exc
        if data is None:
            return None
        arrival = self.bus.arrival_ns
        msg = self._unpack(data, arrival)
        if msg is not SKIPPED:
            self._arrival_ns = arrival  # the kernel's arrival time (CLOCK_REALTIME), for arrival_clock
        return msg

    def _unpack(self, data: bytes, arrival: int | None) -> can.Message | object:
        """The message of a datagram, or :data:`SKIPPED` (counted ``foreign``)."""
        try:
            msg = unpack_message(data, check=True)
            if not isinstance(msg.channel, str | None):
                raise TypeError("channel")
        except Exception:  # stray bytes: anything msgpack or can.Message refuses
            self.foreign += 1
            return SKIPPED
        msg.timestamp = (arrival if arrival is not None else time.time_ns()) * 1e-9  # as python-can stamps it
        return msg

    @property
    def defers_decoding(self) -> bool:  # type: ignore[override]
        """Where the kernel drops own frames, every datagram read is a peer's or a stray:
        they are unpacked later (:meth:`decode_raw`)."""
        return bool(getattr(self.bus, "own_filtered", False))

    def collect_raw(self, timeout: float | None, max_items: int) -> list:
        """The datagrams that arrived, each with its bench time of arrival (None: none
        known), waiting up to ``timeout`` s for the first; unpacked later by
        :meth:`decode_raw`. Decoded at once where own frames reach the socket."""
        if not self.defers_decoding:
            return self._collect(timeout, max_items)
        self._check_open()
        bus, items = self.bus, []
        wait = timeout
        for _ in range(max(1, min(max_items, self.drain_limit))):
            try:
                data = bus.recv(wait)
            except OSError as exc:
                raise LinkError(f"{self!r}: receiving failed: {exc}") from exc
            if data is None:
                break
            arrival = bus.arrival_ns
            if arrival is not None and self.arrival_clock is not None:
                stamp: int | None = self.arrival_clock(arrival)
            else:
                stamp = self.clock() if self.clock is not None else None
            items.append((data, stamp, arrival))
            wait = 0.0
        return items

    def decode_raw(self, items: list) -> list[CanFrame]:
        if not self.defers_decoding:
            return items
        frames = []
        for data, stamp, arrival in items:
            msg = self._unpack(data, arrival)
            if msg is SKIPPED:
                continue
            self._arrival_ns = None
            frame = self._from_message(msg)  # type: ignore[arg-type]
            if frame is None:
                continue
            self.received += 1
            if stamp is not None:
                frame = CanFrame(int(stamp), frame.can_id, frame.data, frame.fd)
            frames.append(frame)
        return frames

    def _to_message(self, t_ns: int, can_id: int, data: bytes, fd: bool) -> can.Message:
        msg = super()._to_message(t_ns, can_id, data, fd)
        msg.channel = f"{TAG_PREFIX}:{self.run_tag}:{self.sender}:{self._seq}:{t_ns}"
        self._seq += 1
        return msg

    def _from_message(self, msg: can.Message) -> CanFrame | None:
        ch = msg.channel
        if not isinstance(ch, str) or not ch.startswith(TAG_PREFIX + ":"):
            self.untagged += 1
            return super()._from_message(msg)
        parts = ch.split(":")
        try:
            if len(parts) != 5:
                raise ValueError(ch)
            run, sender, seq, t_ns = parts[1], parts[2], int(parts[3]), int(parts[4])
        except ValueError:
            self.foreign += 1
            return None
        if run and self.run_tag and run != self.run_tag:
            self.other_bench += 1
            return None
        if sender == self.sender:
            self.own += 1
            if not self.config.receive_own_messages:
                return None
        else:
            expected = self._expected.get(sender)
            if expected is None or seq >= expected:
                if expected is not None:
                    self.drops += seq - expected
                self._expected[sender] = seq + 1
            else:
                self.reordered += 1
        if self.clock is None:
            msg.timestamp = t_ns * 1e-9
        frame = super()._from_message(msg)
        if sender == self.sender:
            self.peer_frames -= 1  # received back, not from a peer
        return frame

    def stats(self) -> dict[str, int]:
        """Sent and received frames, the port, drops, reordered, untagged, own, foreign and
        other benches' frames."""
        return {
            **super().stats(),
            "port": self.port,
            "drops": self.drops,
            "reordered": self.reordered,
            "untagged": self.untagged,
            "own": self.own,
            "senders": len(self._expected),
            "foreign": self.foreign,
            "other_bench": self.other_bench,
        }
