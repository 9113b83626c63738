"""The ``bench`` command line."""

from __future__ import annotations


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bench`` console script."""
    from bench.cli.app import run

    return run(argv)
