"""Fixtures of the campaign tests: the short synthetic case and how to start `bench campaign`."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent
CASE = HERE / "case.toml"
ROOT = HERE.parent.parent


def bench_env() -> dict[str, str]:
    """The environment of a subprocess or worker: this checkout first on PYTHONPATH."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH", "")])])
    return env


def bench_command(*args: str) -> list[str]:
    """``bench ARGS`` run by this interpreter."""
    return [sys.executable, "-c", "import sys; from bench.cli.app import run; sys.exit(run(sys.argv[1:]))", *args]


@pytest.fixture
def case_file() -> Path:
    return CASE
