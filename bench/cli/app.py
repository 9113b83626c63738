"""Argument parsing and dispatch of the ``bench`` subcommands.

Exit codes: 0 pass or success, 1 the DUT failed, 2 usage or configuration error,
3 bench error.

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
import signal
import sys
import threading
from collections.abc import Iterator

from bench import __version__
from bench.errors import BenchError, ConfigError

__all__ = ["run", "interrupts", "EXIT_OK", "EXIT_FAIL", "EXIT_USAGE", "EXIT_ERROR", "SUBCOMMANDS"]

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_ERROR = 0, 1, 2, 3

#: Modules under bench.cli that each provide ``register(subparsers)``.
SUBCOMMANDS = ["synth", "run", "replay", "info", "imu", "score", "accept", "fmu"]


def build_parser() -> argparse.ArgumentParser:
    """The parser with every subcommand registered."""
    parser = argparse.ArgumentParser(prog="bench", description="Hardware-in-the-loop bench for navigation estimators")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        importlib.import_module(f"bench.cli.{name}").register(sub)
    return parser


def run(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the subcommand; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
        return int(exc.code or 0)
    if not getattr(args, "handler", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        with interrupts():
            return int(args.handler(args))
    except ConfigError as exc:
        print(f"bench: configuration error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BenchError as exc:
        print(f"bench: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt as exc:
        print("bench: interrupted" + (f" by {exc.args[0]}" if exc.args else ""), file=sys.stderr)
        return EXIT_ERROR


class _Interrupt:
    """Signal handler: the first signal raises KeyboardInterrupt, the second is reported
    and ignored, the third raises again."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, signum: int, frame: object) -> None:
        self.count += 1
        name = signal.Signals(signum).name
        if self.count == 2:
            print(f"bench: {name}: still finishing the recording and stopping the DUT; signal once more to abort that",
                  file=sys.stderr)
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
