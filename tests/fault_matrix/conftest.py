"""The fault matrix's shared recording."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.fault_matrix.matrix import SHORT_DR, bench


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """A finished recording of the bench's own dead-reckoning case (90 s, in process)."""
    out = tmp_path_factory.mktemp("src")
    bench("run", str(SHORT_DR), "-o", str(out), "-q", "--no-plots", cwd=out, expect=0)
    return out / "recordings" / "SHORT-DR" / "SHORT-DR-s3.mcap"
