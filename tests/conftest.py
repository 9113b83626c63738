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


@pytest.fixture(scope="module")
def ns():
    """A network namespace with multicast on its loopback (for udp_multicast between processes)."""
    from tests.transport import netns

    reason = netns.unavailable()
    if reason:
        pytest.skip(f"udp_multicast between processes needs a network namespace: {reason}")
    with netns.multicast_netns() as name:
        yield name
