"""Reading what the far end writes on a serial link, so that it never blocks.

The bench writes the sensor bytes on its serial lines; a DUT may write back (an echo, a
configuration command, diagnostics). On a pty nobody reads those bytes unless the bench
does, and once the line buffer (a few KiB) is full the DUT's next write blocks: a DUT
that stalls because of the bench. :class:`SerialReader` drains a link in a thread of its
own and keeps what it read as chunks stamped with the bench clock at the time they were
read; the run takes them (:meth:`SerialReader.take`) and records them.

The thread sleeps in ``select`` on the link's descriptor (a pty master) and a wake-up
pipe, so an idle line costs nothing and the reader never competes with a real-time
emission loop unless the DUT really writes; a link without a descriptor (a pyserial URL)
is polled every 50 ms. When more than ``max_pending`` bytes wait to be taken it stops
reading until they are, so the far end waits as on a full line rather than the bench's
memory growing without bound. :meth:`SerialReader.close` stops the thread, reads what is
left on the line (up to ``max_pending`` more bytes, whatever is still waiting to be taken)
and returns it; close the reader before the link.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
from collections.abc import Callable

import numpy as np

from bench.frames import SerialBatch
from bench.transport.serial_link import SerialLink

__all__ = ["SerialReader"]

_POLL_S = 0.05
_READ_MAX = 1 << 16


class SerialReader:
    """A thread draining ``link``; ``clock()`` (bench time, ns) stamps each chunk read.

    ``bytes_read`` counts every byte read; ``error`` holds the exception that stopped the
    thread (the link went away), if any.
    """

    def __init__(self, link: SerialLink, clock: Callable[[], int], *, name: str = "", max_pending: int = 16 << 20):
        self.link = link
        self.clock = clock
        self.max_pending = max_pending
        self.bytes_read = 0
        self.error: Exception | None = None
        self._chunks: list[tuple[int, bytes]] = []
        self._pending = 0
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._closed = False
        self._wake_r, self._wake_w = os.pipe()
        self._thread = threading.Thread(target=self._loop, name=f"serial-reader-{name or link.config.port}",
                                        daemon=True)
        self._thread.start()

    @property
    def pending(self) -> int:
        """Bytes read and not yet taken (cheap: no lock)."""
        return self._pending

    def _keep(self, data: bytes) -> None:
        t = int(self.clock())
        with self._cond:
            self._chunks.append((t, data))
            self._pending += len(data)
            self.bytes_read += len(data)

    def _loop(self) -> None:
        fd = self.link.fileno()
        wake = select.poll()
        wake.register(self._wake_r, select.POLLIN)
        poller = select.poll()
        poller.register(self._wake_r, select.POLLIN)
        if fd is not None:
            poller.register(fd, select.POLLIN)
        try:
            while not self._stop.is_set():
                with self._cond:
                    while self._pending >= self.max_pending and not self._stop.is_set():
                        self._cond.wait()
                if fd is None:
                    data = self.link.read(timeout=_POLL_S, max_bytes=_READ_MAX)
                else:
                    ready = {f for f, _ in poller.poll()}
                    if self._wake_r in ready:
                        break
                    data = self.link.read(timeout=0.0, max_bytes=_READ_MAX)
                    if not data:  # readable but nothing to read (a hang-up): do not spin
                        wake.poll(_POLL_S * 1e3)
                if data:
                    self._keep(data)
        except Exception as exc:  # the link failed or was closed under the reader
            self.error = exc

    def take(self) -> SerialBatch:
        """The chunks read since the last call (an empty batch if none)."""
        with self._cond:
            chunks, self._chunks, self._pending = self._chunks, [], 0
            self._cond.notify_all()
        if not chunks:
            return SerialBatch.empty()
        lengths = np.fromiter((len(d) for _, d in chunks), np.int64, len(chunks))
        offsets = np.zeros(len(chunks) + 1, np.int64)
        np.cumsum(lengths, out=offsets[1:])
        return SerialBatch([t for t, _ in chunks], offsets, b"".join(d for _, d in chunks))

    def stop(self) -> None:
        """Ask the thread to stop (returns at once; :meth:`close` waits for it)."""
        if not self._stop.is_set():
            self._stop.set()
            with contextlib.suppress(OSError):
                os.write(self._wake_w, b"x")
        with self._cond:
            self._cond.notify_all()

    def close(self) -> SerialBatch:
        """Stop the thread, read what is still on the line and return every chunk not taken
        yet. Idempotent (later calls return an empty batch)."""
        if self._closed:
            return SerialBatch.empty()
        self._closed = True
        self.stop()
        self._thread.join(timeout=5.0)
        if not self._thread.is_alive():
            for wake in (self._wake_r, self._wake_w):
                os.close(wake)
        if not self._thread.is_alive() and self.error is None and not self.link.closed:
            budget = self.max_pending  # what is left, bounded: a device that never stops talking cannot hold the close
            try:
                while budget > 0 and (data := self.link.read(timeout=0.0, max_bytes=min(_READ_MAX, budget))):
                    self._keep(data)
                    budget -= len(data)
            except Exception as exc:
                self.error = exc
        return self.take()

    def __enter__(self) -> SerialReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
