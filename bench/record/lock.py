"""One writer per recording: the output file is locked while it is written.

:func:`claim` opens a recording for writing under an exclusive ``flock`` on the file
itself, taken *before* the file is truncated, so a second bench writing the same path is
refused without touching the first one's file (the kernel drops the lock when the file is
closed or its process dies: a killed run leaves no stale lock). The file is written in
place, not renamed from a temporary, so a run killed half way still leaves its readable
part at the path it was asked for.

Problems the user can fix before anything runs (the path is a folder, its folder is a
file, the folder is read-only, the recording exists and ``overwrite`` is False, another
process holds the lock) are :class:`~bench.errors.ConfigError`; the message names the
holder's pid when the kernel says it (``/proc/locks``).
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
from collections.abc import Iterable
from pathlib import Path

from bench.errors import ConfigError

__all__ = ["claim", "holder", "preflight", "preflight_folder", "clear_outputs", "OutputLockedError"]

_USAGE = {
    errno.EISDIR: "is a folder, expected a recording file",
    errno.ENOTDIR: "cannot be created: a part of its folder path is a file, not a folder",
    errno.EACCES: "cannot be written: permission denied",
    errno.EPERM: "cannot be written: operation not permitted",
    errno.EROFS: "cannot be written: the file system is read-only",
    errno.ENOENT: "cannot be created: its folder does not exist",
    errno.ELOOP: "cannot be created: too many symbolic links",
    errno.ENAMETOOLONG: "cannot be created: the name is too long",
}


def _usage(path: Path, exc: OSError) -> ConfigError:
    what = _USAGE.get(exc.errno or 0, f"cannot be opened for writing: {exc.strerror or exc}")
    return ConfigError(what, file=str(path))


def holder(path: str | Path) -> int | None:
    """The pid of the process that holds the write lock of ``path`` (0 when the lock is
    held but the kernel does not say by whom), None when nobody holds it."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _pid_of(fd)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def _pid_of(fd: int) -> int:
    st = os.fstat(fd)
    key = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    try:
        with open("/proc/locks") as fh:
            for line in fh:
                parts = line.split()
                if len(parts) > 5 and parts[1] == "FLOCK" and parts[5] == key and parts[3] == "WRITE":
                    return int(parts[4])
    except (OSError, ValueError):
        pass
    return 0


class OutputLockedError(ConfigError):
    """The output is being written by another process (``pid``: 0 when the kernel does not
    say which); ``path`` is the output."""

    def __init__(self, path: Path, pid: int):
        self.path, self.pid = path, pid
        who = f"pid {pid}" if pid else "another process"
        super().__init__(f"is being written by another bench ({who}): two writers would interleave their records; "
                         "wait for it or choose another output", file=str(path))

    def __reduce__(self) -> tuple:  # pickled by a campaign's worker processes
        return (type(self), (self.path, self.pid))


def _refuse_locked(path: Path, pid: int) -> ConfigError:
    return OutputLockedError(path, pid)


def _refuse_existing(path: Path) -> ConfigError:
    return ConfigError("exists: a recording is not overwritten without --force", file=str(path))


def claim(path: str | Path, *, overwrite: bool) -> int:
    """Open ``path`` for writing, locked and truncated; returns the file descriptor.

    Parent folders are created. Raises :class:`ConfigError` (see the module docstring).
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise ConfigError("cannot be created: a part of its folder path is a file, not a folder",
                          file=str(path)) from None
    except OSError as exc:
        raise _usage(path, exc) from None
    flags = os.O_RDWR | os.O_CLOEXEC
    created = False
    try:
        fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o644)
        created = True
    except FileExistsError:
        if path.is_dir():
            raise ConfigError(_USAGE[errno.EISDIR], file=str(path)) from None
        try:
            fd = os.open(path, flags | os.O_NONBLOCK)
        except OSError as exc:
            raise _usage(path, exc) from None
    except OSError as exc:
        raise _usage(path, exc) from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ConfigError("is not a regular file (a device or FIFO?), expected a recording file", file=str(path))
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise _refuse_locked(path, _pid_of(fd)) from None
        if not created and not overwrite:
            raise _refuse_existing(path)
        os.ftruncate(fd, 0)
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def preflight(path: str | Path, *, force: bool) -> None:
    """Check up front, changing nothing, that ``path`` can become a recording: not a
    folder, its folder path free of files and writable, not being written by another
    bench, not an existing file unless ``force``. Raises :class:`ConfigError`."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(_USAGE[errno.EISDIR], file=str(path))
    if os.path.lexists(path):
        if not path.is_file():
            raise ConfigError("is not a regular file (a device or FIFO?), expected a recording file", file=str(path))
        pid = holder(path)
        if pid is not None:
            raise _refuse_locked(path, pid)
        if not force:
            raise _refuse_existing(path)
        _writable(path, path, os.W_OK)
        return
    folder = _existing_ancestor(path.parent)
    if not folder.is_dir():
        raise ConfigError(_USAGE[errno.ENOTDIR], file=str(path))
    _writable(folder, path, os.W_OK | os.X_OK)


def _existing_ancestor(folder: Path) -> Path:
    while not os.path.lexists(folder) and folder != folder.parent:
        folder = folder.parent
    return folder


def preflight_folder(folder: str | Path) -> None:
    """Check up front that ``folder`` is (or can be created as) a writable folder: not a
    file, no file on its path, not read-only. Raises :class:`ConfigError`."""
    folder = Path(folder)
    found = _existing_ancestor(folder)
    if not found.is_dir():
        what = "is a file, expected a folder" if found == folder else (
            f"cannot be created: {found} on its path is a file, not a folder")
        raise ConfigError(what, file=str(folder))
    _writable(found, folder, os.W_OK | os.X_OK)


def _writable(where: Path, path: Path, mode: int) -> None:
    if not os.access(where, mode):
        code = errno.EROFS if os.statvfs(where).f_flag & os.ST_RDONLY else errno.EACCES
        raise _usage(path, OSError(code, os.strerror(code)))


def clear_outputs(paths: Iterable[str | Path], *, force: bool) -> list[Path]:
    """Make way for recordings about to be written (``bench run``/``accept``): refuse when
    one exists without ``force`` or is being written by another process; with ``force``
    remove the existing ones. Returns those removed."""
    paths = [Path(p) for p in paths]
    for folder in sorted({p.parent for p in paths}):
        preflight_folder(folder)
    existing = [p for p in paths if os.path.lexists(p)]
    for p in existing:
        if p.is_dir():
            raise ConfigError(_USAGE[errno.EISDIR], file=str(p))
        if not p.is_file():
            raise ConfigError("is not a regular file (a device or FIFO?), expected a recording file", file=str(p))
        pid = holder(p)
        if pid is not None:
            raise _refuse_locked(p, pid)
    if existing and not force:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise ConfigError(f"exists{more}: recordings are not overwritten without --force", file=str(existing[0]))
    for p in existing:
        try:
            p.unlink()
        except OSError as exc:
            raise _usage(p, exc) from None
    return existing
