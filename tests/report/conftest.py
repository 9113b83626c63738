"""Small real suites for the results record tests: a synthetic-DUT case with fault
windows, bad frames and two Monte Carlo seeds (``bench accept``), and the 90 s in-process
dead-reckoning run of the engine with a fault file (``bench run``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from bench.cli.app import run as cli
from tests.acceptance.conftest import DRIVE
from tests.report.suite import write_suite

ROOT = Path(__file__).resolve().parent.parent

SUITE_CASE = """
[case]
id = "ID1"
title = "identity test case"
requirements = ["R1", "R2"]
waived = { R2 = "the test cases built on this one judge R2 where they add its criteria" }

[scenario]
script = "drive.toml"

[[fault]]
start = "20 s"
end = "25 s"
target = "odometer"
kind = "idling"

[[fault]]
start = "50 s"
end = "55.5 s"
target = "odometer"
kind = "sliding"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"
latency = "3 ms"
sigma_position = ["1 m", "1 m", "1 m"]

[[dut.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["3 m", "4 m", "0 m"]

[[dut.synthetic.output]]
kind = "bad_frames"
every = 50

[run]
seeds = [1, 2]

[[criterion]]
id = "H"
requirement = "R1"
metric = "accuracy.horizontal.rms"
at_most = "6 m"
marginal = "0.5 m"
paper = "5 m"

[[criterion]]
id = "HMAX"
requirement = "R2"
metric = "accuracy.horizontal.max"
at_most = "20 m"
monte_carlo = { pass_runs = 2 }

[[criterion]]
id = "HMEAN"
requirement = "R2"
metric = "accuracy.horizontal.rms"
at_most = "1 km"
monte_carlo = { aggregate = "mean" }
"""

ENGINE_FAULTS = """
[[fault]]
layer = "sensor"
target = "doppler"
kind = "dropout"
start = "20 s"
end = "25 s"
"""


@pytest.fixture(scope="session")
def suite(tmp_path_factory) -> dict:
    """``bench accept`` of :data:`SUITE_CASE`: ``out``, ``doc`` (results.json), ``code``."""
    d = tmp_path_factory.mktemp("suite")
    (d / "drive.toml").write_text(DRIVE)
    (d / "case.toml").write_text(SUITE_CASE)
    out = d / "out"
    code = cli(["accept", str(d / "case.toml"), "-o", str(out), "-q", "--no-plots"])
    return {"dir": d, "out": out, "code": code, "doc": json.loads((out / "results.json").read_text())}


@pytest.fixture(scope="session")
def engine_run(tmp_path_factory) -> dict:
    """``bench run`` of the 90 s in-process dead-reckoning case with a Doppler dropout
    from a fault file: ``out``, ``doc``, ``recording``, ``case``, ``faults``."""
    d = tmp_path_factory.mktemp("engine")
    drive = (ROOT / "data" / "short_drive.toml").as_posix()
    text = (ROOT / "run" / "data" / "short_dr.toml").read_text().replace('"../../data/short_drive.toml"', f'"{drive}"')
    (d / "dropout.toml").write_text(ENGINE_FAULTS)
    case = d / "case.toml"
    case.write_text(text.replace("[case]", 'fault_files = ["dropout.toml"]\n\n[case]', 1))
    out = d / "out"
    code = cli(["run", str(case), "-o", str(out), "-q", "--no-plots"])
    assert code in (0, 1), f"the engine run could not be judged (exit {code})"
    recs = sorted((out / "recordings").rglob("*.mcap"))
    assert len(recs) == 1
    return {"out": out, "doc": json.loads((out / "results.json").read_text()), "recording": recs[0], "case": case,
            "faults": d / "dropout.toml"}



@pytest.fixture(scope="session")
def suite_out(tmp_path_factory) -> Path:
    """The output folder of ``bench accept`` on the two report-test cases (RPT-B FAILs its
    limit and leaves a requirement unjudged, ERROR: exit code 3): results.json,
    report.html, report.pdf, recordings/."""
    root = tmp_path_factory.mktemp("report_suite")
    cases = write_suite(root)
    out = root / "out"
    code = cli(["accept", str(cases / "rpt_a.toml"), str(cases / "rpt_b.toml"), "-o", str(out), "-q"])
    assert code == 3, "RPT-B fails its limit and leaves R-NEVER unjudged (ERROR), RPT-A passes"
    return out


@pytest.fixture(scope="session")
def report_dir(request) -> Path:
    """The folder whose report.html, report.pdf and results.json the report checks read:
    ``$BENCH_REPORT_DIR`` when set (the main job's ``reports/`` after ``make demo``, say),
    otherwise the report-test suite's."""
    given = os.environ.get("BENCH_REPORT_DIR")
    return Path(given) if given else request.getfixturevalue("suite_out")
