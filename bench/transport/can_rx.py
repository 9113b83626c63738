"""Receiving a CAN link's frames in a thread of its own (real-time runs): each frame
stamped when it arrived, whatever the caller is doing."""

from __future__ import annotations

import threading

from bench.frames import CanBatch, CanFrame
from bench.transport.can_link import CanLink

__all__ = ["CanReceiveThread"]


class CanReceiveThread:
    """Receives a link's frames in a thread of its own (real-time runs).

    Each frame is stamped by the link (its ``arrival_clock`` on the kernel's arrival time
    where the link knows it, else its ``clock`` the moment the thread reads it), whatever
    the caller is doing; the caller never waits on it (:meth:`take` hands over what came,
    :attr:`frames_pending` counts it without a lock). The thread waits in the link's
    receive (which releases the interpreter lock) and does nothing else, so it competes
    with an emission loop only for the microseconds a frame takes; where the link can
    (:attr:`CanLink.defers_decoding <bench.transport.can_link.CanLink.defers_decoding>`:
    udp_multicast on Linux) it only reads and stamps the datagrams, which are unpacked
    when they are taken (a few microseconds per frame instead of tens). It stops reading
    once ``max_pending`` items wait to be taken (memory bounded; a flood is the caller's
    to judge from :attr:`arrived`). While it runs, nothing else may receive on the link.
    :attr:`error` holds what stopped it (the link failed), if anything.
    """

    def __init__(self, link: CanLink, *, max_pending: int = 4 << 20, poll_s: float = 0.05, name: str = "can-rx"):
        self.link = link
        self.max_pending = max_pending
        self.poll_s = poll_s
        self.error: Exception | None = None
        self.full = False
        self._raw = 0  # items read, decoded or not (deferred decoding)
        self._frames: list = []
        self._settled: list[CanFrame] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._thread.start()

    @property
    def frames_pending(self) -> int:
        """Frames received and not yet taken."""
        return len(self._frames)

    def _loop(self) -> None:
        link, frames, lock = self.link, self._frames, self._lock
        try:
            while not self._stop.is_set():
                if len(frames) >= self.max_pending:
                    self.full = True
                    self._stop.wait(self.poll_s)
                    continue
                got = link.collect_raw(self.poll_s, 4096)
                if got:
                    with lock:
                        frames.extend(got)
                        self._raw += len(got)
        except Exception as exc:  # the link failed or was closed under the thread
            self.error = exc

    @property
    def arrived(self) -> int:
        """Every frame a peer sent that reached the link so far (remote and error frames
        too; where decoding is deferred, every datagram read, strays included, until
        :meth:`settle`): what a flood limit is checked against."""
        return self._raw if self.link.defers_decoding else self.link.peer_frames

    def settle(self, last: int) -> int:
        """Decode what is pending now, in order, keeping it for :meth:`take` (the link's
        counters then count it); returns how many of the ``last`` items read were a
        peer's frames (data, remote or error frames), the rest being strays: a flood is
        told apart from stray datagrams. Without deferred decoding: ``last``."""
        if not self.link.defers_decoding:
            return last
        with self._lock:
            raw = self._frames[:]
            del self._frames[:]
        k = max(0, len(raw) - last)
        frames = self.link.decode_raw(raw[:k])
        before = self.link.peer_frames
        frames += self.link.decode_raw(raw[k:])
        peers = self.link.peer_frames - before
        with self._lock:
            self._settled.extend(frames)
        return peers

    def take(self) -> CanBatch:
        """The frames received since the last call, in arrival order (an empty batch if none)."""
        with self._lock:
            got = self._frames[:]
            del self._frames[:]
            settled, self._settled = self._settled, []
        self.full = False
        frames = settled + self.link.decode_raw(got)
        return CanBatch.from_frames(frames) if frames else CanBatch.empty()

    def stop(self) -> CanBatch:
        """Stop the thread (within ``poll_s``) and return what it still holds."""
        self._stop.set()
        self._thread.join()
        return self.take()
