"""A step watchdog for in-process estimators: a step that runs past its timeout is stopped.

An external DUT that hangs is found by the lockstep timeout (no DUT_READY within ``[clock]
timeout``). An in-process estimator runs in the bench's own thread, so a step that never
returns would hang the bench. :class:`StepWatchdog` watches the steps from a thread of its
own and, when one has run longer than the timeout, raises :class:`StepTimeout` in the
thread running the step:

* in the main thread, by a signal (``SIGALRM``, sent with ``pthread_kill``, its handler
  installed while the watchdog is open and the previous one put back after): a blocking
  call in the step (``time.sleep``, a ``select``, a lock) is interrupted too;
* in another thread (a Dask worker runs tasks in threads), by an asynchronous exception
  (``PyThreadState_SetAsyncExc``), raised at the thread's next Python instruction: a step
  blocked in a system call is stopped when that call returns.

Either way a step busy inside native code (a numba kernel, a C extension) is stopped only
when it comes back to Python: an estimator that can hang there is run as an external DUT
(``python -m bench.dut.harness``), whose process the bench can end.

:class:`StepTimeout` derives from :class:`BaseException`, so an estimator's ``except
Exception`` does not swallow it. Only a step that is still running when the watchdog fires
is stopped: a step that returns first is left alone (the watchdog checks under a lock,
and a pending asynchronous exception is withdrawn when the step ends).
"""

from __future__ import annotations

import ctypes
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType, TracebackType
from typing import Any

__all__ = ["StepWatchdog", "StepTimeout"]

_SIGNAL = signal.SIGALRM


class StepTimeout(BaseException):
    """Raised in the thread of a step that ran past the watchdog's timeout."""


_async_exc = ctypes.pythonapi.PyThreadState_SetAsyncExc
_async_exc.argtypes = (ctypes.c_ulong, ctypes.c_void_p)  # an exception class, or NULL to withdraw one
_async_exc.restype = ctypes.c_int


def _set_async_exc(ident: int, exc: type[BaseException] | None) -> None:
    """Raise ``exc`` in the thread ``ident`` at its next Python instruction (None: withdraw
    a pending one). CPython keeps its own reference to the class."""
    _async_exc(ident, id(exc) if exc is not None else None)


class StepWatchdog:
    """Stops a step that runs longer than ``timeout_s`` (module docstring).

    Use as a context manager around the run, and :meth:`step` around each call::

        with StepWatchdog(5.0) as dog:
            for inputs in steps:
                with dog.step():
                    out = estimator.step(inputs)
    """

    def __init__(self, timeout_s: float):
        if not timeout_s > 0:
            raise ValueError(f"the step timeout must be positive, found {timeout_s!r}")
        self.timeout_s = float(timeout_s)
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = False
        self._armed: int | None = None  # the token of the step running, if any
        self._ident = 0  # the thread the steps run in (the one that opened the watchdog)
        self._fired: int | None = None  # the token of the step stopped
        self._token = 0
        self._thread: threading.Thread | None = None
        self._old_handler: Any = None
        self._main = False

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self) -> StepWatchdog:
        self._main = threading.current_thread() is threading.main_thread()
        self._ident = threading.get_ident()
        if self._main:
            self._old_handler = signal.signal(_SIGNAL, self._on_signal)
        self._thread = threading.Thread(target=self._watch, name="bench-step-watchdog", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        """Stop watching (idempotent); the previous signal handler is put back."""
        self._stop = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._main and self._old_handler is not None:
            signal.signal(_SIGNAL, self._old_handler)
            self._old_handler = None

    # ------------------------------------------------------------------ steps
    def arm(self) -> int:
        """A step begins (in the thread that opened the watchdog); returns its token for
        :meth:`disarm`. Cheap: the watchdog times a token it sees armed from when it first
        saw it, so a step costs a few attribute writes, not a clock read."""
        token = self._token = self._token + 1
        self._armed = token
        return token

    def disarm(self, token: int) -> None:
        """The step ``token`` has ended; raise :class:`StepTimeout` if it ran past the
        timeout (it came back just as the watchdog fired).

        No lock on the way of a step in time: the step clears ``_armed`` then reads
        ``_fired``, the watchdog sets ``_fired`` then reads ``_armed`` (under the GIL one of
        them sees the other's write), so the watchdog never raises in a step it has not
        marked; a marked one waits for the watchdog's critical section to end, then withdraws
        what it may have sent."""
        self._armed = None
        if self._fired == token:
            with self._lock:
                if not self._main:
                    _set_async_exc(threading.get_ident(), None)  # withdrawn if not raised yet
            raise StepTimeout(f"the step ran longer than {self.timeout_s:g} s")

    @contextmanager
    def step(self) -> Iterator[None]:
        """:meth:`arm`, the code inside, :meth:`disarm`: :class:`StepTimeout` is raised in
        it past the timeout, or as it ends."""
        token = self.arm()
        try:
            yield
        finally:
            self.disarm(token)

    @property
    def fired(self) -> bool:
        """Whether the watchdog has stopped a step."""
        return self._fired is not None

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        armed = self._armed
        if armed is not None and self._fired == armed:
            raise StepTimeout(f"the step ran longer than {self.timeout_s:g} s")

    def _watch(self) -> None:
        period = min(0.5, self.timeout_s / 4)
        seen, since = None, 0.0  # the token armed at the last look, and when it was first seen
        while not self._stop:
            self._wake.wait(period)
            token = self._armed
            now = time.monotonic()
            if token is None or token != seen:
                seen, since = token, now
                continue
            if now - since <= self.timeout_s:
                continue
            with self._lock:
                first = self._fired != token
                self._fired = token  # marked before looking again (disarm's docstring)
                if self._armed != token:
                    continue
                if first and not self._main:
                    _set_async_exc(self._ident, StepTimeout)
                if self._main:  # (again each period: an estimator may swallow it once)
                    signal.pthread_kill(self._ident, _SIGNAL)
