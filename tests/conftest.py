"""Shared fixtures of the bench's own tests."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """Real recordings copied into the repository with their licences (tests/data)."""
    return DATA


@pytest.fixture(scope="session")
def s000_trajectory():
    """The S000 reference drive (built once per session)."""
    from bench.scenario.loader import load_scenario

    return load_scenario("S000").trajectory()
