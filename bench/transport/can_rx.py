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
    with an emission loop only for the microseconds a frame takes. It stops reading once
    ``max_pending`` frames wait to be taken (memory bounded; a flood is the caller's to
    judge from :attr:`CanLink.peer_frames`). While it runs, nothing else may receive on
    the link. :attr:`error` holds what stopped it (the link failed), if anything.
    """

    def __init__(self, link: CanLink, *, max_pending: int = 4 << 20, poll_s: float = 0.05, name: str = "can-rx"):
        self.link = link
        self.max_pending = max_pending
        self.poll_s = poll_s
        self.error: Exception | None = None
        self.full = False
        self._frames: list[CanFrame] = []
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
                got = link._collect(self.poll_s, 4096)
                if got:
                    with lock:
                        frames.extend(got)
        except Exception as exc:  # the link failed or was closed under the thread
            self.error = exc

    def take(self) -> CanBatch:
        """The frames received since the last call, in arrival order (an empty batch if none)."""
        with self._lock:
            got = self._frames[:]
            del self._frames[:]
        self.full = False
        return CanBatch.from_frames(got) if got else CanBatch.empty()

    def stop(self) -> CanBatch:
        """Stop the thread (within ``poll_s``) and return what it still holds."""
        self._stop.set()
        self._thread.join()
        return self.take()
