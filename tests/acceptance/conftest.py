"""Short scenarios and case files for the acceptance tests (written into tmp folders, so
the pytest plugin never sees them as cases of this test run)."""

from __future__ import annotations

from pathlib import Path

import pytest

DRIVE = """
[scenario]
id = "T-short"
title = "a short drive for tests"

[initial]
latitude = 30.0
longitude = 110.0
height = "50 m"
speed = "10 m/s"
heading = "0 deg"

[[segment]]
kind = "uniform"
duration = "60 s"

[[segment]]
kind = "uniform"
duration = "30 s"
gnss = "blocked"
label = "tunnel"

[[segment]]
kind = "uniform"
duration = "110 s"
"""

BASE = """
[case]
id = "T1"
title = "test case"
requirements = ["R1", "R2"]
waived = { R2 = "the test cases built on this one judge R2 where they add its criteria" }

[scenario]
script = "drive.toml"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"
latency = "3 ms"

[[dut.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["3 m", "4 m", "0 m"]

[run]
seeds = [1]

[[criterion]]
id = "H"
requirement = "R1"
metric = "accuracy.horizontal.rms"
at_most = "{limit}"
marginal = "{band}"
paper = "5 m"
"""


@pytest.fixture
def drive_dir(tmp_path: Path) -> Path:
    """A folder with the short drive as ``drive.toml``."""
    (tmp_path / "drive.toml").write_text(DRIVE)
    return tmp_path


@pytest.fixture
def make_case(drive_dir: Path):
    """Write a case file next to the drive: ``make_case(text, name)`` -> path."""

    def make(text: str, name: str = "case.toml") -> Path:
        p = drive_dir / name
        p.write_text(text)
        return p

    return make


def base_case(limit: str = "6 m", band: str = "0.5 m") -> str:
    """A one-criterion case: horizontal RMS of a 5 m bias against ``limit``."""
    return BASE.replace("{limit}", limit).replace("{band}", band)
