"""Reading the files users give the bench: regular files of bounded size only.

Every loader of a user file (test cases, scenario scripts, parameter sets, fault files,
mapping and vehicle files, track CSV files, field logs) reads it through this module, so
a directory, a FIFO, a device (``/dev/zero``) or a file larger than its limit is refused
before anything is read, with a :class:`~bench.errors.ConfigError` naming the file and
what it is::

    scenarios/: is a directory, not a file
    /dev/zero: is a character device, not a file
    big.toml: is 3.2 GiB, more than the 64 MiB limit of a text file

Limits (:data:`bench.config.bounds.BOUNDS`): 64 MiB for text files (TOML, CSV), 1 GiB
for binary field logs.
"""

from __future__ import annotations

import errno
import os
import stat
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bench.config.bounds import bound
from bench.errors import ConfigError

__all__ = [
    "TEXT_LIMIT", "LOG_LIMIT", "regular_file", "read_bytes", "read_text", "read_toml", "file_size_text",
    "expand_case_dir",
]

#: Largest text input (TOML, CSV), bytes.
TEXT_LIMIT = int(bound("text_file").high or 0)
#: Largest binary field log, bytes.
LOG_LIMIT = int(bound("log_file").high or 0)

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
)


def file_size_text(n: float) -> str:
    """A size in bytes as people read it: ``512 bytes``, ``3.2 GiB``."""
    if n < 1024:
        return f"{int(n)} bytes"
    for unit in ("KiB", "MiB", "GiB", "TiB"):
        n /= 1024.0
        if n < 1024 or unit == "TiB":
            return f"{n:.3g} {unit}"
    raise AssertionError  # pragma: no cover


def _what(mode: int) -> str | None:
    for test, name in _KINDS:
        if test(mode):
            return name
    return None if stat.S_ISREG(mode) else "not a regular file"


def _a(what: str) -> str:
    """``what`` with its article: ``a TOML file``, ``an IMU log``, ``an image``."""
    first = what.split()[0] if what.split() else what
    vowel = what[:1] in "aeiouAEIOU" or (first.isupper() and what[:1] in "AEFHILMNORSX")
    return f"{'an' if vowel else 'a'} {what}"


def _refuse_stat(st: os.stat_result, file: str, limit: int, what: str) -> None:
    kind = _what(st.st_mode)
    if kind is not None:
        raise ConfigError(f"is {kind}, not {_a(what)}", file=file)
    if st.st_size > limit:
        raise ConfigError(
            f"is {file_size_text(st.st_size)}, more than the {file_size_text(limit)} limit of {_a(what)}", file=file
        )


def _os_error(exc: OSError, file: str, what: str) -> ConfigError:
    if exc.errno == errno.ENOENT:
        return ConfigError(f"{what} not found", file=file)
    reason = exc.strerror or type(exc).__name__
    return ConfigError(f"cannot read the {what}: {reason}", file=file)


def regular_file(path: str | Path, *, what: str = "file", limit: int = TEXT_LIMIT) -> Path:
    """``path`` if it is a regular file of at most ``limit`` bytes, else ConfigError.

    For readers that open the file themselves (python-can's log readers); never opens it.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as exc:
        raise _os_error(exc, str(p), what) from None
    _refuse_stat(st, str(p), limit, what)
    return p


def read_bytes(path: str | Path, *, what: str = "file", limit: int = LOG_LIMIT) -> bytes:
    """The content of a regular file of at most ``limit`` bytes (see the module docstring).

    The file is checked before it is opened (a FIFO would block the open) and again on the
    open descriptor; at most ``limit`` bytes are ever read, even from a file that grows.
    """
    p = regular_file(path, what=what, limit=limit)
    file = str(p)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise _os_error(exc, file, what) from None
    try:
        _refuse_stat(os.fstat(fd), file, limit, what)  # the path may have changed since the stat
        chunks: list[bytes] = []
        total = 0
        while True:
            chunk = os.read(fd, min(1 << 20, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > limit:
                raise ConfigError(f"grew past the {file_size_text(limit)} limit of {_a(what)} while read", file=file)
    except OSError as exc:
        raise _os_error(exc, file, what) from None
    finally:
        os.close(fd)
    return b"".join(chunks)


def read_text(path: str | Path, *, what: str = "text file", limit: int = TEXT_LIMIT) -> str:
    """A regular UTF-8 text file of at most ``limit`` bytes (newlines as written)."""
    data = read_bytes(path, what=what, limit=limit)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not UTF-8 text: {exc}", file=str(path)) from None


def read_toml(path: str | Path, *, what: str = "TOML file") -> dict[str, Any]:
    """Parse a TOML file; every error (missing, not a file, too large, not UTF-8, syntax)
    names the file, syntax errors the line."""
    text = read_text(path, what=what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", file=str(path)) from None


def expand_case_dir(value: Any, base: Path | None) -> Any:
    """``{case_dir}`` in the string values of a ``[dut.config]`` table (nested tables and lists
    too) replaced by the case file's folder (the working directory for a case from text)."""
    if isinstance(value, str):
        return value.replace("{case_dir}", str(base if base is not None else Path.cwd()))
    if isinstance(value, Mapping):
        return {k: expand_case_dir(v, base) for k, v in value.items()}
    if isinstance(value, list):
        return [expand_case_dir(v, base) for v in value]
    return value
