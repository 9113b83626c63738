"""Fixtures of the run tests."""

from __future__ import annotations

import pytest

from tests.transport import netns


@pytest.fixture(scope="module")
def ns():
    """A network namespace with multicast on its loopback (for udp_multicast between processes)."""
    reason = netns.unavailable()
    if reason:
        pytest.skip(f"udp_multicast between processes needs a network namespace: {reason}")
    with netns.multicast_netns() as name:
        yield name
