"""One campaign at a time in a campaign folder: ``DIR/campaign.lock``.

Two campaigns in one folder would run the same runs twice, each writing the other's
recordings from under it; so :func:`acquire` takes an exclusive ``flock`` on
``DIR/campaign.lock`` for the whole campaign, and writes in it who holds it (JSON: host,
the kernel's boot id, pid, since when, bench version, command line, a heartbeat count).

* **held**: a second campaign is refused at once (:class:`CampaignHeldError`, a
  :class:`~bench.errors.ConfigError`: exit 2), naming the holder's host, pid and start;
* **released**: a campaign that ends, however it ends short of being killed, empties the
  file and unlocks it; an empty file is a free folder;
* **stale**: the kernel drops a ``flock`` when its holder dies, SIGKILL included, so a lock
  file that still names a holder while nobody holds its lock was left by a killed campaign.
  When it names this kernel (same host and boot id) that is certain, and the lock is taken
  over at once, said through ``notice``. When it names another host (a shared file system)
  or this host before a reboot, the free lock proves the holder dead only if the file
  system shares locks between hosts (NFS v4, and v3 with lockd: yes; NFS mounted
  ``nolock``, some FUSE file systems: no). The holder rewrites its lock every
  :data:`BEAT_S` seconds (``beat``); the starter watches the file for :data:`WATCH_S`
  seconds: a beat seen means a live campaign whose host does not share its lock with this
  one (refused, saying so); none means a dead one (taken over, said through ``notice``).

A file system on which ``flock`` fails (``ENOLCK``: NFS v3 without lockd) is treated as one
that does not share locks: only the heartbeat protects the folder there.

:func:`lock_state` tells a reader (``bench campaign-report``) whether a campaign holds
the folder, without keeping any lock.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import fcntl
import json
import os
import shlex
import socket
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench import __version__
from bench.errors import ConfigError

__all__ = ["LOCK_NAME", "BEAT_S", "WATCH_S", "CampaignHeldError", "CampaignLock", "acquire", "lock_state",
           "describe", "this_kernel"]

LOCK_NAME = "campaign.lock"
#: How often the holder rewrites its lock (its heartbeat), in seconds.
BEAT_S = 5.0
#: How long a starter watches a lock that names another host before taking it over.
WATCH_S = 15.0
_RETRY_S = 0.5  # a lock held only for an instant (a reader's probe, a starter writing its name) is tried again


class CampaignHeldError(ConfigError):
    """Another campaign holds the folder; ``holder`` is what its lock file says (None:
    unreadable, or not written yet)."""

    def __init__(self, folder: str | Path, holder: dict[str, Any] | None, why: str = ""):
        self.holder = holder
        super().__init__(
            f"is held by another bench campaign: {describe(holder)}{why}. Two campaigns in one folder would run "
            "the same runs twice: wait for it to end, or use another folder", file=str(folder))


def describe(holder: dict[str, Any] | None) -> str:
    """``pid 123 on host, since 2026-01-01T10:00:00+00:00, bench 1.2, command `bench campaign ...```."""
    if not holder:
        return "one that has not written its name yet"
    text = f"pid {holder.get('pid', '?')} on {holder.get('host', '?')}, since {holder.get('started_utc', '?')}"
    if holder.get("bench_version"):
        text += f", bench {holder['bench_version']}"
    return text + (f", command `{holder['command']}`" if holder.get("command") else "")


def this_kernel() -> dict[str, Any]:
    """This host's name and the running kernel's boot id (None where there is none)."""
    try:
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip() or None
    except OSError:
        boot = None
    return {"host": socket.gethostname(), "boot_id": boot}


def _same_kernel(holder: dict[str, Any]) -> bool:
    me = this_kernel()
    return holder.get("host") == me["host"] and holder.get("boot_id") == me["boot_id"]


def _read(path: Path) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read(65536)
    except OSError:
        return b""


def _parse(raw: bytes) -> dict[str, Any] | None:
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return data if isinstance(data, dict) else None


#: How long an empty or unreadable lock file is read again before it counts as empty or
#: unreadable: a holder on another host that rewrites its file by truncating it first (not
#: the bench's own, which overwrites in place) leaves it empty or half written for an instant.
_SETTLE_S = 0.2


def _holder(path: Path) -> dict[str, Any] | None:
    """The holder a lock file names; None only for a file found empty at every read over
    :data:`_SETTLE_S` (one caught mid-write, empty or half written, is read again)."""
    end = time.monotonic() + _SETTLE_S
    unreadable = False
    while True:
        raw = _read(path)
        if raw.strip():
            if (data := _parse(raw)) is not None:
                return data
            unreadable = True
        if time.monotonic() >= end:
            break
        time.sleep(0.03)
    if unreadable:
        return {"host": "?", "pid": "?", "started_utc": "?", "command": f"unreadable lock file {path}"}
    return None


def _flock(fd: int, mode: int) -> bool | None:
    """True: locked; False: held by another; None: the file system has no locks."""
    try:
        fcntl.flock(fd, mode | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
            return None
        raise


class CampaignLock:
    """The folder's lock while a campaign holds it: ``info`` is what its file says,
    ``took_over`` what it said before, when this campaign took a stale lock over (None
    otherwise). :meth:`release` (or leaving the ``with`` block) empties and unlocks it."""

    def __init__(self, path: Path, fd: int, info: dict[str, Any], took_over: dict[str, Any] | None, beat_s: float):
        self.path, self.info, self.took_over = path, info, took_over
        self._fd: int | None = fd
        self._io = threading.Lock()
        self._stop = threading.Event()
        self._write()
        self._beat = threading.Thread(target=self._beating, args=(beat_s,), name="campaign-lock-beat", daemon=True)
        self._beat.start()

    def _write(self) -> None:
        data = json.dumps(self.info, sort_keys=True).encode("utf-8")
        with self._io:
            if self._fd is None:
                return
            os.pwrite(self._fd, data, 0)
            os.ftruncate(self._fd, len(data))
            os.fsync(self._fd)

    def _beating(self, beat_s: float) -> None:
        while not self._stop.wait(beat_s):
            self.info["beat"] = int(self.info.get("beat", 0)) + 1
            with contextlib.suppress(OSError):  # a full disk: the lock itself still holds on this host
                self._write()

    def release(self) -> None:
        """Empty the lock file and unlock it (idempotent)."""
        self._stop.set()
        if self._beat.is_alive() and self._beat is not threading.current_thread():
            self._beat.join()
        with self._io:
            fd, self._fd = self._fd, None
            if fd is None:
                return
            try:
                with contextlib.suppress(OSError):  # left as it is, the next start takes it over
                    os.ftruncate(fd, 0)
                    os.fsync(fd)
                with contextlib.suppress(OSError):
                    fcntl.flock(fd, fcntl.LOCK_UN)
            finally:
                os.close(fd)

    def __enter__(self) -> CampaignLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def acquire(folder: str | Path, command: str | None = None, *, notice: Callable[[str], None] | None = None,
            beat_s: float = BEAT_S, watch_s: float = WATCH_S) -> CampaignLock:
    """Hold ``folder`` (created if need be) for one campaign, or raise
    :class:`CampaignHeldError` (module docstring). ``notice`` is told of a stale lock taken
    over and of a watch (default: stderr); ``command`` is recorded (default: this
    process's command line)."""
    notice = notice or _stderr
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    try:  # a file this call creates names nobody: no need to wait for a holder's rewrite
        fd, created = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644), True
    except FileExistsError:
        fd, created = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644), False
    try:
        end = time.monotonic() + _RETRY_S
        while (locked := _flock(fd, fcntl.LOCK_EX)) is False and time.monotonic() < end:
            time.sleep(0.02)
        if locked is False:
            raise CampaignHeldError(folder, _holder(path))
        prev = None if created and locked and not _read(path).strip() else _holder(path)
        if prev is not None and not (locked and _same_kernel(prev)):
            # another kernel's campaign (or no locks here): only its heartbeat tells whether it lives
            notice(f"bench campaign: {path} names a campaign this host cannot check ({describe(prev)}) and its "
                   f"lock is free; watching its heartbeat for {watch_s:g} s")
            if _beats(path, watch_s):
                why = ("; its heartbeat goes on while its lock is free here: the file system does not share locks "
                       "between hosts (an NFS mount with nolock?)" if locked else
                       "; its heartbeat goes on (this file system has no locks)")
                raise CampaignHeldError(folder, prev, why)
        info = {**this_kernel(), "pid": os.getpid(), "bench_version": __version__, "beat": 0,
                "started_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "command": command if command is not None else shlex.join(sys.argv)}
        held = CampaignLock(path, fd, info, prev, beat_s)
    except BaseException:
        os.close(fd)  # unlocks
        raise
    if prev is not None:
        notice(f"bench campaign: {folder} was held by a campaign that ended without releasing it "
               f"({describe(prev)}): killed, or its machine lost; its lock is taken over")
    return held


def _beats(path: Path, watch_s: float) -> bool:
    """Whether ``path`` changes within ``watch_s`` seconds (a holder's heartbeat)."""
    first = _read(path)
    end = time.monotonic() + watch_s
    while time.monotonic() < end:
        time.sleep(min(0.25, max(0.0, end - time.monotonic())))
        if _read(path) != first:
            return True
    return False


def lock_state(folder: str | Path) -> tuple[str, dict[str, Any] | None]:
    """``("held", holder)`` while a campaign holds ``folder`` (on this host, or on another
    that shares its locks); ``("stale", holder)`` for a lock left by a campaign that did
    not release it (killed, or on a host whose locks this one cannot see: it may be
    running there); ``("free", None)`` otherwise. Holds no lock on return."""
    path = Path(folder) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return "free", None
    try:
        locked = _flock(fd, fcntl.LOCK_SH)
        if locked:
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
    holder = _holder(path)
    if locked is False:
        return "held", holder
    return ("stale", holder) if holder is not None else ("free", None)
