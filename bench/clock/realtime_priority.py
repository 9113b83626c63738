"""Real-time scheduling of the emission loop (Linux ``SCHED_FIFO``), when permitted.

A real-time run spends most of its time asleep and wakes for every emission; under a
normal time-sharing policy any other busy process on the same core delays that wake-up
by milliseconds, and a full garbage collection of the interpreter stops it for tens of
milliseconds. So for the emission loop the garbage collector is off (the loop allocates
little, and the objects made before it are frozen out of later collections), and with
``SCHED_FIFO`` the bench preempts ordinary processes, as a HIL target's real-time task
would. The policy needs root or ``CAP_SYS_NICE`` (or an ``rtprio`` limit); without them
the run goes on under the normal policy and says so in its ``realtime_scheduling``
metadata. ``BENCH_RT_PRIORITY=0`` turns it off.

Every other thread of the process gets the same policy (threads started later inherit
it): the emission loop needs the interpreter lock after each sleep, and a helper thread
under the normal policy (a serial reader, the DUT's output readers) that holds the lock
when an ordinary process preempts it would stop the loop for that process's time slice.
"""

from __future__ import annotations

import contextlib
import gc
import os
import threading

__all__ = ["acquire", "release", "DEFAULT_PRIORITY"]

DEFAULT_PRIORITY = 50
_saved: tuple[int, int] | None = None
_saved_threads: dict[int, tuple[int, int]] = {}
_gc_was_enabled: bool | None = None


def acquire(priority: int | None = None) -> dict[str, str]:
    """Switch this thread to ``SCHED_FIFO``; returns what was granted (for the record)."""
    global _saved, _gc_was_enabled
    _gc_was_enabled = gc.isenabled()
    gc.collect()
    gc.freeze()
    gc.disable()
    want = int(os.environ.get("BENCH_RT_PRIORITY", DEFAULT_PRIORITY if priority is None else priority))
    if want <= 0:
        return {"policy": "normal", "reason": "BENCH_RT_PRIORITY=0"}
    if not hasattr(os, "sched_setscheduler"):
        return {"policy": "normal", "reason": "no SCHED_FIFO on this platform"}
    try:
        if _saved is None:
            _saved = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(want))
    except (PermissionError, OSError) as exc:
        _saved = None
        return {"policy": "normal", "reason": f"SCHED_FIFO not permitted: {exc}"}
    others = _other_threads()
    for tid in others:
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            saved = (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority)
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(want))
            _saved_threads[tid] = saved
    return {"policy": "SCHED_FIFO", "priority": str(want), "threads": str(1 + len(_saved_threads))}


def _other_threads() -> list[int]:
    """Kernel ids of this process's other threads."""
    me = threading.get_native_id()
    return [t.native_id for t in threading.enumerate() if t.native_id is not None and t.native_id != me]


def release() -> None:
    """Back to the policy in force before :func:`acquire` (idempotent)."""
    global _saved, _gc_was_enabled
    if _gc_was_enabled is not None:
        gc.unfreeze()
        if _gc_was_enabled:
            gc.enable()
        _gc_was_enabled = None
    for tid, (policy, prio) in list(_saved_threads.items()):
        with contextlib.suppress(OSError):  # ended meanwhile
            os.sched_setscheduler(tid, policy, os.sched_param(prio))
    _saved_threads.clear()
    if _saved is None:
        return
    policy, prio = _saved
    _saved = None
    with contextlib.suppress(OSError):
        os.sched_setscheduler(0, policy, os.sched_param(prio))
