"""A pseudo-terminal pair with a raw slave, the bench's end of a ``port = "pty"`` line
(:class:`~bench.transport.serial_link.PtyLink`; why the bench keeps a slave descriptor
and polls it: :mod:`bench.transport.serial_link`)."""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import struct
import termios
import time
import tty

__all__ = ["PtyPair"]

#: A delivery's wait between two polls while the DUT reads or the kernel's work moves
#: bytes in (that work may be preempted for a scheduler slice on a busy machine).
_SETTLE_S = 0.0002

_BAUD_CONSTANTS = {
    b: getattr(termios, f"B{b}")
    for b in (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
    if hasattr(termios, f"B{b}")
}


class PtyPair:
    """A pseudo-terminal pair: the bench keeps ``master_fd``, the DUT opens ``slave_path``.

    The slave is raw (8 bits, no echo, no line discipline) with the configured baud in its
    termios (ptys ignore it, but a DUT that reads it back finds what it expects).
    """

    def __init__(self, baudrate: int = 460_800):
        self.master_fd, self.slave_fd = os.openpty()
        try:
            tty.setraw(self.slave_fd)
            attrs = termios.tcgetattr(self.slave_fd)
            speed = _BAUD_CONSTANTS.get(baudrate)
            if speed is not None:
                attrs[4] = attrs[5] = speed
            termios.tcsetattr(self.slave_fd, termios.TCSANOW, attrs)
            os.set_blocking(self.master_fd, False)
            self.slave_path = os.ttyname(self.slave_fd)
            #: bytes the slave's line discipline holds readable at most (4095 on Linux)
            self.ldisc_capacity = self._measure_capacity()
        except OSError:
            self.close()
            raise
        self._closed = False

    def settle(self) -> None:
        """Run the tty layer's pending work now: a poll of a slave with nothing readable
        moves what the master wrote into its line discipline (see the module docstring)."""
        poller = select.poll()
        poller.register(self.slave_fd, select.POLLIN)
        poller.poll(0)

    def readable(self) -> int:
        """Bytes the slave's line discipline holds readable (``FIONREAD``, the DUT's
        ``in_waiting``)."""
        return struct.unpack("i", fcntl.ioctl(self.slave_fd, termios.FIONREAD, b"\0\0\0\0"))[0]

    def _measure_capacity(self) -> int:
        """Fill the line discipline once, before the DUT opens the slave: what it holds
        once the tty layer's work has stopped moving bytes in; then empty it again."""
        os.set_blocking(self.slave_fd, False)
        try:
            with contextlib.suppress(BlockingIOError):
                os.write(self.master_fd, bytes(16384))
            capacity, still = -1, 0
            for _ in range(100):  # the work may be preempted between its buffers: until steady
                self.settle()
                held = self.readable()
                still = still + 1 if held == capacity else 0
                capacity = held
                if still >= 3:
                    break
                time.sleep(_SETTLE_S)
            with contextlib.suppress(BlockingIOError):
                while os.read(self.slave_fd, 65536):  # EAGAIN only once the pending work ran
                    pass
        finally:
            os.set_blocking(self.slave_fd, True)
        return max(capacity, 1)

    def close(self) -> None:
        """Close both ends (safe to call twice)."""
        for name in ("master_fd", "slave_fd"):
            fd = getattr(self, name, -1)
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
                setattr(self, name, -1)
        self._closed = True

    def __enter__(self) -> PtyPair:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
