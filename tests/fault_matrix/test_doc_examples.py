"""The fault matrix (issue 34, item 10): the docs' external-estimator example runs as
written, and the bench says why an external DUT cannot work instead of waiting it out.

Every row runs ``bench run`` as a user would (matrix.py: exit code, no traceback, nothing
left running).

On 57b1bce: docs/estimators.md's external example named plain ``python`` (a user's
interpreter without the bench: ModuleNotFoundError, printed once per criterion, 11 times)
and no ``[dut.links]``, so the CAN bus was python-can's ``virtual`` one, which no other
process can reach: the run waited 5 s and ended ERROR (exit 3), "the DUT did not answer
BENCH_TIME(0 s) with DUT_READY within 5 s"; the example's drive and case were in tests/
only, not shipped.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from tests.fault_matrix.matrix import SHORT, bench

ROOT = Path(__file__).parent.parent.parent
EXAMPLE = ROOT / "examples" / "gyro_doppler"
HARNESS = ("-m bench.dut.harness --estimator gyro_doppler:GyroDoppler --can-interface {can_interface} "
           "--can-channel {can_channel} --can-port {can_port} --imu {imu_port} --gnss {gnss_port} --config {config}")


def _doc_commands(doc: str, case: str) -> list[str]:
    """The ``bench run`` commands of ``doc`` that run ``case``, as a user would copy them."""
    text = (ROOT / "docs" / doc).read_text()
    return [c for c in re.findall(r"^\s*(?:\$ )?(\S*bench run [^\n]+)$", text, flags=re.M) if case in c]


def _run_doc_command(command: str, tmp_path: Path):
    """``command`` run in a scratch folder holding the repository's examples/ (its output
    there too): ``.venv/bin/bench`` is the bench of this test's interpreter."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    argv = shlex.split(command)
    assert argv[0].endswith("bench") and argv[1] == "run", command
    return bench(*argv[1:], cwd=tmp_path, timeout=600)


@pytest.mark.parametrize("case", ["in_process.toml", "external.toml"])
def test_the_estimator_example_of_the_docs_runs_as_written(tmp_path, case):
    commands = _doc_commands("estimators.md", f"examples/gyro_doppler/{case}")
    assert commands, f"docs/estimators.md gives no command running examples/gyro_doppler/{case}"
    out = _run_doc_command(commands[0], tmp_path)
    assert out.code == 0, out.text
    results = json.loads(next(tmp_path.glob("reports/*/results.json")).read_text())
    assert results["verdict"] == "PASS" and results["counts"]["PASS"] == 1
    assert sum(results["counts"].values()) == 1  # the one case, passed
    # the shipped code is the document's, word for word
    doc = (ROOT / "docs" / "estimators.md").read_text()
    assert (EXAMPLE / "gyro_doppler.py").read_text() in doc


def _external_case(folder: Path, command: str, links: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    doc = (ROOT / "docs" / "estimators.md").read_text()  # its example estimator, saved beside the case
    code = re.search(r"```python\n(import numpy.*?class GyroDoppler.*?)```", doc, re.S)
    (folder / "gyro_doppler.py").write_text(code[1])
    path = folder / "mine.toml"
    path.write_text(f"""
[case]
id = "MINE"
title = "my estimator through the harness"
requirements = ["R"]

[scenario]
script = "{SHORT}"
duration = "5 s"

[sensors]
imu = {{ grade = "seed000", rate = "200 Hz" }}
doppler = "seed000"

[dut]
kind = "external"
command = "{command}"
config = {{ initial_position = [34.246, 108.909, 380.0], initial_heading = 45.0 }}
{links}
[run]
seeds = [3]

[[criterion]]
id = "HPOS"
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "20 m"
""")
    return path


@pytest.mark.parametrize("links", ["", '\n[dut.links]\ncan = { interface = "virtual" }\n'], ids=["no links", "virtual"])
def test_an_external_dut_on_the_virtual_can_bus_is_a_configuration_error_naming_file_and_key(tmp_path, links):
    case = _external_case(tmp_path / "cases", "{python} " + HARNESS, links)
    out = bench("run", str(case), "-o", str(tmp_path / "out"), cwd=tmp_path, timeout=120)
    assert out.code == 2, out.text
    key = "dut.links.can.interface" if links else "dut.links.can"
    assert f"{case}: {key}:" in out.err or f"mine.toml: {key}:" in out.err, out.text
    assert "virtual" in out.err and "cannot reach another process" in out.err, out.text
    assert "udp_multicast" in out.err  # what to write instead
    assert not (tmp_path / "out" / "recordings").exists()  # refused before anything ran


def test_an_external_dut_whose_interpreter_lacks_the_bench_is_reported_once_with_its_stderr(tmp_path):
    # `-S`: the bench's interpreter without its site-packages, as a plain `python` that is not
    # the bench's venv (the case folder does not hold the bench either)
    case = _external_case(tmp_path / "cases", "{python} -S " + HARNESS,
                          '\n[dut.links]\ncan = { interface = "udp_multicast", channel = "239.74.163.9" }\n')
    out = bench("run", str(case), "-o", str(tmp_path / "out"), cwd=tmp_path, timeout=120)
    assert out.code in (1, 3), out.text  # the DUT never started: not a PASS
    assert out.text.count("No module named 'bench'") == 1, out.text  # its stderr tail, once
    assert "{python}" in out.text  # how to run the bench's interpreter
    summary = (tmp_path / "out" / "summary.txt").read_text()
    assert summary.count("No module named 'bench'") == 1, summary
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    assert results["verdict"] != "PASS"
