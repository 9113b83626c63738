"""Processes as ``/proc`` shows them (Linux), for :mod:`bench.dut.reaper`: their parent,
state, group and session, descendants, environments and command lines, and a handle
(:class:`Proc`) that signals, waits for and reaps one process through a pidfd where the
kernel has them (Linux 5.3), so that its id can be reused meanwhile without a stranger
being hit.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Stat", "Proc", "stat", "processes", "descendants", "has_token", "descends", "wait_group_gone",
           "wait_gone"]

_MAX_COMMAND = 300


@dataclass(frozen=True)
class Stat:
    """A process's parent id, state letter (``Z``: a zombie), process group and session."""

    ppid: int
    state: str
    pgrp: int
    session: int


def stat(pid: int) -> Stat | None:
    """Parent, state letter, process group and session of a process; None if there is none."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    f = text[text.rindex(")") + 2 :].split()
    return Stat(int(f[1]), f[0], int(f[2]), int(f[3]))


def processes() -> dict[int, Stat]:
    """Every process visible."""
    out = {}
    with contextlib.suppress(OSError):
        for entry in os.listdir("/proc"):
            if entry.isdigit() and (st := stat(int(entry))) is not None:
                out[int(entry)] = st
    return out


def wait_group_gone(pgid: int, timeout_s: float = 5.0) -> bool:
    """Wait until no live process is left in process group ``pgid`` (one just killed:
    its members take a moment to exit), at most ``timeout_s`` (a hang guard); whether
    none is. The group's id cannot be reused while a member exists."""
    deadline = time.monotonic() + timeout_s
    pause = 0.001
    while any(st.pgrp == pgid and st.state not in ("Z", "X") for st in processes().values()):
        if time.monotonic() >= deadline:
            return False
        time.sleep(pause)
        pause = min(2 * pause, 0.05)
    return True


def descendants(table: dict[int, Stat], ancestor: int) -> set[int]:
    """The processes of ``table`` that descend from ``ancestor``."""
    children: dict[int, list[int]] = {}
    for pid, st in table.items():
        children.setdefault(st.ppid, []).append(pid)
    out: set[int] = set()
    todo = [ancestor]
    while todo:
        for c in children.get(todo.pop(), ()):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def has_token(pid: int, needle: bytes) -> bool:
    try:
        return needle in Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    except OSError:  # gone, a zombie, or another user's
        return False


def descends(pid: int, ancestor: int) -> bool:
    """Whether ``pid`` descends from ``ancestor`` (read now, up the parent chain)."""
    seen = 0
    while pid > 1 and seen < 100_000:
        st = stat(pid)
        if st is None:
            return False
        pid = st.ppid
        if pid == ancestor:
            return True
        seen += 1
    return False


def _command(pid: int) -> str:
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        raw = b""
    text = raw.rstrip(b"\0").replace(b"\0", b" ").decode("utf-8", "replace")
    if not text:
        with contextlib.suppress(OSError):
            stat = Path(f"/proc/{pid}/stat").read_text()
            text = stat[stat.index("(") : stat.rindex(")") + 1]
    return text if len(text) <= _MAX_COMMAND else text[: _MAX_COMMAND - 1] + "…"


class Proc:
    """A process found: its pidfd where the kernel has them (so its id can be reused
    without it being hit), its command line."""

    def __init__(self, pid: int, fd: int | None):
        self.pid = pid
        self.fd = fd
        self.command = _command(pid)

    @classmethod
    def open(cls, pid: int) -> Proc | None:
        """The process, None if it is gone."""
        try:
            return cls(pid, os.pidfd_open(pid))
        except ProcessLookupError:
            return None
        except (OSError, AttributeError):  # no pidfds (Linux < 5.3): by id
            return cls(pid, None) if stat(pid) is not None else None

    def signal(self, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            if self.fd is not None:
                signal.pidfd_send_signal(self.fd, sig)
            else:
                os.kill(self.pid, sig)

    def gone(self) -> bool:
        """Whether it has exited (a zombie is gone)."""
        if self.fd is not None:
            p = select.poll()
            p.register(self.fd, select.POLLIN)
            return bool(p.poll(0))
        st = stat(self.pid)
        return st is None or st.state in ("Z", "X")

    def reap(self) -> None:
        """Reap it if it is a zombie child of this process (an orphan it adopted)."""
        with contextlib.suppress(ChildProcessError, OSError):
            if self.fd is not None and hasattr(os, "P_PIDFD"):
                os.waitid(os.P_PIDFD, self.fd, os.WEXITED | os.WNOHANG)
            elif (st := stat(self.pid)) is not None and st.ppid == os.getpid() and st.state == "Z":
                os.waitpid(self.pid, os.WNOHANG)  # a zombie child keeps its id until reaped

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def wait_gone(procs: Sequence[Proc], timeout_s: float) -> None:
    """Wait until every one of ``procs`` has exited, at most ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    pause = 0.001
    while not all(p.gone() for p in procs):
        left = deadline - time.monotonic()
        if left <= 0:
            return
        time.sleep(min(pause, left))
        pause = min(2 * pause, 0.05)
