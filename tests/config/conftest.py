"""Small case and scenario files for the configuration tests, written into tmp folders."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.acceptance.conftest import DRIVE, base_case

__all__ = ["DRIVE", "base_case"]


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """A folder with the short drive as ``drive.toml`` (what ``base_case()`` runs)."""
    (tmp_path / "drive.toml").write_text(DRIVE)
    return tmp_path


@pytest.fixture
def write(folder: Path):
    """``write(name, text)`` -> the path of a file written into the folder."""

    def make(name: str, text: str) -> Path:
        p = folder / name
        p.write_text(text)
        return p

    return make
