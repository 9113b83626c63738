"""A cgroup (v2) of one run's DUT processes, where the bench may make one (Linux).

The bench's own cgroup is read from ``/proc/self/cgroup`` (the ``0::`` line) and found
under the cgroup2 mount of ``/proc/self/mountinfo``; the run's cgroup is a child of it,
``bench-dut-<bench pid>-<token>``. The DUT's first process enters it between ``fork``
and ``exec`` (it writes ``0``, "myself", to ``cgroup.procs``), so every process it ever
starts is born inside, and no unprivileged process can leave it: its members are the
DUT's processes, whatever sessions or groups they made. ``cgroup.kill`` (Linux 5.14)
ends them all at once.

There is none where cgroup2 is not mounted here (cgroup v1 hosts; a network namespace of
``ip netns exec``, which mounts a fresh ``/sys``), where the bench's cgroup is not
writable (no root, no delegated subtree), where ``cgroup.kill`` is missing, or where a
process cannot be moved into the child (the kernel says no): :meth:`RunCgroup.create`
returns None, or :meth:`RunCgroup.add` says no and the caller goes on without it.
"""

from __future__ import annotations

import contextlib
import os
import re
import time
from pathlib import Path

__all__ = ["RunCgroup", "PREFIX"]

#: Name prefix of the cgroups the bench makes.
PREFIX = "bench-dut-"


def _unescape(field: str) -> str:
    """A mountinfo field with its octal escapes (``\\040`` for a space) decoded."""
    return re.sub(r"\\([0-7]{3})", lambda m: chr(int(m.group(1), 8)), field)


def own_cgroup() -> tuple[Path, str] | None:
    """``(folder, path in the hierarchy)`` of this process's cgroup v2, if mounted here."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
        mounts = Path("/proc/self/mountinfo").read_text().splitlines()
    except OSError:
        return None
    own = next((ln[3:] for ln in lines if ln.startswith("0::")), None)
    if own is None or not own.startswith("/"):
        return None
    for line in mounts:
        left, _, right = line.partition(" - ")
        fields = left.split()
        if not right.startswith("cgroup2 ") or len(fields) < 5:
            continue
        root, mount = _unescape(fields[3]), _unescape(fields[4])
        if root == "/":
            rel = own
        elif own == root or own.startswith(root + "/"):
            rel = own[len(root):] or "/"
        else:
            continue
        folder = Path(mount) / rel.lstrip("/")
        if folder.is_dir():
            return folder, own
    return None


class RunCgroup:
    """One run's cgroup: made by :meth:`create`, the DUT's first process put in it
    (:meth:`add`), its members listed (:meth:`pids`), killed (:meth:`kill`) and removed
    (:meth:`remove`)."""

    def __init__(self, folder: Path, path: str):
        self.folder = folder
        #: its path in the hierarchy, as ``/proc/PID/cgroup`` shows it
        self.path = path
        self._fd: int | None = None

    @classmethod
    def create(cls, token: str) -> RunCgroup | None:
        """A new cgroup for a run beside the bench's own, or None where none can be made."""
        own = own_cgroup()
        if own is None:
            return None
        base, path = own
        _remove_stale(base)
        name = f"{PREFIX}{os.getpid()}-{token[:12]}"
        try:
            (base / name).mkdir()
        except OSError:
            return None
        cg = cls(base / name, path.rstrip("/") + "/" + name)
        try:
            if not (cg.folder / "cgroup.kill").exists():  # Linux < 5.14
                raise OSError("no cgroup.kill")
            cg._fd = os.open(cg.folder / "cgroup.procs", os.O_WRONLY | os.O_CLOEXEC)
        except OSError:
            cg.remove(0.0)
            return None
        return cg

    def add(self, pid: int) -> bool:
        """Move process ``pid`` into it (once: the file is closed then); whether it is in."""
        if self._fd is None:
            return False
        try:
            os.write(self._fd, str(pid).encode())
        except OSError:  # the kernel says no (delegation, a threaded or domain-invalid cgroup)
            return False
        finally:
            self._close()
        return self.holds(pid)

    def _close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def holds(self, pid: int) -> bool:
        """Whether process ``pid`` is in this cgroup (a zombie too)."""
        try:
            lines = Path(f"/proc/{pid}/cgroup").read_text().splitlines()
        except OSError:
            return False
        return f"0::{self.path}" in lines

    def pids(self) -> list[int]:
        """Its live member processes."""
        try:
            return [int(x) for x in (self.folder / "cgroup.procs").read_text().split()]
        except (OSError, ValueError):
            return []

    def populated(self) -> bool:
        """Whether a live process is in it."""
        try:
            text = (self.folder / "cgroup.events").read_text()
        except OSError:
            return False
        return "populated 1" in text.splitlines()

    def kill(self) -> None:
        """SIGKILL every member, including one forking meanwhile (``cgroup.kill``)."""
        with contextlib.suppress(OSError):
            (self.folder / "cgroup.kill").write_text("1")

    def remove(self, timeout_s: float = 5.0) -> bool:
        """Remove it once no live process is in it (waiting at most ``timeout_s``, a hang
        guard: killed processes leave within milliseconds); whether it is gone."""
        self._close()
        deadline = time.monotonic() + timeout_s
        pause = 0.001
        while True:
            try:
                self.folder.rmdir()
                return True
            except FileNotFoundError:
                return True
            except OSError:
                if time.monotonic() >= deadline:
                    return False
            time.sleep(pause)
            pause = min(2 * pause, 0.05)


def _remove_stale(base: Path) -> None:
    """Remove the empty cgroups left by benches that are gone (killed before their end)."""
    with contextlib.suppress(OSError):
        for d in base.glob(PREFIX + "*"):
            try:
                owner = int(d.name[len(PREFIX):].split("-")[0])
            except ValueError:
                continue
            if owner == os.getpid() or _alive(owner):
                continue
            with contextlib.suppress(OSError):
                d.rmdir()  # fails while a process is still in it


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
