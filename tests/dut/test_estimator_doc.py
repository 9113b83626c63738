"""The example of docs/estimators.md, "Writing your own estimator", run as the document
says: its code saved beside a test case naming it ``module:Class``, on the 90 s test
drive in lockstep, in process and through the harness."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.dut import MODE_DOPPLER, SOLUTION_VALID
from bench.record.mcap_io import RecordingReader

ROOT = Path(__file__).parent.parent.parent
SHORT = ROOT / "tests" / "data" / "short_drive.toml"


def _section() -> str:
    text = (ROOT / "docs" / "estimators.md").read_text()
    start = text.index("\n## Writing your own estimator\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else len(text)]


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", _section(), flags=re.S)


def _case(folder: Path, dut_table: str, duration: str | None = None) -> Path:
    module = next(b for b in _blocks("python") if "class GyroDoppler(Estimator)" in b)
    assert len(module.strip().splitlines()) <= 45  # a short example
    (folder / "gyro_doppler.py").write_text(module)  # "saved as gyro_doppler.py beside a case file"
    cut = f'duration = "{duration}"\n' if duration else ""
    short = 'shortened = "a test"\n' if duration else ""
    path = folder / "case.toml"
    path.write_text(f"""
[case]
id = "DOC"
title = "the example of docs/estimators.md"
requirements = ["R"]
{short}
[scenario]
script = "{SHORT}"
{cut}
[sensors]
imu = {{ grade = "seed000", rate = "200 Hz" }}
doppler = {{ model = "seed000" }}

{dut_table}

[run]
seeds = [3]

[[criterion]]
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "20 m"
""")
    return path


def _check(result, duration_s: float) -> None:
    assert result.verdict is Verdict.PASS, {c.criterion.id: c.aggregate.reason for c in result.criteria}
    rec = RecordingReader(result.runs[0].recording)
    assert rec.metadata()["run_end"]["status"] == "complete"
    sol, q = rec.read_columnar("/dut/nav_solution"), rec.read_columnar("/dut/nav_quality")
    n = round(duration_s * 100)
    assert len(sol) == n and len(q) == n  # an epoch every 10 ms, from the first IMU frame's to the end
    np.testing.assert_array_equal(np.diff(sol["t_ns"]), 10_000_000)
    np.testing.assert_array_equal(sol["epoch"], np.arange(n) % 256)  # filled by the bench
    np.testing.assert_array_equal(q["epoch"], sol["epoch"])
    assert np.all(sol["mode"] == MODE_DOPPLER) and np.all(sol["valid"] == SOLUTION_VALID)
    assert np.all((sol["heading"] >= 0) & (sol["heading"] < 2 * np.pi))
    speed = np.hypot(sol["vel_n"][:, 0], sol["vel_n"][:, 1])
    assert speed[:400].max() < 0.5 and 14.0 < speed.max() < 16.0  # at rest 5 s, then up to 15 m/s
    truth = rec.read_columnar("/truth")
    k = np.searchsorted(truth["t_ns"], sol["t_ns"][-1])
    miss = (np.degrees(sol["heading"][-1] - truth["euler"][k][0]) + 180.0) % 360.0 - 180.0
    assert abs(miss) < 1.0, miss  # the heading still right after the turns


def test_the_documented_example_runs_in_process_from_beside_its_case(tmp_path):
    dut = next(b for b in _blocks("toml") if 'kind = "in_process"' in b)
    result = run_case(load_case(_case(tmp_path, dut)), SuiteOptions(tmp_path / "out"))
    _check(result, 90.0)


@pytest.mark.slow
def test_the_documented_example_runs_through_the_harness(tmp_path):
    # the document's [dut] and [dut.links] as written ({python}, udp_multicast on the loopback:
    # no network namespace), with generous hang guards for a loaded machine
    dut = next(b for b in _blocks("toml") if 'kind = "external"' in b)
    dut = dut.replace("[dut]\n", '[dut]\nstartup_timeout = "60 s"\nshutdown_timeout = "60 s"\n', 1)
    dut += '\n[clock]\nmode = "lockstep"\ntimeout = "60 s"\n'
    case = load_case(_case(tmp_path, dut, duration="20 s"))
    result = run_case(case, SuiteOptions(tmp_path / "out"))
    _check(result, 20.0)
