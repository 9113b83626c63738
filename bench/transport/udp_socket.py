"""The bench's end of a UDP multicast group (:mod:`bench.transport.udp` carries CAN on it):
bound to the group on one interface, sending from a socket of its own whose datagrams a
socket filter keeps from coming back (Linux), receive stamps from the kernel."""

from __future__ import annotations

import contextlib
import ctypes
import select
import socket
import struct
import sys

import can

__all__ = ["MulticastSocket"]

_SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
_IP_MULTICAST_ALL = getattr(socket, "IP_MULTICAST_ALL", 49)  # Linux
_MAX_DATAGRAM = 4096  # a packed CAN FD message is about 200 bytes
_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)  # Linux: the kernel's arrival time of each datagram


class MulticastSocket:
    """The bench's end of the group: send, receive (raw datagrams), shutdown."""

    def __init__(
        self, group: str, port: int, interface_address: str, hop_limit: int, recv_buffer: int, skip_own: bool = True
    ):
        self.group = group
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            iface = socket.inet_aton(interface_address)
            if port:  # shared with the DUT's socket (python-can reuses addresses)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                if hasattr(socket, "SO_REUSEPORT"):
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            sock.bind((group, port))
            if not port:  # a port no socket held; now open it to the DUT's
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            with contextlib.suppress(OSError):  # only the group joined here (Linux)
                sock.setsockopt(socket.IPPROTO_IP, _IP_MULTICAST_ALL, 0)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, socket.inet_aton(group) + iface)
            if recv_buffer:
                for opt in (_SO_RCVBUFFORCE, socket.SO_RCVBUF):
                    try:
                        sock.setsockopt(socket.SOL_SOCKET, opt, recv_buffer)
                        break
                    except OSError:
                        continue
            for s in (sock, out):  # the sending socket too: a DUT on this host gets the frames
                s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, hop_limit)
                s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, iface)
                s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
            out.bind((interface_address, 0))
        except OSError:
            sock.close()
            out.close()
            raise
        self.sock = sock
        self.out = out
        #: True when the kernel drops this link's own frames before they reach ``sock``
        self.own_filtered = skip_own and _drop_from_port(sock, out.getsockname()[1])
        #: CLOCK_REALTIME ns at which the kernel received the last datagram read (None: unknown).
        #: Linux turns arrival stamping on from a work queue a moment after the first socket
        #: asks; a datagram that arrives before then is stamped when it is read.
        self.arrival_ns: int | None = None
        try:
            sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            self._stamped = True
        except OSError:
            self._stamped = False
        self.port = int(sock.getsockname()[1])
        self._dest = (group, self.port)
        self._poll = select.poll()  # not select(): any descriptor number
        self._poll.register(sock, select.POLLIN)

    def send(self, data: bytes, timeout: float | None) -> None:
        if timeout is None:
            self.out.sendto(data, self._dest)
            return
        try:
            self.out.sendto(data, socket.MSG_DONTWAIT, self._dest)
        except BlockingIOError:
            out = select.poll()
            out.register(self.out, select.POLLOUT)
            if not out.poll(timeout * 1e3):
                raise can.CanTimeoutError(f"the socket took no datagram within {timeout:g} s") from None
            self.out.sendto(data, socket.MSG_DONTWAIT, self._dest)

    def recv(self, timeout: float | None) -> bytes | None:
        if timeout != 0.0 and not self._poll.poll(None if timeout is None else timeout * 1e3):
            return None
        try:
            if not self._stamped:
                return self.sock.recv(_MAX_DATAGRAM, socket.MSG_DONTWAIT)
            data, anc, _, _ = self.sock.recvmsg(_MAX_DATAGRAM, 64, socket.MSG_DONTWAIT)
        except BlockingIOError:
            return None
        self.arrival_ns = None
        for level, kind, cdata in anc:
            if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(cdata) >= 16:
                sec, nsec = struct.unpack("qq", cdata[:16])
                self.arrival_ns = sec * 1_000_000_000 + nsec
        return data

    def shutdown(self) -> None:
        self.sock.close()
        self.out.close()


def _drop_from_port(sock: socket.socket, port: int) -> bool:
    """Attach a socket filter (classic BPF, Linux) that drops the datagrams whose UDP source
    port is ``port`` (the link's own, looped back by multicast) in the kernel; False where
    that is not possible (the link then skips them itself).

    A receive thread that unpacked every own frame took the interpreter lock right while the
    emission loop sent, for tens of microseconds per frame."""
    if not sys.platform.startswith("linux"):
        return False
    # for a UDP socket the filter sees the datagram from its UDP header: [0:2] the source port
    prog = [
        (0x28, 0, 0, 0),  # ldh [0]
        (0x15, 0, 1, port),  # jeq #port, drop, keep
        (0x06, 0, 0, 0),  # drop: ret #0
        (0x06, 0, 0, 0xFFFFFFFF),  # keep: ret #-1 (the whole datagram)
    ]
    code = b"".join(struct.pack("HBBI", *ins) for ins in prog)
    buf = ctypes.create_string_buffer(code, len(code))
    fprog = struct.pack("HL", len(prog), ctypes.addressof(buf))
    try:
        sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_ATTACH_FILTER", 26), fprog)
    except OSError:
        return False
    return True
