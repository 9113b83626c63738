"""Where the bench finds its data: ``models/``, ``test_cases/`` and ``fmu/``.

The data folders live at the project root beside the package. ``BENCH_HOME`` overrides
the root (for an installed package used with a checkout elsewhere).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["project_root", "models_dir", "test_cases_dir", "fmu_dir", "reports_dir"]


def project_root() -> Path:
    """The folder holding ``models/`` and ``test_cases/``."""
    env = os.environ.get("BENCH_HOME")
    if env:
        return Path(env).resolve()
    return Path(__file__).resolve().parent.parent


def models_dir() -> Path:
    """Parameter sets, the ICD as DBC, vehicle data."""
    return project_root() / "models"


def test_cases_dir() -> Path:
    """Acceptance test cases and the scenario motion scripts under ``scenarios/``."""
    return project_root() / "test_cases"


def fmu_dir() -> Path:
    """FMU sources and built ``.fmu`` files."""
    return project_root() / "fmu"


def reports_dir() -> Path:
    """Generated output (git-ignored)."""
    return project_root() / "reports"
