"""The report tests' suite, run once per test process by ``bench accept``."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli.app import run as cli
from tests.report.suite import write_suite


@pytest.fixture(scope="session")
def suite_out(tmp_path_factory) -> Path:
    """The output folder of ``bench accept`` on the two report-test cases (RPT-B FAILs:
    exit code 1): results.json, report.html, report.pdf, recordings/."""
    root = tmp_path_factory.mktemp("report_suite")
    cases = write_suite(root)
    out = root / "out"
    code = cli(["accept", str(cases / "rpt_a.toml"), str(cases / "rpt_b.toml"), "-o", str(out), "-q"])
    assert code == 1, "RPT-B fails its limit, RPT-A passes"
    return out
