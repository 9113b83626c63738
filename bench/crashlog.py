"""Where the traceback of an unexpected exception goes, and the one line that names it.

An exception that is not a :class:`~bench.errors.BenchError` is a bug of the bench (or a
failure of its environment: disk full, permissions). The user sees one line naming it and
pointing to a log file; the traceback goes to that file, appended under a header with
the time, the process id and the command line:

* ``<folder>/bench-error.log`` when the command or the suite has an output folder;
* otherwise, or when that folder cannot be written, ``bench-error.log`` in the user's
  state folder (``$XDG_STATE_HOME/bench``, default ``~/.local/state/bench``), then in
  ``<temp dir>/bench-<uid>``.

The run engine also appends here, in the recording's folder, the traceback of an
in-process estimator that raised (the DUT's bug, not the bench's: its header line says
``DUT error``).
"""

from __future__ import annotations

import datetime as _dt
import os
import sys
import tempfile
import traceback
from pathlib import Path

from bench.textsafe import for_terminal

__all__ = ["LOG_NAME", "state_dir", "write_traceback", "one_line"]

LOG_NAME = "bench-error.log"
_MAX_LINE = 300


def state_dir() -> Path:
    """The user's state folder for the bench (not created here)."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "bench"


def _fallbacks() -> list[Path]:
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    return [state_dir(), Path(tempfile.gettempdir()) / f"bench-{uid}"]


def one_line(exc: BaseException) -> str:
    """``TypeName: message`` on one line, control characters visible, at most 300 characters."""
    try:
        message = str(exc)
    except Exception:  # an exception whose __str__ fails still has a name
        message = "(message unprintable)"
    text = f"{type(exc).__name__}: {message}" if message else type(exc).__name__
    text = for_terminal(text)
    return text if len(text) <= _MAX_LINE else text[: _MAX_LINE - 1] + "…"


def _format(exc: BaseException, context: str) -> str:
    try:
        tb = "".join(traceback.format_exception(exc))
    except Exception as e:  # MemoryError or a broken __str__: still say what we know
        tb = f"(the traceback could not be formatted: {type(e).__name__})\n{type(exc).__name__}\n"
    when = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    head = f"==== {when} pid {os.getpid()}: {' '.join(sys.argv)}"
    return f"{head}\n{context + chr(10) if context else ''}{tb}\n"


def write_traceback(exc: BaseException, folder: str | Path | None = None, *, context: str = "") -> Path | None:
    """Append the traceback of ``exc`` to ``bench-error.log`` in ``folder`` (created if
    need be), else in the state or temporary folder; returns the file written, or None if
    none could be. Never raises."""
    try:
        text = _format(exc, context)
    except Exception:
        return None
    for d in ([Path(folder)] if folder is not None else []) + _fallbacks():
        try:
            d.mkdir(parents=True, exist_ok=True)
            path = d / LOG_NAME
            with open(path, "a", encoding="utf-8", errors="backslashreplace") as fh:
                fh.write(text)
            return path
        except Exception:  # an unwritable folder, a full disk: try the next one
            continue
    return None
