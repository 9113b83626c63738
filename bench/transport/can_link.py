"""CAN links over python-can: any interface python-can supports, one small wrapper.

A :class:`CanLink` opens a python-can bus from a :class:`CanConfig` (the usual python-can
settings: ``interface``, ``channel``, ``bitrate``, ``fd``, ``data_bitrate``,
``receive_own_messages`` and any interface option), and moves the bench's own frame
types across it: :meth:`CanLink.send_many` takes a :class:`~bench.frames.CanBatch`,
:meth:`CanLink.drain` returns one. This module and its siblings are the only places that
touch ``can.Message``.

* ``virtual`` (default; CI): in-process bus, timestamps preserved, so a receiver sees
  the bench time the frame was sent at.
* ``socketcan``: Linux SocketCAN, ``vcan0`` for cross-process runs on one machine. A
  missing interface is reported with the one-time setup
  ``ip link add dev vcan0 type vcan; ip link set up vcan0``.
* ``udp_multicast``: python-can's multicast wire format where neither fits (CI
  containers, network namespaces) on a socket bound to the group on the loopback (or
  the ``interface_address`` given), never on every address; see :mod:`bench.transport.udp`
  for the port, the run tag that filters other benches, the sequence numbers and the
  counts of foreign datagrams.
* ``interface=None``: python-can resolves everything from its configuration file or
  ``CAN_INTERFACE``/``CAN_CHANNEL``/``CAN_BITRATE`` environment variables.

Receiving never waits on a flood: one :meth:`CanLink.recv` or :meth:`CanLink.drain`
handles at most :attr:`CanLink.drain_limit` messages and returns by its timeout however
many keep coming. Remote (RTR) and error frames carry no ICD message and are not
returned, but they are counted (``remote``, ``error_frames``) and, like every frame a
peer sends, in :attr:`CanLink.peer_frames`, which a flood limit is checked against.

Time stamps: a sent frame's ``t_ns`` (bench time) goes out as the message timestamp in
seconds. A received frame gets ``t_ns`` from the link's ``arrival_clock`` applied to the
kernel's arrival time where the link knows it (udp_multicast: ``SO_TIMESTAMPNS``), else
from its ``clock`` (bench time now) when one is given, else the message timestamp
converted to ns (the sender's bench time on ``virtual``, the host clock of the receiving
socket on real interfaces).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import can

from bench.errors import ConfigError, LinkError
from bench.frames import CanBatch, CanFrame

__all__ = [
    "CanConfig",
    "CanLink",
    "open_can_link",
    "socketcan_unavailable",
    "VCAN_SETUP",
    "SKIPPED",
]

#: The one-time setup of a virtual SocketCAN interface (as root).
VCAN_SETUP = "ip link add dev {ch} type vcan; ip link set up {ch}"

_DEFAULT_CHANNELS = {"virtual": "bench", "socketcan": "vcan0", "udp_multicast": "239.74.163.2"}

#: What :meth:`CanLink._receive` returns for something that arrived but is no message
#: (a stray datagram): the receive loop goes on, the link has counted it.
SKIPPED = object()


@dataclass
class CanConfig:
    """python-can settings of one bus.

    ``interface`` None lets python-can read its own configuration; ``channel`` None takes
    the bench's default for the interface (``bench`` on virtual, ``vcan0`` on socketcan,
    ``239.74.163.2`` on udp_multicast). ``bitrate`` 500 kbit/s and ``data_bitrate``
    2 Mbit/s (ICD 2) are passed to interfaces that set them. ``fd`` must be true for the
    DUT's CAN FD frames. ``options`` go to ``can.Bus`` unchanged.
    """

    interface: str | None = "virtual"
    channel: str | int | None = None
    bitrate: int = 500_000
    fd: bool = True
    data_bitrate: int = 2_000_000
    receive_own_messages: bool = False
    options: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any], *, file: str | None = None, key: str = "can") -> CanConfig:
        """A config from a TOML table; unknown keys go to ``options`` only if python-can names them."""
        known = {f.name for f in fields(cls)} - {"options"}
        kwargs: dict[str, Any] = {}
        options: dict[str, Any] = dict(table.get("options", {}))
        for name, value in table.items():
            if name == "options":
                continue
            if name in known:
                kwargs[name] = value
            else:
                options[name] = value
        for name, typ in (("bitrate", int), ("data_bitrate", int), ("fd", bool), ("receive_own_messages", bool)):
            if name in kwargs and not isinstance(kwargs[name], typ):
                raise ConfigError(f"expected {typ.__name__}, found {kwargs[name]!r}", file=file, key=f"{key}.{name}")
        iface = kwargs.get("interface", "virtual")
        if iface is not None and iface not in can.VALID_INTERFACES:
            raise ConfigError(
                f"unknown python-can interface {iface!r}; known: {', '.join(sorted(can.VALID_INTERFACES))}",
                file=file,
                key=f"{key}.interface",
            )
        if iface == "udp_multicast":
            from bench.transport.udp import check_udp_config

            check_udp_config(kwargs.get("channel"), options, file=file, key=key)
        return cls(**kwargs, options=options)

    @property
    def resolved_channel(self) -> str | int | None:
        """The channel, or the bench's default for the interface."""
        return self.channel if self.channel is not None else _DEFAULT_CHANNELS.get(self.interface or "")

    def bus_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``can.Bus``."""
        kw: dict[str, Any] = {
            "channel": self.resolved_channel,
            "bitrate": self.bitrate,
            "fd": self.fd,
            "data_bitrate": self.data_bitrate,
            "receive_own_messages": self.receive_own_messages,
        }
        if self.interface is not None:
            kw["interface"] = self.interface
        if self.interface == "virtual":
            kw["preserve_timestamps"] = True
        if kw["channel"] is None:
            del kw["channel"]
        kw.update(self.options)
        return kw


def socketcan_unavailable(channel: str = "vcan0") -> str | None:
    """Why SocketCAN ``channel`` cannot be used here, with the fix; None if it can."""
    if not hasattr(socket, "AF_CAN") or not hasattr(socket, "CAN_RAW"):
        return "this Python has no SocketCAN support (socket.AF_CAN); SocketCAN needs Linux"
    sysfs = Path("/sys/class/net") / str(channel)
    if not sysfs.exists():
        fix = (
            VCAN_SETUP.format(ch=channel)
            if str(channel).startswith("vcan")
            else (f"ip link set {channel} up type can bitrate 500000 dbitrate 2000000 fd on")
        )
        return f"SocketCAN interface {channel!r} does not exist; set it up once as root: {fix}"
    try:
        state = (sysfs / "operstate").read_text().strip()
        flags = int((sysfs / "flags").read_text().strip(), 16)
    except OSError:
        return None
    if not flags & 0x1:  # IFF_UP
        return f"SocketCAN interface {channel!r} is down ({state}); bring it up as root: ip link set up {channel}"
    try:
        s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
        s.close()
    except OSError as exc:
        return f"the kernel refuses CAN_RAW sockets ({exc}); load the modules: modprobe can_raw vcan"
    return None


class CanLink:
    """One open python-can bus carrying bench frames (a context manager, idempotent close).

    Parameters
    ----------
    config:
        The bus settings.
    clock:
        Bench time now, ns; stamps received frames (None: use message timestamps).
    """

    #: The most messages one :meth:`recv` or :meth:`drain` handles before it returns.
    drain_limit = 65_536

    def __init__(self, config: CanConfig | None = None, *, clock: Callable[[], int] | None = None):
        self.config = config or CanConfig()
        self.clock = clock
        self.sent = 0
        self.received = 0
        #: Remote (RTR) and error frames received (counted, not returned).
        self.remote = 0
        self.error_frames = 0
        #: Every frame a peer sent that reached this link: data, remote and error frames.
        self.peer_frames = 0
        #: Maps the kernel's arrival time of a frame (CLOCK_REALTIME ns, where the link knows
        #: it: udp_multicast) to bench time; used instead of ``clock`` when set.
        self.arrival_clock: Callable[[int], int] | None = None
        self._arrival_ns: int | None = None
        self._closed = True  # until the bus is open
        if self.config.interface == "socketcan":
            reason = socketcan_unavailable(str(self.config.resolved_channel))
            if reason:
                raise LinkError(reason)
        try:
            self.bus = self._open()
        except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as exc:
            raise LinkError(
                f"cannot open CAN bus {self.config.interface!r} channel {self.config.resolved_channel!r}: {exc}"
            ) from exc
        self._closed = False

    def _open(self) -> can.BusABC:
        return can.Bus(**self.config.bus_kwargs())

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return f"{type(self).__name__}({self.config.interface}:{self.config.resolved_channel}, {state})"

    # ---------------------------------------------------------------- conversion
    def _to_message(self, t_ns: int, can_id: int, data: bytes, fd: bool) -> can.Message:
        return can.Message(
            timestamp=t_ns * 1e-9,
            arbitration_id=can_id,
            is_extended_id=can_id > 0x7FF,
            data=data,
            is_fd=fd,
            bitrate_switch=fd,
            check=False,
        )

    def _from_message(self, msg: can.Message) -> CanFrame | None:
        """The frame of a peer's message; None (counted) for remote and error frames."""
        self.peer_frames += 1
        if msg.is_error_frame:
            self.error_frames += 1
            return None
        if msg.is_remote_frame:
            self.remote += 1
            return None
        arrival, self._arrival_ns = self._arrival_ns, None
        if arrival is not None and self.arrival_clock is not None:
            t_ns = self.arrival_clock(arrival)
        else:
            t_ns = self.clock() if self.clock is not None else round(msg.timestamp * 1e9)
        return CanFrame(int(t_ns), int(msg.arbitration_id), bytes(msg.data), bool(msg.is_fd))

    # ---------------------------------------------------------------- traffic
    def _check_open(self) -> None:
        if self._closed:
            raise LinkError(f"{self!r} is closed")

    def send(self, frame: CanFrame, timeout: float | None = None) -> None:
        """Send one frame."""
        self._send_message(self._to_message(frame.t_ns, frame.can_id, frame.data, frame.fd), timeout)

    def _send_message(self, msg: can.Message, timeout: float | None) -> None:
        self._check_open()
        try:
            self.bus.send(msg, timeout)
        except can.CanError as exc:
            raise LinkError(f"{self!r}: sending 0x{msg.arbitration_id:03X} failed: {exc}") from exc
        self.sent += 1

    def send_many(self, frames: CanBatch | Iterable[CanFrame], timeout: float | None = None) -> int:
        """Send frames in order; returns how many were sent."""
        if not isinstance(frames, CanBatch):
            frames = CanBatch.from_frames(frames)
        n = len(frames)
        if n == 0:
            return 0
        width = frames.data.shape[1]
        flat = frames.data.tobytes()
        t = frames.t_ns.tolist()
        ids = frames.can_id.tolist()
        lengths = frames.length.tolist()
        fds = frames.fd.tolist()
        for i in range(n):  # python-can sends one message at a time
            start = i * width
            self._send_message(self._to_message(t[i], ids[i], flat[start : start + lengths[i]], fds[i]), timeout)
        return n

    def _receive(self, timeout: float | None) -> can.Message | object | None:
        """The next message from the bus within ``timeout`` s (None: forever); None when
        nothing came, :data:`SKIPPED` for something that is no message."""
        try:
            return self.bus.recv(timeout)
        except can.CanError as exc:
            raise LinkError(f"{self!r}: receiving failed: {exc}") from exc

    def recv(self, timeout: float | None = 0.0) -> CanFrame | None:
        """The next frame, waiting up to ``timeout`` s (None: forever); None if none came."""
        got = self._collect(timeout, 1)
        return got[0] if got else None

    def drain(self, timeout: float | None = 0.0, max_frames: int | None = None) -> CanBatch:
        """Every frame that is pending, waiting up to ``timeout`` s for the first one.

        Messages that are not returned (remote and error frames, a stray datagram, own or
        another bench's frames) do not restart the wait: it ends at ``timeout`` whatever
        arrives, and after :attr:`drain_limit` messages at most."""
        frames = self._collect(timeout, self.drain_limit if max_frames is None else max_frames)
        return CanBatch.from_frames(frames) if frames else CanBatch.empty()

    #: True when :meth:`collect_raw` leaves the decoding to :meth:`decode_raw` (a receive
    #: thread then holds the interpreter lock only for the reading).
    defers_decoding = False

    def collect_raw(self, timeout: float | None, max_items: int) -> list:
        """What arrived, waiting up to ``timeout`` s for the first item, each stamped on
        arrival, for :meth:`decode_raw`; here the frames themselves (decoded at once)."""
        return self._collect(timeout, max_items)

    def decode_raw(self, items: list) -> list[CanFrame]:
        """The frames of items from :meth:`collect_raw`, in order (the counters updated as
        if they had been received now)."""
        return items

    def _collect(self, timeout: float | None, max_frames: int) -> list[CanFrame]:
        self._check_open()
        frames: list[CanFrame] = []
        limit = max(1, min(max_frames, self.drain_limit))
        deadline = None if timeout is None else time.monotonic() + timeout
        wait = timeout
        for _ in range(self.drain_limit):
            msg = self._receive(wait)
            if msg is None:
                break
            frame = None if msg is SKIPPED else self._from_message(msg)  # type: ignore[arg-type]
            if frame is not None:
                self.received += 1
                frames.append(frame)
                if len(frames) >= limit:
                    break
                wait = 0.0
            elif not frames and deadline is not None:  # still waiting for the first frame
                wait = max(0.0, deadline - time.monotonic())
        return frames

    def stats(self) -> dict[str, int]:
        """Frames sent and received, remote and error frames received (subclasses add
        their own counts)."""
        return {
            "sent": self.sent,
            "received": self.received,
            "remote": self.remote,
            "error_frames": self.error_frames,
        }

    # ---------------------------------------------------------------- lifetime
    def close(self) -> None:
        """Shut the bus down (safe to call twice)."""
        if self._closed:
            return
        self._closed = True
        self.bus.shutdown()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` ran."""
        return self._closed

    def __enter__(self) -> CanLink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:  # a forgotten link must not keep a bus (or a socket) open
        if not getattr(self, "_closed", True):
            self.close()


def open_can_link(
    config: CanConfig | None = None, *, clock: Callable[[], int] | None = None, run_tag: str | None = None
) -> CanLink:
    """The link class for ``config.interface`` (udp_multicast: isolated, with sequence
    numbers; ``run_tag`` as :class:`~bench.transport.udp.UdpMulticastCanLink` takes it)."""
    config = config or CanConfig()
    if config.interface == "udp_multicast":
        from bench.transport.udp import UdpMulticastCanLink

        return UdpMulticastCanLink(config, clock=clock, run_tag=run_tag)
    return CanLink(config, clock=clock)
