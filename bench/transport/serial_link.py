"""Serial links: pty pairs for local DUTs, real ports and pyserial URLs (``loop://``).

* ``port = "pty"``: the bench creates a pseudo-terminal pair (:class:`PtyPair`), keeps
  the master and gives the DUT the slave's path (``/dev/pts/N``) to open like a serial
  port. The slave is put in raw mode at creation (no echo, no CR/LF translation), and the
  bench keeps it open too, so bytes written before the DUT opens it wait in the line
  buffer and the master never sees a hang-up when the DUT reopens.
* a device path (``/dev/ttyUSB0``) or any pyserial URL (``loop://`` for tests,
  ``socket://host:port``, ``rfc2217://``): opened with pyserial at the configured baud
  and framing.

:meth:`SerialLink.write_many` writes a whole batch in one call (one system call for a
pty: about 40 us per call, so never one frame at a time on hot paths). A pty delivers
bytes at once whatever the baud; real-time pacing is :mod:`bench.transport.pacing`.

:meth:`SerialLink.deliver` makes what was written readable at the far end before the
bench goes on (lockstep: before BENCH_TIME(T), ICD 6). A write to a pty master only
queues the bytes: the tty layer moves them into the slave's line discipline from a work
item a moment later, and until then the slave's ``FIONREAD`` (pyserial's
``in_waiting``) does not count them, so a CAN frame sent meanwhile can overtake them.
``poll`` on a slave that has nothing readable runs that work at once (the kernel's
``n_tty_poll`` flushes the buffer work), and the bench keeps a slave descriptor of its
own, so :class:`PtyLink` polls it: every byte written is then readable by the DUT, up to
the line discipline's buffer (4095 bytes, measured when the pair is made); a step with
more waits, polling again, until the DUT has read enough for the rest to move in. This
holds when the DUT had read what it was given before (ICD 6: all pending input before
each BENCH_TIME): a poll of a slave that still holds bytes does not run the work. A real
port (:class:`PySerialLink`) waits until its output is transmitted (``flush``:
``tcdrain``).
"""

from __future__ import annotations

import errno
import os
import queue
import select
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import serial

from bench.config.bounds import check
from bench.config.table import check_keys
from bench.errors import ConfigError, LinkError
from bench.frames import SerialBatch, SerialChunk
from bench.transport.pacing import parse_framing
from bench.transport.pty import _SETTLE_S, PtyPair

__all__ = ["SerialConfig", "SerialLink", "PtyPair", "PtyLink", "PySerialLink", "open_serial_link"]

#: A line whose readable count has not changed for this long is taken as delivered: the
#: DUT left bytes unread, and nothing more can move in until it reads.
_STILL_S = 0.01


@dataclass
class SerialConfig:
    """One serial link: ``port`` (``"pty"``, a device path or a pyserial URL), baud, framing.

    ICD: ``imu`` 460800 8N1, ``gnss`` 115200 8N1. ``write_timeout`` (s) bounds how long a
    write may block on a DUT that does not read.
    """

    port: str = "pty"
    baudrate: int = 460_800
    framing: str = "8N1"
    write_timeout: float = 5.0

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any], *, file: str | None = None, key: str = "serial") -> SerialConfig:
        """A config from a TOML table (keys port, baudrate, framing, write_timeout)."""
        allowed = {"port", "baudrate", "framing", "write_timeout"}
        check_keys(table, allowed, file=file, key=key)
        cfg = cls(**table)
        if not isinstance(cfg.port, str):
            raise ConfigError(f"expected a port name, found {cfg.port!r}", file=file, key=f"{key}.port")
        if not isinstance(cfg.baudrate, int) or isinstance(cfg.baudrate, bool) or cfg.baudrate <= 0:
            raise ConfigError(f"expected a positive integer, found {cfg.baudrate!r}", file=file, key=f"{key}.baudrate")
        check("baud", cfg.baudrate, file=file, key=f"{key}.baudrate")
        w = cfg.write_timeout
        if isinstance(w, bool) or not isinstance(w, (int, float)):
            raise ConfigError(f"expected a number of seconds, found {w!r}", file=file, key=f"{key}.write_timeout")
        check("timeout", float(w), file=file, key=f"{key}.write_timeout", shown=w)
        try:
            parse_framing(cfg.framing)
        except ValueError as exc:
            raise ConfigError(str(exc), file=file, key=f"{key}.framing") from None
        return cfg


class SerialLink:
    """The bench's end of a serial line (a context manager with idempotent close).

    ``clock`` (bench time now, ns) stamps what :meth:`read_chunk` returns.
    """

    #: The path the DUT opens (the pty slave), or None when the DUT is on the far end of a cable.
    dut_port: str | None = None

    def __init__(self, config: SerialConfig, *, clock: Callable[[], int] | None = None):
        self.config = config
        self.clock = clock
        self.bytes_written = 0
        self.bytes_read = 0
        self._closed = False

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.config.port}, {self.config.baudrate} {self.config.framing})"

    # subclasses implement these three
    def _write(self, data: bytes, timeout: float) -> None:
        raise NotImplementedError

    def _read(self, timeout: float | None, max_bytes: int) -> bytes:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    def write(self, data: bytes) -> None:
        """Write all of ``data`` (LinkError if the far end does not take it within ``write_timeout``)."""
        if self._closed:
            raise LinkError(f"{self!r} is closed")
        if data:
            self._write(bytes(data), self.config.write_timeout)
            self.bytes_written += len(data)

    def write_some(self, data: bytes) -> int:
        """Write what the line takes now, without waiting; returns the bytes taken (a pty
        whose far end does not read takes fewer; other links take everything)."""
        self.write(data)
        return len(data)

    def write_many(self, chunks: SerialBatch | Iterable[SerialChunk]) -> int:
        """Write every chunk in one call; returns the number of bytes."""
        data = chunks.tobytes() if isinstance(chunks, SerialBatch) else b"".join(c.data for c in chunks)
        self.write(data)
        return len(data)

    def deliver(self) -> None:
        """Return once every byte written so far is readable at the far end (or, on a
        real line, transmitted); see the module docstring."""
        if self._closed:
            raise LinkError(f"{self!r} is closed")
        self._deliver()

    def _deliver(self) -> None:
        """Subclasses: make the written bytes readable at the far end."""

    def read(self, timeout: float | None = 0.0, max_bytes: int = 1 << 16) -> bytes:
        """What is available, waiting up to ``timeout`` s for the first byte (b"" if none)."""
        if self._closed:
            raise LinkError(f"{self!r} is closed")
        data = self._read(timeout, max_bytes)
        self.bytes_read += len(data)
        return data

    def fileno(self) -> int | None:
        """A file descriptor that ``select`` reports readable when bytes wait to be read, or
        None when the link has none (pyserial URLs): then poll :meth:`read` with a timeout."""
        return None

    def read_chunk(self, timeout: float | None = 0.0, max_bytes: int = 1 << 16) -> SerialChunk:
        """:meth:`read` stamped with the bench clock (0 without one)."""
        data = self.read(timeout, max_bytes)
        return SerialChunk(int(self.clock()) if self.clock else 0, data)

    def close(self) -> None:
        """Close the port (safe to call twice)."""
        if not self._closed:
            self._closed = True
            self._close()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` ran."""
        return self._closed

    def __enter__(self) -> SerialLink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        if not getattr(self, "_closed", True):
            self.close()


class PtyLink(SerialLink):
    """The bench's end (master) of a :class:`PtyPair`; ``dut_port`` is the slave path."""

    def __init__(self, config: SerialConfig | None = None, *, clock: Callable[[], int] | None = None):
        super().__init__(config or SerialConfig(), clock=clock)
        try:
            self.pair = PtyPair(self.config.baudrate)
        except OSError as exc:
            self._closed = True
            raise LinkError(f"cannot create a pty pair: {exc}") from exc
        self.dut_port = self.pair.slave_path
        self._undelivered = 0

    def fileno(self) -> int | None:
        return None if self._closed else self.pair.master_fd

    def write_some(self, data: bytes) -> int:
        if self._closed:
            raise LinkError(f"{self!r} is closed")
        try:
            n = os.write(self.pair.master_fd, data) if data else 0
        except BlockingIOError:
            return 0
        except OSError as exc:
            raise LinkError(f"{self!r}: write failed: {exc}") from exc
        self._undelivered += n
        self.bytes_written += n
        return n

    def _write(self, data: bytes, timeout: float) -> None:
        view = memoryview(data)
        deadline = time.monotonic() + timeout
        while view:
            try:
                n = os.write(self.pair.master_fd, view)
                view = view[n:]
                self._undelivered += n
                continue
            except BlockingIOError:
                pass
            except OSError as exc:
                raise LinkError(f"{self!r}: write failed: {exc}") from exc
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([], [self.pair.master_fd], [], left)[1]:
                raise LinkError(
                    f"{self!r}: the DUT on {self.dut_port} took no bytes for {timeout:g} s "
                    f"({len(view)} of {len(data)} bytes left)"
                )

    def _deliver(self) -> None:
        # See the module docstring. ``written``: bytes written since the last delivery.
        pair, timeout = self.pair, self.config.write_timeout
        written, self._undelivered = self._undelivered, 0
        deadline = time.monotonic() + timeout
        last, since = -1, time.monotonic()
        while True:
            pair.settle()
            held = pair.readable()
            if held == 0:
                # that poll found nothing readable, so it ran the pending work; once more,
                # in case the DUT emptied the buffer between the poll and the count
                pair.settle()
                held = pair.readable()
                if held == 0:
                    return  # nothing waits in the tty layer: the DUT has read it all
            elif held >= written and held < pair.ldisc_capacity:
                return  # everything written is readable (the DUT has read none of it yet)
            now = time.monotonic()
            if held >= pair.ldisc_capacity:  # full: the rest moves in as the DUT reads
                if now > deadline:
                    raise LinkError(
                        f"{self!r}: the DUT on {self.dut_port} took no bytes for {timeout:g} s "
                        f"({held} bytes readable, more waiting to move in)"
                    )
            elif held != last:
                last, since = held, now  # the DUT reads, or the kernel is still moving bytes in
            elif now - since > _STILL_S:
                return  # nothing moved for a while: the DUT left bytes unread (ICD 6 asks it not to)
            time.sleep(_SETTLE_S)

    def _read(self, timeout: float | None, max_bytes: int) -> bytes:
        fd = self.pair.master_fd
        if timeout != 0.0 and not select.select([fd], [], [], timeout)[0]:
            return b""
        out = bytearray()
        while len(out) < max_bytes:
            try:
                part = os.read(fd, max_bytes - len(out))
            except BlockingIOError:
                break
            except OSError as exc:
                if exc.errno == errno.EIO:  # no slave open: nothing to read
                    break
                raise LinkError(f"{self!r}: read failed: {exc}") from exc
            if not part:
                break
            out += part
        return bytes(out)

    def _close(self) -> None:
        self.pair.close()


class PySerialLink(SerialLink):
    """A real port or a pyserial URL (``loop://``), opened with pyserial."""

    def __init__(self, config: SerialConfig, *, clock: Callable[[], int] | None = None):
        super().__init__(config, clock=clock)
        data, parity, stop = parse_framing(config.framing)
        try:
            self.port = serial.serial_for_url(
                config.port,
                baudrate=config.baudrate,
                bytesize=data,
                parity=parity,
                stopbits=stop,
                timeout=0,
                write_timeout=config.write_timeout,
            )
        except (serial.SerialException, ValueError, OSError) as exc:
            self._closed = True
            raise LinkError(f"cannot open serial port {config.port!r}: {exc}") from exc

    def _write(self, data: bytes, timeout: float) -> None:
        try:
            self.port.write(data)
        except (serial.SerialTimeoutException, queue.Full) as exc:  # loop:// raises queue.Full
            raise LinkError(f"{self!r}: the far end took no bytes for {timeout:g} s") from exc
        except serial.SerialException as exc:
            raise LinkError(f"{self!r}: write failed: {exc}") from exc

    def _deliver(self) -> None:
        try:
            self.port.flush()  # tcdrain on a real port: the bytes are on the wire
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"{self!r}: waiting for the output to be transmitted failed: {exc}") from exc

    def _read(self, timeout: float | None, max_bytes: int) -> bytes:
        try:
            waiting = self.port.in_waiting
            if not waiting and timeout != 0.0:
                self.port.timeout = timeout
                first = self.port.read(1)
                self.port.timeout = 0
                if not first:
                    return b""
                return first + self.port.read(min(self.port.in_waiting, max_bytes - 1))
            return self.port.read(min(waiting, max_bytes))
        except serial.SerialException as exc:
            raise LinkError(f"{self!r}: read failed: {exc}") from exc

    def _close(self) -> None:
        self.port.close()


def open_serial_link(config: SerialConfig, *, clock: Callable[[], int] | None = None) -> SerialLink:
    """A pty pair for ``port = "pty"``, else the port or URL through pyserial."""
    if config.port == "pty":
        return PtyLink(config, clock=clock)
    return PySerialLink(config, clock=clock)
