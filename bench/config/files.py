"""Reading the files users give the bench: regular files of bounded size only.

Every loader of a user file (test cases, scenario scripts, parameter sets, fault files,
mapping and vehicle files, track CSV files, field logs, results records, campaign files,
DUT configurations, road networks) reads it through this module, so a directory, a FIFO,
a device (``/dev/zero``) or a file larger than its limit is refused before anything is
read, with a :class:`~bench.errors.ConfigError` naming the file, what it is and the limit::

    scenarios/: is a directory, not a file (a regular file of at most 64 MiB)
    /dev/zero: is a character device, not a results record (a regular file of at most 256 MiB)
    big.toml: is 3.2 GiB, more than the 64 MiB limit of a text file

Limits (:data:`bench.config.bounds.BOUNDS`): 64 MiB for text files (TOML, CSV), 256 MiB
for JSON files (results records, campaign files, a JSON DUT configuration), 1 GiB
for binary field logs. At most the limit + 1 bytes are ever read, whatever the file
claims to be (a file that grows while it is read is refused).

TOML and JSON are parsed here too (:func:`read_toml`, :func:`read_json`, and
:func:`parse_toml`, :func:`parse_json` for a text already read), with what every such input
must be:

* nested at most :data:`MAX_DEPTH` levels (arrays and tables/objects inside each other),
  checked before the parser sees it: a deep file is a :class:`ConfigError` naming the file
  and the limit, never Python's ``RecursionError``;
* every number finite: TOML's ``nan`` and ``inf``, JSON's ``NaN``, ``Infinity`` and
  ``-Infinity`` tokens and a literal that overflows (``1e999``) are refused, the field
  named as a path (``criterion[0].at_most``, ``cases[0].criteria[3].value``)::

    b.json: cases[0].criteria[3].value: expected a finite number, found NaN

  A JSON reader may take ``Infinity`` (``infinity=True``) where the bench itself writes an
  infinite measurement so (a campaign's files); a results record writes it as ``"inf"``.
"""

from __future__ import annotations

import errno
import json
import math
import os
import re
import stat
import tomllib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.bounds import bound
from bench.errors import ConfigError

__all__ = [
    "TEXT_LIMIT", "LOG_LIMIT", "JSON_LIMIT", "MAX_DEPTH", "regular_file", "open_bounded", "read_blocks", "read_bytes",
    "read_text", "read_toml", "parse_toml", "read_json", "parse_json", "check_finite", "file_size_text",
    "expand_case_dir",
]

#: Largest text input (TOML, CSV), bytes.
TEXT_LIMIT = int(bound("text_file").high or 0)
#: Largest binary field log, bytes.
LOG_LIMIT = int(bound("log_file").high or 0)
#: Largest JSON input (a results record, a campaign's files, a DUT configuration), bytes.
JSON_LIMIT = int(bound("json_file").high or 0)
#: Deepest nesting of arrays and tables/objects in a TOML or JSON input.
MAX_DEPTH = int(bound("nesting").high or 0)

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
        raise ConfigError(f"is {kind}, not {_a(what)} (a regular file of at most {file_size_text(limit)})",
                          file=file)
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


def open_bounded(path: str | Path, *, what: str = "file", limit: int = LOG_LIMIT) -> tuple[int, str]:
    """An open descriptor, and the name, of a regular file of at most ``limit`` bytes:
    checked before the open (a FIFO would block it) and again on the descriptor. The
    caller closes it, reading it with :func:`read_blocks` (at most ``limit`` + 1 bytes)."""
    p = regular_file(path, what=what, limit=limit)
    file = str(p)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise _os_error(exc, file, what) from None
    try:
        _refuse_stat(os.fstat(fd), file, limit, what)  # the path may have changed since the stat
    except BaseException:
        os.close(fd)
        raise
    return fd, file


def read_blocks(fd: int, file: str, *, what: str, limit: int, size: int = 1 << 20) -> Iterator[bytes]:
    """The content of the open file ``fd`` in blocks of at most ``size`` bytes; a
    :class:`ConfigError` once more than ``limit`` bytes came (a file that grows)."""
    total = 0
    while True:
        try:
            chunk = os.read(fd, min(size, limit + 1 - total))
        except OSError as exc:
            raise _os_error(exc, file, what) from None
        if not chunk:
            return
        total += len(chunk)
        if total > limit:
            raise ConfigError(f"grew past the {file_size_text(limit)} limit of {_a(what)} while read", file=file)
        yield chunk


def read_bytes(path: str | Path, *, what: str = "file", limit: int = LOG_LIMIT) -> bytes:
    """The content of a regular file of at most ``limit`` bytes (see the module docstring).

    The file is checked before it is opened (a FIFO would block the open) and again on the
    open descriptor; at most ``limit`` + 1 bytes are ever read, even from a file that grows.
    """
    fd, file = open_bounded(path, what=what, limit=limit)
    try:
        return b"".join(read_blocks(fd, file, what=what, limit=limit))
    finally:
        os.close(fd)


def read_text(path: str | Path, *, what: str = "text file", limit: int = TEXT_LIMIT) -> str:
    """A regular UTF-8 text file of at most ``limit`` bytes (newlines as written)."""
    data = read_bytes(path, what=what, limit=limit)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not UTF-8 text: {exc}", file=str(path)) from None


def read_toml(path: str | Path, *, what: str = "TOML file") -> dict[str, Any]:
    """Parse a TOML file; every error (missing, not a file, too large, not UTF-8, nested
    too deep, syntax, a number that is not finite) names the file, a syntax error the line,
    a number that is not finite its key."""
    return parse_toml(read_text(path, what=what), file=str(path), what=what)


def parse_toml(text: str, *, file: str | None, what: str = "TOML file") -> dict[str, Any]:
    """:func:`read_toml` of a text already read (``file`` names it in messages)."""
    _check_depth(text.encode("utf-8", "surrogatepass"), _TOML_SKIP, file, what)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", file=file) from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise ConfigError(f"nested deeper than the {MAX_DEPTH} levels {_a(what)} may have", file=file) from None
    check_finite(doc, file=file)
    return doc


def read_json(path: str | Path, *, what: str = "JSON file", limit: int = JSON_LIMIT, infinity: bool = False) -> Any:
    """Parse a JSON file of at most ``limit`` bytes; every error (missing, not a file, too
    large, not UTF-8, nested too deep, syntax, a number that is not finite) names the file,
    a number that is not finite its field (``cases[0].criteria[3].value``). With
    ``infinity`` the tokens ``Infinity`` and ``-Infinity`` are infinities (``NaN`` never is)."""
    data = read_bytes(path, what=what, limit=limit)
    return parse_json(data, file=str(path), what=what, infinity=infinity)


class _NonFinite:
    """A number of a JSON text that is not finite, kept as its token for the message."""

    __slots__ = ("token",)

    def __init__(self, token: str):
        self.token = token


def parse_json(text: str | bytes, *, file: str | None, what: str = "JSON file", infinity: bool = False) -> Any:
    """:func:`read_json` of a text already read (``file`` names it in messages)."""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text
    _check_depth(data, _JSON_SKIP, file, what)
    try:
        s = data.decode("utf-8") if isinstance(text, bytes) else text
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not UTF-8 text: {exc}", file=file) from None
    bad: list[_NonFinite] = []

    def refused(token: str) -> _NonFinite:
        bad.append(_NonFinite(token if len(token) <= 24 else token[:20] + "..."))
        return bad[-1]

    def constant(token: str) -> Any:  # NaN, Infinity, -Infinity
        if infinity and token != "NaN":
            return math.inf if token == "Infinity" else -math.inf
        return refused(token)

    def number(token: str) -> Any:
        x = float(token)
        return x if math.isfinite(x) else refused(token)

    def integer(token: str) -> Any:
        n = int(token)
        return n if abs(n) < 1 << 1023 else refused(token)  # beyond any float

    big = _may_overflow(data)  # else every number is parsed at C speed
    try:
        doc = json.loads(s, parse_constant=constant, parse_float=number if big else None,
                         parse_int=integer if big else None)
    except ValueError as exc:  # a syntax error, or an integer of more digits than Python converts
        raise ConfigError(f"not JSON: {exc}", file=file) from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise ConfigError(f"nested deeper than the {MAX_DEPTH} levels {_a(what)} may have", file=file) from None
    if bad:  # where the first one is, as a path
        at, token = _first_non_finite(doc, floats=False) or ("", bad[0].token)
        raise ConfigError(f"expected a finite number, found {token}", file=file, key=at or "(the document)")
    return doc


def _first_non_finite(doc: Any, key: str = "", *, floats: bool = True) -> tuple[str, str] | None:
    """The path and the text of the first number of ``doc`` (in document order) that is
    not finite (``floats``: a float; always: a JSON token refused), or None."""
    stack: list[tuple[str, Any]] = [(key, doc)]
    while stack:
        at, v = stack.pop()
        if isinstance(v, _NonFinite):
            return at, v.token
        if floats and isinstance(v, float) and not math.isfinite(v):
            return at, repr(v)
        if isinstance(v, Mapping):
            stack.extend((f"{at}.{k}" if at else str(k), x) for k, x in reversed(list(v.items())))
        elif isinstance(v, list):
            stack.extend((f"{at}[{i}]", x) for i, x in reversed(list(enumerate(v))))
    return None


def check_finite(doc: Any, *, file: str | None, key: str = "") -> None:
    """Raise :class:`ConfigError` naming ``file`` and the path of the field when a number of
    the parsed document ``doc`` (in nested tables and arrays too) is not finite."""
    found = _first_non_finite(doc, key)
    if found is not None:
        at, text = found
        raise ConfigError(f"expected a finite number, found {text}", file=file, key=at or "(the document)")


#: What cannot hold a bracket that nests: strings (with their escapes) and, in TOML, comments.
_JSON_SKIP = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"', re.S)
_TOML_SKIP = re.compile(
    rb'"""(?:[^"\\]|\\.|"(?!""))*"""'  # multi-line basic string
    rb"|'''.*?'''"  # multi-line literal string
    rb'|"[^"\\\n]*(?:\\.[^"\\\n]*)*"'  # basic string
    rb"|'[^'\n]*'"  # literal string
    rb"|#[^\n]*",  # comment
    re.S,
)
_DIGITS_AS_ZERO = bytes.maketrans(b"123456789E", b"000000000e")


def _may_overflow(data: bytes) -> bool:
    """Whether ``data`` may hold a number literal too large for a float: an exponent of
    three digits or more, or 300 digits in a row (passes at C speed; strings may give a
    false alarm, which only costs time)."""
    m = data.translate(_DIGITS_AS_ZERO)
    return b"e000" in m or b"e+000" in m or b"0" * 300 in m


_NOT_BRACKETS = bytes(b for b in range(256) if b not in b"[]{}")


def _check_depth(data: bytes, skip: re.Pattern[bytes], file: str | None, what: str) -> None:
    """ConfigError when arrays and tables/objects nest more than :data:`MAX_DEPTH` deep,
    counted over the brackets outside strings (and comments), in passes at C speed."""
    if data.count(b"[") + data.count(b"{") <= MAX_DEPTH:
        return
    a = np.frombuffer(skip.sub(b"", data).translate(None, _NOT_BRACKETS), np.uint8)
    depth = 0
    step = 1 << 22
    for i in range(0, len(a), step):
        part = a[i : i + step]
        d = depth + np.cumsum(np.where((part == 0x5B) | (part == 0x7B), 1, -1), dtype=np.int64)
        if int(d.max()) > MAX_DEPTH:
            raise ConfigError(f"nested deeper than the {MAX_DEPTH} levels {_a(what)} may have", file=file)
        depth = int(d[-1])


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
