"""Every process a DUT starts ends with its run: its daemons, its groups, its orphans.

A DUT process is started in a session of its own and its group is ended at shutdown
(:mod:`bench.dut.process`), but a DUT can start processes out of that group: a daemon
(fork, ``setsid``, fork again), a process group of its own, ``nohup cmd &`` in a script
that then exits. :class:`DutProcesses` starts a DUT's first process so that every process
it starts can be found when the run ends, and :meth:`DutProcesses.end` ends those it
finds. How they are found (:attr:`DutProcesses.tracking`):

``cgroup``     (Linux, where the bench can make a cgroup v2 beside its own:
               :mod:`bench.dut.cgroup`) the members of the run's cgroup: born inside, they
               cannot leave it;
``subreaper``  (Linux otherwise) while a DUT of it runs, the bench's process is a child
               subreaper (``prctl(PR_SET_CHILD_SUBREAPER)``), so an orphaned process of
               the DUT is reparented to it rather than to init and stays its descendant:
               the bench's descendants that carry the run's token in their environment
               (:data:`TOKEN_ENV`, given to the DUT's first process and inherited);
``token``      (no subreaper could be set) as ``subreaper``, but an orphan goes to init: a
               token holder that no longer descends from the bench is named, not killed;
``none``       (no ``/proc``: not Linux) only the DUT's process group is ended.

A process with no or another token -- another run's DUT, or whatever else the process
hosting the bench runs (pytest, a campaign worker, a Dask worker's tasks in other
threads) -- is never signalled, and every process is signalled through a pidfd opened
before it is checked, so a process id reused meanwhile is never hit.

What is found gets SIGTERM, the grace (the DUT's shutdown timeout), then SIGKILL
(``cgroup.kill`` in a cgroup: a process forking meanwhile is killed too); the bench reaps
those that became its children, and each is returned (:class:`LeftRunning`: pid, command
line, how it ended) for the run's notes.

What a subreaper does to the process hosting the bench: while a DUT of it runs, every
orphan of any of its descendants is reparented to it, its other work's too. The bench
reaps only processes it found with its run's token and their zombie children -- it never
waits for "any child", which would steal another's exit status -- and turns the subreaper
off when its last DUT has ended (unless the host was one before). An orphan that exits by
itself while a DUT runs thus stays a zombie of the host until the host exits (a zombie has
no environment to tell whose it is); it holds a process-table entry, nothing else. Where
the bench makes a cgroup it is not made a subreaper at all.
"""

from __future__ import annotations

import ctypes
import errno
import os
import shutil
import signal
import subprocess
import threading
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.dut.cgroup import RunCgroup
from bench.dut.proctable import (
    Proc,
    Stat,
    descendants,
    descends,
    has_token,
    processes,
    stat,
    wait_gone,
    wait_group_gone,
)

__all__ = ["DutProcesses", "LeftRunning", "TOKEN_ENV", "subreaper_state", "wait_group_gone"]

#: The environment variable that carries a run's token to every process of its DUT.
TOKEN_ENV = "BENCH_DUT_RUN"

_PR_SET_CHILD_SUBREAPER = 36
_PR_GET_CHILD_SUBREAPER = 37
_HANG_S = 5.0  # a hang guard on a SIGKILLed process to disappear
_ROUNDS = 10  # kill rounds at most (a process forking as fast as it is killed)
_SH = "/bin/sh"
#: what the DUT's first process runs until it is in the cgroup: a line read (none: the
#: bench failed meanwhile, and nothing is run), then the DUT, on /dev/null
_TRAMPOLINE = 'read -r _ || exit 125; exec "$@" </dev/null'


@dataclass(frozen=True)
class LeftRunning:
    """A process of a DUT found running after the DUT's shutdown: its id, command line
    (``/proc/PID/cmdline``, arguments joined by spaces, cut at 300 characters) and how
    it ended (``ended on SIGTERM``, ``killed (SIGKILL) ...``, or ``not killed: ...``)."""

    pid: int
    command: str
    ended: str

    def as_dict(self) -> dict[str, Any]:
        return {"pid": self.pid, "command": self.command, "ended": self.ended}


# ----------------------------------------------------------------------------- subreaper
class _Subreaper:
    """The process's subreaper attribute, held while any run of it needs it."""

    lock = threading.Lock()
    users = 0
    owner = 0  # the process the count belongs to (a forked child starts at none)
    was = False  # the host was a subreaper before the first user


def _prctl(option: int, arg: Any) -> int:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(ctypes.c_int(option), arg, ctypes.c_ulong(0), ctypes.c_ulong(0), ctypes.c_ulong(0)))
    except (OSError, AttributeError):  # no libc prctl: not Linux
        return -1


def subreaper_state() -> bool | None:
    """Whether this process is a child subreaper (None: cannot tell, not Linux)."""
    value = ctypes.c_int(0)
    if _prctl(_PR_GET_CHILD_SUBREAPER, ctypes.byref(value)) != 0:
        return None
    return bool(value.value)


def _acquire_subreaper() -> bool:
    """Make this process a child subreaper (counted); whether it is one."""
    with _Subreaper.lock:
        if _Subreaper.owner != os.getpid():
            _Subreaper.owner, _Subreaper.users = os.getpid(), 0
        if _Subreaper.users == 0:
            state = subreaper_state()
            if state is None:
                return False
            _Subreaper.was = state
            if not state and _prctl(_PR_SET_CHILD_SUBREAPER, ctypes.c_ulong(1)) != 0:
                return False
        _Subreaper.users += 1
        return True


def _release_subreaper() -> None:
    with _Subreaper.lock:
        if _Subreaper.owner != os.getpid() or _Subreaper.users == 0:
            return
        _Subreaper.users -= 1
        if _Subreaper.users == 0 and not _Subreaper.was:
            _prctl(_PR_SET_CHILD_SUBREAPER, ctypes.c_ulong(0))


def _check_executable(name: str, cwd: Any, env: dict[str, str]) -> None:
    """Raise the :class:`OSError` Popen would raise when ``name`` cannot be executed (the
    DUT is started through a shell that would only exit 127)."""
    if os.sep in name:
        path = Path(name) if os.path.isabs(name) or cwd is None else Path(cwd) / name
        if not path.exists():
            raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), name)
        if path.is_dir() or not os.access(path, os.X_OK):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), name)
    elif shutil.which(name, path=env.get("PATH", os.defpath)) is None:
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), name)


# ------------------------------------------------------------------------------- runs
class DutProcesses:
    """The processes of one run's DUT: :meth:`popen` starts its first one, :meth:`end`
    ends every one left (idempotent; also what releases the cgroup or the subreaper).

    ``cgroup``: try a cgroup first (False: the subreaper and the token only).
    """

    def __init__(self, *, cgroup: bool = True):
        self.token = uuid.uuid4().hex
        #: how the DUT's processes are found (module docstring); set by :meth:`popen`
        self.tracking = "none"
        self._cgroup = RunCgroup.create(self.token) if cgroup else None
        self._subreaper = False
        self._session: int | None = None  # the DUT's own session (start_new_session)
        self._zombies: dict[int, Proc] = {}
        self._left: list[LeftRunning] | None = None

    @property
    def env(self) -> dict[str, str]:
        """The environment variable every process of the DUT inherits."""
        return {TOKEN_ENV: self.token}

    def popen(self, argv: Sequence[str], **kwargs: Any) -> subprocess.Popen:
        """``subprocess.Popen(argv, **kwargs)`` with this run's token in its environment
        (``env``, default this process's) and its standard input ``/dev/null`` (``stdin``
        must be :data:`subprocess.DEVNULL`), inside the run's cgroup where there is one,
        else with this process a subreaper while the run lasts.

        In a cgroup the process starts as ``/bin/sh`` waiting for a line on its standard
        input; it is moved into the cgroup, then told to go on, and replaces itself with
        ``argv`` (``exec``: the same process id): the DUT runs nothing outside. A missing
        or non-executable program raises :class:`OSError` here, as Popen does."""
        if kwargs.get("stdin", subprocess.DEVNULL) != subprocess.DEVNULL:
            raise ValueError("a DUT's standard input is /dev/null")
        kwargs["stdin"] = subprocess.DEVNULL
        env = kwargs["env"] = {**(os.environ if kwargs.get("env") is None else kwargs["env"]), **self.env}
        p: subprocess.Popen | None = None
        if self._cgroup is not None and os.access(_SH, os.X_OK):
            _check_executable(argv[0], kwargs.get("cwd"), env)
            p = subprocess.Popen([_SH, "-c", _TRAMPOLINE, "bench-dut", *argv], **{**kwargs, "stdin": subprocess.PIPE})
            try:
                if self._cgroup.add(p.pid):
                    self.tracking = "cgroup"
                else:  # the kernel refused it the cgroup: without (the DUT is not running yet)
                    self._cgroup.remove(0.0)
                    self._cgroup = None
                    self._start_subreaper()
                assert p.stdin is not None
                p.stdin.write(b"go\n")
                p.stdin.close()
            except BaseException:
                p.kill()
                p.wait()
                raise
        else:
            if self._cgroup is not None:
                self._cgroup.remove(0.0)
                self._cgroup = None
            self._start_subreaper()
            p = subprocess.Popen(list(argv), **kwargs)
        if kwargs.get("start_new_session"):
            self._session = p.pid
        return p

    def _start_subreaper(self) -> None:
        if Path("/proc/self/stat").exists():
            self._subreaper = _acquire_subreaper()
            self.tracking = "subreaper" if self._subreaper else "token"

    # ----------------------------------------------------------------------- the end
    def end(self, grace_s: float) -> list[LeftRunning]:
        """End every process of the DUT still running: SIGTERM, at most ``grace_s`` for
        them to exit, SIGKILL; reap the adopted ones; release the cgroup or the
        subreaper. Call it once the DUT's first process has been reaped (and, if its group
        was killed, the group is gone: :func:`wait_group_gone`). Returns what was found,
        in the order found; an interrupt while waiting still kills them."""
        if self._left is not None:
            return self._left
        self._left = []
        found: dict[int, tuple[Proc, str | None]] = {}
        looked = False
        try:
            if self.tracking != "none":
                live, foreign = self._find(found)
                for p in foreign:
                    self._left.append(LeftRunning(p.pid, p.command, "not killed: no longer a descendant of the bench"))
                    p.close()
                for p in live:
                    found[p.pid] = (p, None)
                    p.signal(signal.SIGTERM)
                looked = True
                wait_gone(live, grace_s)
                for p in live:
                    ended = "ended on SIGTERM" if p.gone() else f"killed (SIGKILL) {grace_s:g} s after SIGTERM"
                    found[p.pid] = (p, ended)
        finally:
            try:
                if self.tracking != "none" and (found or not looked or self._populated()):
                    self._kill_all(found)
                for z in self._zombies.values():  # zombie children of what ended, adopted now
                    z.reap()
            finally:
                for pid, (p, ended) in found.items():
                    self._left.append(LeftRunning(pid, p.command, ended or "killed (SIGKILL)"))
                    p.close()
                for z in self._zombies.values():
                    z.close()
                self._zombies = {}
                self._release()
        return self._left

    def _populated(self) -> bool:
        return self._cgroup is not None and self._cgroup.populated()

    def _kill_all(self, found: dict[int, tuple[Proc, str | None]]) -> None:
        """SIGKILL what is left and whatever is found meanwhile, then reap it."""
        for _ in range(_ROUNDS):
            if self._cgroup is not None:
                self._cgroup.kill()
            for p, _ended in found.values():
                if not p.gone():
                    p.signal(signal.SIGKILL)
            more, foreign = self._find(found)
            for p in foreign:
                p.close()
            for p in more:
                p.signal(signal.SIGKILL)
                found[p.pid] = (p, "killed (SIGKILL): started during the shutdown")
            wait_gone([p for p, _ in found.values()], _HANG_S)
            if not more:
                break
        for p, _ended in found.values():
            p.reap()

    def _find(self, exclude: dict[int, Any]) -> tuple[list[Proc], list[Proc]]:
        """``(live processes of the DUT, token holders out of the bench's descent)``,
        but those in ``exclude``; notes the zombies to reap."""
        live: list[Proc] = []
        if self._cgroup is not None:
            for pid in self._cgroup.pids():
                if pid not in exclude and (p := Proc.open(pid)) is not None:
                    if self._cgroup.holds(pid) and not p.gone():  # through the pidfd's process
                        live.append(p)
                    else:
                        p.close()
            return live, []
        foreign: list[Proc] = []
        me, needle = os.getpid(), f"{TOKEN_ENV}={self.token}".encode()
        table = processes()
        # a subreaper keeps the DUT's processes among its descendants: only their
        # environments are read (elsewhere every process's: a token holder may be anywhere)
        candidates = descendants(table, me) if self._subreaper else set(table)
        ours = {pid for pid, st in table.items() if pid != me and st.state not in ("Z", "X")
                and (self._in_session(st) or (pid in candidates and has_token(pid, needle)))}
        for pid in sorted(ours - exclude.keys()):
            if (p := Proc.open(pid)) is None:
                continue
            st = stat(pid)  # checked again, now that the pidfd holds the process
            if st is None or st.state in ("Z", "X") or pid == self._session:
                p.close()
            elif self._in_session(st) or (has_token(pid, needle) and descends(pid, me)):
                live.append(p)
            elif has_token(pid, needle):
                foreign.append(p)
            else:
                p.close()
        for pid, st in table.items():  # zombies that are (or will be) adopted
            if (st.state == "Z" and pid not in self._zombies and pid != self._session
                    and (st.ppid in ours or (st.ppid == me and self._in_session(st)))
                    and (z := Proc.open(pid)) is not None):
                self._zombies[pid] = z
        return live, foreign

    def _in_session(self, st: Stat) -> bool:
        """In the DUT's own session or process group (its id cannot be reused while a
        member lives, and no other process can join it)."""
        return self._session is not None and self._session in (st.session, st.pgrp)

    def _release(self) -> None:
        if self._cgroup is not None:
            self._cgroup.remove()
            self._cgroup = None
        if self._subreaper:
            self._subreaper = False
            _release_subreaper()
