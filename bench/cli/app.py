"""Argument parsing and dispatch of the ``bench`` subcommands.

Exit codes: 0 pass or success, 1 the DUT failed, 2 usage or configuration error,
3 bench error.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from bench import __version__
from bench.errors import BenchError, ConfigError

__all__ = ["run", "EXIT_OK", "EXIT_FAIL", "EXIT_USAGE", "EXIT_ERROR", "SUBCOMMANDS"]

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
        return int(args.handler(args))
    except ConfigError as exc:
        print(f"bench: configuration error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BenchError as exc:
        print(f"bench: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("bench: interrupted", file=sys.stderr)
        return EXIT_ERROR
