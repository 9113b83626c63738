"""Files written whole: to a temporary name in the same folder, then renamed into place.

Every report the bench writes (``results.json``, ``junit.xml``, the summaries, plots, the
certification and campaign reports, ``bench compare -o``, ``bench score --json/--junit``,
a campaign's records) goes through :func:`atomic_file` or :func:`write_atomic`, so a
reader (a CI job, a test-management tool, a second bench) sees the old file or the new
one, never a torn or an empty one:

* the content goes to ``.<name>.<random>.tmp`` beside ``<name>`` (same folder, same file
  system, so the rename is atomic), created with the usual permissions (``0666`` less the
  umask, as ``open(..., "w")`` would);
* with ``durable`` (the default) the file is flushed to the disk (``fsync``) before it is
  renamed over ``<name>``, and the folder after, so a power cut cannot leave the new name
  on an empty file either;
* if anything fails before the rename -- a full disk (``ENOSPC``, ``EFBIG``), a crash
  while formatting, an interrupt (Ctrl-C, SIGTERM: :class:`KeyboardInterrupt`) -- the
  temporary file is removed, ``<name>`` is left as it was (the old file, or none), and the
  exception goes on.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = ["atomic_file", "write_atomic", "temporary_name"]


def temporary_name(path: Path) -> Path:
    """A fresh hidden temporary name beside ``path`` (``.<name>.<random>.tmp``)."""
    return path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")


def _sync_folder(folder: Path) -> None:
    """Flush a folder's entries (the rename) to the disk, where the file system allows it."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike[str], mode: str = "wb", *, encoding: str | None = None,
                durable: bool = True) -> Iterator[IO[Any]]:
    """A file object to write ``path``'s new content into (``mode`` ``"w"`` or ``"wb"``);
    ``path`` is replaced by it when the block ends without an exception, and left as it
    was otherwise (module docstring). The folder is created if needed."""
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_file writes a new file: mode 'w' or 'wb', not {mode!r}")
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(target)
    created = False
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
        created = True
        try:
            fh: IO[Any] = (os.fdopen(fd, "w", encoding=encoding or "utf-8", newline="") if mode == "w"
                           else os.fdopen(fd, "wb"))
        except BaseException:
            os.close(fd)
            raise
        with fh:
            yield fh
            fh.flush()
            if durable:
                os.fsync(fh.fileno())
        os.replace(tmp, target)
        created = False
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
    if durable:
        _sync_folder(target.parent)


def write_atomic(path: str | os.PathLike[str], data: str | bytes, *, encoding: str = "utf-8",
                 durable: bool = True) -> Path:
    """Replace ``path`` by ``data`` (text is encoded with ``encoding``) as a whole: see the
    module docstring. Returns ``path``."""
    with atomic_file(path, "wb", durable=durable) as fh:
        fh.write(data.encode(encoding) if isinstance(data, str) else data)
    return Path(path)
