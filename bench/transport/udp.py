"""CAN over python-can's ``udp_multicast`` bus, with sequence numbers and a drop count.

UDP multicast loses datagrams when a receiver's socket buffer overflows and may reorder
them, and python-can's bus hands every datagram back to its own sender too. The ICD
payloads must stay untouched, so the bench carries its bookkeeping in the one message
field python-can's packing transmits but CAN does not: ``Message.channel``. Every frame
a :class:`UdpMulticastCanLink` sends has the channel ``"bench:<sender tag>:<sequence>:<t_ns>"``:

* ``sender tag``: unique per link (process id and random bits), so a link recognises and
  skips its own frames (unless ``receive_own_messages``) and tells senders apart;
* ``sequence``: +1 per frame sent by that link; a receiver expects, per sender, the next
  number: a gap of k counts ``k`` drops, a number below the expected one a ``reordered``
  frame (delivered late);
* ``t_ns``: the sender's bench time of the frame (the bus itself stamps arrival with the
  host clock), so receivers without a bench clock see bench time as on ``virtual``.

Frames from senders that do not tag (an external DUT using plain python-can) are
delivered as they are and counted ``untagged``; their losses cannot be seen here (the
ICD alive and epoch counters still show them). The socket receive buffer is enlarged
(8 MiB by default, ``SO_RCVBUFFORCE`` when permitted) to make overflow rare.
"""

from __future__ import annotations

import os
import secrets
import socket
from collections.abc import Callable

import can

from bench.frames import CanFrame
from bench.transport.can_link import CanConfig, CanLink

__all__ = ["UdpMulticastCanLink", "TAG_PREFIX"]

TAG_PREFIX = "bench"
_SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)


class UdpMulticastCanLink(CanLink):
    """A :class:`~bench.transport.can_link.CanLink` on udp_multicast with drop detection.

    ``stats()`` adds ``drops`` (frames missing from tagged senders), ``reordered``,
    ``untagged`` and ``own`` (own frames seen and skipped).
    """

    def __init__(
        self,
        config: CanConfig | None = None,
        *,
        clock: Callable[[], int] | None = None,
        recv_buffer: int = 8 << 20,
    ):
        self.tag = f"{os.getpid():x}{secrets.token_hex(3)}"
        self.recv_buffer = recv_buffer
        self._seq = 0
        self._expected: dict[str, int] = {}
        self.drops = 0
        self.reordered = 0
        self.untagged = 0
        self.own = 0
        super().__init__(config or CanConfig(interface="udp_multicast"), clock=clock)

    def _open(self) -> can.BusABC:
        kw = self.config.bus_kwargs()
        kw.pop("receive_own_messages", None)  # python-can refuses it; own frames are filtered here
        for name in ("bitrate", "data_bitrate"):
            kw.pop(name, None)
        bus = can.Bus(**kw)
        sock = getattr(getattr(bus, "_multicast", None), "_socket", None)
        if sock is not None and self.recv_buffer:
            for opt in (_SO_RCVBUFFORCE, socket.SO_RCVBUF):
                try:
                    sock.setsockopt(socket.SOL_SOCKET, opt, self.recv_buffer)
                    break
                except OSError:
                    continue
        return bus

    def _to_message(self, t_ns: int, can_id: int, data: bytes, fd: bool) -> can.Message:
        msg = super()._to_message(t_ns, can_id, data, fd)
        msg.channel = f"{TAG_PREFIX}:{self.tag}:{self._seq}:{t_ns}"
        self._seq += 1
        return msg

    def _from_message(self, msg: can.Message) -> CanFrame | None:
        ch = msg.channel
        parts = ch.split(":") if isinstance(ch, str) else []
        if len(parts) == 4 and parts[0] == TAG_PREFIX:
            tag, seq, t_ns = parts[1], int(parts[2]), int(parts[3])
            if tag == self.tag:
                self.own += 1
                if not self.config.receive_own_messages:
                    return None
            else:
                expected = self._expected.get(tag)
                if expected is None or seq >= expected:
                    if expected is not None:
                        self.drops += seq - expected
                    self._expected[tag] = seq + 1
                else:
                    self.reordered += 1
            if self.clock is None:
                msg.timestamp = t_ns * 1e-9
        else:
            self.untagged += 1
        return super()._from_message(msg)

    def stats(self) -> dict[str, int]:
        """Sent and received frames, drops, reordered, untagged and own frames."""
        return {
            **super().stats(),
            "drops": self.drops,
            "reordered": self.reordered,
            "untagged": self.untagged,
            "own": self.own,
            "senders": len(self._expected),
        }
