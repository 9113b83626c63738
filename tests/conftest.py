"""Shared fixtures of the bench's own tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings

DATA = Path(__file__).parent / "data"

# No wall-clock deadline on any property test (hypothesis's default of 200 ms per example
# fails a loaded machine); each test bounds its own max_examples.
settings.register_profile("bench", deadline=None)
settings.load_profile("bench")


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
