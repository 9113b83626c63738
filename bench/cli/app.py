"""Argument parsing and dispatch of the ``bench`` subcommands.

Exit codes: 0 pass or success, 1 the DUT failed, 2 usage or configuration error,
3 bench error. Nothing else: whatever a subcommand raises is one of these.

* :class:`~bench.errors.ConfigError`: 2, ``bench: configuration error: ...``;
* another :class:`~bench.errors.BenchError`: 3, ``bench: error: ...``;
* an :class:`OSError` about a path the user gave as an input (an argument or option that
  is not an output: ``-o``, ``--json``, ``--junit``, ``--plot``), or a file inside a
  folder given as one: 2, ``bench: usage error: PATH: Is a directory``;
* any other exception (a bug, a full disk, an unwritable output, MemoryError,
  RecursionError...): 3, one line ``bench: internal error: ZeroDivisionError: ...
  (traceback in FILE)`` (``bench: error:`` for an OSError), the traceback appended to
  ``bench-error.log`` in the output folder of ``bench run``/``accept`` or in the user's
  state folder (:mod:`bench.crashlog`); ``--traceback`` or ``BENCH_TRACEBACK=1`` prints it
  too. Never a traceback alone, never the FAIL code 1.

Messages are shown through :func:`~bench.textsafe.for_terminal`: a DUT's output quoted in
a reason cannot drive the terminal.

SIGINT (Ctrl-C) and SIGTERM end a subcommand the same way: the first one raises
:class:`KeyboardInterrupt` (its argument names the signal), so a run in progress ends
with ``run_end`` status ``interrupted``, its recording finished and its DUT process
group shut down, and the exit code is 3. A second signal while that cleanup runs is
reported and otherwise ignored (the cleanup is bounded by the DUT's shutdown timeout);
a third aborts the cleanup. A signal the parent process set to be ignored stays ignored.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading
import traceback
from collections.abc import Iterator
from pathlib import Path

from bench import __version__, shield
from bench.crashlog import one_line, write_traceback
from bench.errors import BenchError, ConfigError
from bench.textsafe import for_terminal

__all__ = ["run", "interrupts", "EXIT_OK", "EXIT_FAIL", "EXIT_USAGE", "EXIT_ERROR", "SUBCOMMANDS"]

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_ERROR = 0, 1, 2, 3

#: Modules under bench.cli that each provide ``register(subparsers)``.
SUBCOMMANDS = [
    "synth", "run", "replay", "info", "imu", "score", "accept", "report", "compare", "fmu", "exchange", "views",
    "campaign",
]


def build_parser() -> argparse.ArgumentParser:
    """The parser with every subcommand registered."""
    parser = argparse.ArgumentParser(prog="bench", description="Hardware-in-the-loop bench for navigation estimators")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--traceback", action="store_true",
                        help="also print the traceback of an internal error (as BENCH_TRACEBACK=1 does)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        importlib.import_module(f"bench.cli.{name}").register(sub)
    return parser


def run(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the subcommand; returns the exit code (see the module
    docstring: whatever the handler raises ends as one of the four codes)."""
    args: argparse.Namespace | None = None
    try:
        parser = build_parser()
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
            return int(exc.code or 0)
        if not getattr(args, "handler", None):
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        with interrupts():
            return int(args.handler(args))
    except ConfigError as exc:
        _say(f"bench: configuration error: {for_terminal(exc, keep=chr(10))}")
        return EXIT_USAGE
    except BenchError as exc:
        _say(f"bench: error: {for_terminal(exc, keep=chr(10))}")
        return EXIT_ERROR
    except KeyboardInterrupt as exc:
        _end_progress_line()
        _say("bench: interrupted" + (f" by {exc.args[0]}" if exc.args else ""))
        return EXIT_ERROR
    except Exception as exc:  # a bug or the environment: ERROR, one line, the traceback in a log
        return _unexpected(exc, args)


def _end_progress_line() -> None:
    """End the line of a progress bar still drawn, so a message starts on its own line."""
    with contextlib.suppress(Exception):
        from bench.cli.progress import end_line

        end_line()


def _say(line: str) -> None:
    with contextlib.suppress(Exception):  # a closed or broken stderr cannot change the exit code
        print(line, file=sys.stderr)


def _unexpected(exc: Exception, args: argparse.Namespace | None) -> int:
    """Exit code and one line for an exception that is not a :class:`BenchError`."""
    if isinstance(exc, OSError) and args is not None:
        given = _given_input(exc, args)
        if given is not None:
            _say(f"bench: usage error: {for_terminal(given)}: {for_terminal(exc.strerror or exc)}")
            return EXIT_USAGE
    log = write_traceback(exc, _output_folder(args))
    wanted = os.environ.get("BENCH_TRACEBACK", "") not in ("", "0")
    if wanted or (args is not None and getattr(args, "traceback", False)):
        with contextlib.suppress(Exception):
            traceback.print_exception(exc, file=sys.stderr)
    where = f"traceback in {log}" if log else "the traceback could not be written; BENCH_TRACEBACK=1 prints it"
    kind = "error" if isinstance(exc, OSError) else "internal error"
    _say(f"bench: {kind}: {one_line(exc)} ({where})")
    return EXIT_ERROR


#: Options naming what a command writes; every other path-like option or argument is an input.
OUTPUT_OPTIONS = ("out", "output", "json", "junit", "plot")


def _given_input(exc: OSError, args: argparse.Namespace) -> str | None:
    """The input path the user gave that ``exc`` is about (the path itself, or a file inside
    a folder given), or None: an OSError about anything else is the bench's ERROR."""
    names = [n for n in (exc.filename, exc.filename2) if isinstance(n, str | os.PathLike)]
    if not names:
        return None
    for dest, value in vars(args).items():
        if dest in OUTPUT_OPTIONS or dest in ("handler", "command"):
            continue
        for given in value if isinstance(value, list) else [value]:
            if not isinstance(given, str | os.PathLike) or not str(given):
                continue
            g = os.path.abspath(given)
            for n in names:
                p = os.path.abspath(n)
                if p == g or p.startswith(g.rstrip(os.sep) + os.sep):
                    return str(n)
    return None


def _output_folder(args: argparse.Namespace | None) -> Path | None:
    """The output folder of the command (``bench run``/``accept``/``campaign``), where its traceback
    log goes; None for commands without one."""
    if args is None or args.command not in ("run", "accept", "campaign"):
        return None
    if getattr(args, "out", None):
        return Path(args.out)
    if args.command == "accept":
        from bench.paths import reports_dir

        return reports_dir()
    return None


class _Interrupt:
    """Signal handler: the first signal raises KeyboardInterrupt (held to the end of a
    :func:`~bench.shield.shielded` section, such as a recording write), the second is
    reported and ignored, the third raises again at once."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, signum: int, frame: object) -> None:
        self.count += 1
        name = signal.Signals(signum).name
        if self.count == 2:
            _end_progress_line()
            print(f"bench: {name}: still finishing the recording and stopping the DUT, or writing the reports; "
                  "signal once more to abort that", file=sys.stderr)
            return
        if self.count == 1 and shield.hold(name):
            return
        raise KeyboardInterrupt(name)


@contextlib.contextmanager
def interrupts() -> Iterator[None]:
    """SIGINT and SIGTERM raise KeyboardInterrupt inside the block (see the module
    docstring); the previous handlers are restored after it. Only the main thread can
    handle signals: elsewhere nothing is installed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    handler = _Interrupt()
    previous: dict[int, object] = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            old = signal.getsignal(sig)
            if old is not signal.SIG_IGN:
                previous[sig] = old
                signal.signal(sig, handler)
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)
