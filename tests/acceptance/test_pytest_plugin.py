"""The pytest plugin, as users meet it: pytest run in a fresh process on a project folder
with test cases and hand-written tests (the plugin is loaded by its entry point)."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.acceptance.conftest import DRIVE, base_case

USER_TEST = """
import pytest


@pytest.mark.requirement("R-USER-1")
@pytest.mark.bench_case("../test_cases/pass.toml")
def test_drive_twice(bench, bench_case, bench_recording, bench_links):
    result = bench.score(bench_recording)
    assert str(result.verdict) == "PASS"
    assert bench_links == {"can": {"interface": "virtual", "channel": "vehicle"}}
    assert bench_case.id == "T1"


def test_plain():
    assert True
"""

NO_DATA = """
[[criterion]]
requirement = "R2"
metric = "accuracy.horizontal.max"
window = { kind = "climb" }
at_most = "1 m"
"""


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("project")
    cases = root / "test_cases"
    cases.mkdir()
    (cases / "drive.toml").write_text(DRIVE)
    links = '\n[dut.links.can]\ninterface = "virtual"\nchannel = "vehicle"\n'
    (cases / "pass.toml").write_text(base_case(limit="6 m").replace("[dut.synthetic]", links + "[dut.synthetic]"))
    (cases / "marginal.toml").write_text(base_case(limit="5.2 m").replace('id = "T1"', 'id = "T2"'))
    (cases / "fail.toml").write_text(base_case(limit="4 m").replace('id = "T1"', 'id = "T3"'))
    (cases / "error.toml").write_text(base_case().replace('id = "T1"', 'id = "T4"') + NO_DATA)
    (cases / "malformed.toml").write_text(base_case(limit="4 m/s").replace('id = "T1"', 'id = "T5"'))
    tests = root / "tests"
    tests.mkdir()
    (tests / "test_user.py").write_text(USER_TEST)
    return root


def _pytest(root: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-o", "addopts=", *args],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_cases_run_as_tests_with_verdicts_mapped(project):
    r = _pytest(project, "test_cases", "-rA", "--junitxml=junit.xml", "--bench-out", "out")
    out = r.stdout
    assert r.returncode == 1, out + r.stderr
    assert "2 passed" in out and "1 failed" in out and "2 errors" in out, out
    assert "FAILED test_cases/fail.toml::T3" in out
    assert "ERROR test_cases/error.toml::T4" in out  # the bench could not judge: an error
    assert "ERROR test_cases/malformed.toml::malformed" in out
    assert "criterion[0].at_most" in out and "expected length" in out  # file, key, expectation
    assert "BenchMarginalWarning" in out and "T2: marginal: H" in out
    junit = ET.parse(project / "junit.xml").getroot()
    cases = {tc.get("name"): tc for tc in junit.iter("testcase")}
    assert cases["T3"].find("failure") is not None and cases["T3"].find("error") is None
    assert cases["T4"].find("error") is not None and cases["T4"].find("failure") is None
    props = {(p.get("name"), p.get("value")) for p in cases["T1"].iter("property")}
    assert ("requirement", "R1") in props and ("requirement", "R2") in props and ("verdict", "PASS") in props
    assert (project / "out" / "results.json").exists()
    assert (project / "out" / "recordings" / "T1" / "T1-s1.mcap").exists()


def test_fixtures_and_requirement_marker(project):
    r = _pytest(project, "tests", "-q", "--junitxml=user.xml", "--bench-out", "out2", "--bench-seed", "7")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 passed" in r.stdout
    assert (project / "out2" / "recordings" / "T1" / "T1-s7.mcap").exists()
    junit = ET.parse(project / "user.xml").getroot()
    tc = next(t for t in junit.iter("testcase") if t.get("name") == "test_drive_twice")
    assert ("requirement", "R-USER-1") in {(p.get("name"), p.get("value")) for p in tc.iter("property")}


@pytest.mark.parametrize("args", [(), (".",)])
def test_inert_unless_cases_are_given(project, args):
    r = _pytest(project, "--collect-only", "-q", *args)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "test_user.py::test_plain" in r.stdout
    assert ".toml" not in r.stdout


def test_bench_cases_option_collects_everywhere(project):
    r = _pytest(project, "--collect-only", "-q", "--bench-cases", ".")
    assert "test_cases/pass.toml::T1" in r.stdout
    assert "drive.toml" not in r.stdout  # a scenario, not a case
