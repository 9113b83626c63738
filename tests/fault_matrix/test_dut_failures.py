"""The fault matrix (issue 32), a DUT's failure: a DUT that crashes, hangs or floods has
failed its acceptance run, in every DUT kind -- in process, external, hardware and batch --
and the bench says FAIL with the reason, never ERROR ("rerun the bench").

Every row runs ``bench run`` as a user would (tests/fault_matrix/matrix.py: exit code, no
traceback, nothing left running) and checks that the FAIL is the DUT's failure with its
reason everywhere a reviewer reads it: exit 1; ``results.json`` (case and run FAIL, the
reason among the run's ``dut_issues``, no bench issue, no case error); ``summary.txt``;
``junit.xml`` (failures, no errors); the recording (readable, ``run_end`` ``dut_failed``)
and ``bench score`` of it (FAIL again). A control row per kind runs the same DUT behaving:
it PASSes, so each row is about the failure.

On 57b1bce every in-process, external and hardware row ended ERROR, exit 3 (``dut_error``);
an in-process estimator that hung hung the bench, and one calling ``sys.exit`` ended it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import uuid
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bench.record.mcap_io import RecordingReader
from tests.fault_matrix.matrix import bench
from tests.run.robust_util import MISBEHAVE, SHORT, dut_command

HERE = Path(__file__).parent
UNIT = HERE / "hardware_unit.py"
BATCH_CASE = HERE.parent / "exchange" / "batch_case.toml"
BATCH_DUT = HERE.parent / "exchange" / "batch_dut.py"

CASE = """
[case]
id = "DF"
title = "a DUT that fails"
requirements = ["R"]
shortened = "3 s: the DUT fails at 1 s"

[scenario]
script = "{short}"
duration = "3 s"

[sensors]
imu = {{ grade = "navigation", rate = "200 Hz" }}

[dut]
{dut}
startup_timeout = "60 s"  # hang guards, not speed bounds
shutdown_timeout = "{shutdown}"
{links}
[clock]
timeout = "{timeout}"

[run]
seeds = [1]

[scoring.integrity]
invalid_fraction = {{ check = false, reason = "the test DUT flags its epochs invalid" }}
quality_unmatched = {{ check = false, reason = "the test DUT sends no NAV_QUALITY" }}

[[criterion]]
id = "RATE"
requirement = "R"
metric = "output.rate"
at_least = "90 Hz"
"""

#: how -> (misbehave mode, its config, the reason's words, the lockstep timeout)
HOW = {
    "crash": ("crash_raise", {}, "filter diverged at 1.00 s", "60 s"),
    "exit": ("crash_exit", {}, "exited with code 3", "60 s"),
    "hang": ("hang", {}, "", "3 s"),
    "flood": ("flood", {"flood_frames": 5000}, "floods", "60 s"),
}
HANG = {"in_process": "did not return from its step at bench time 1.000 s within the step timeout of 3 s",
        "external": "no DUT_READY for bench time 1.000 s within 3 s (the DUT hangs",
        "hardware": "no DUT_READY for bench time 1.000 s within 3 s (the DUT hangs"}


def _config(tmp_path: Path, mode: str, extra: dict) -> dict:
    return {"mode": mode, "at_s": 1.0, **extra, "pid_file": str(tmp_path / "pids")}


def _write(tmp_path: Path, dut: str, links: str = "", timeout: str = "60 s") -> Path:
    # a hung DUT (the misbehave harness finishes its sleep before it acts on SIGTERM) is
    # killed after the shutdown timeout: short where the DUT hangs, generous elsewhere
    shutdown = "5 s" if timeout == "3 s" else "60 s"
    case = tmp_path / "case.toml"
    case.write_text(CASE.format(short=SHORT, dut=dut, links=links, timeout=timeout, shutdown=shutdown))
    return case


def _toml(d: dict) -> str:
    return "{ " + ", ".join(f"{k} = {json.dumps(v)}" for k, v in d.items()) + " }"


def _failed(tmp_path: Path, out: Path, reason: str, **kw) -> None:
    """The run FAILed, the reason everywhere, nothing called ERROR."""
    r = bench("run", str(tmp_path / "case.toml"), "-o", str(out), "--no-plots", cwd=tmp_path, expect=1, **kw)
    case = json.loads((out / "results.json").read_text())["cases"][0]
    run = case["runs"][0]
    assert case["verdict"] == "FAIL" and not case["errors"], case["errors"]
    assert run["verdict"] == "FAIL" and not run["bench_issues"], run["bench_issues"]
    assert any(reason in i for i in run["dut_issues"]), run["dut_issues"]
    assert reason in (out / "summary.txt").read_text()
    junit = ET.parse(out / "junit.xml").getroot()
    assert list(junit.iter("failure")) and not list(junit.iter("error"))
    assert "FAIL" in r.out and reason in r.text
    rec = out / "recordings" / "DF" / "DF-s1.mcap"
    with RecordingReader(rec) as r:  # (bench info would show the DUT's own traceback, kept in the recording)
        assert r.intact and r.metadata()["run_end"]["status"] == "dut_failed"
    bench("score", str(rec), cwd=tmp_path, expect=1, **kw)


def _passed(tmp_path: Path, out: Path, **kw) -> None:
    bench("run", str(tmp_path / "case.toml"), "-o", str(out), "--no-plots", "-q", cwd=tmp_path, expect=0, **kw)


# --------------------------------------------------------------------------- in process
@pytest.mark.parametrize("how", list(HOW))
def test_an_in_process_estimator_that_crashes_exits_hangs_or_floods_fails(tmp_path, how):
    (tmp_path / "misbehave.py").write_text(MISBEHAVE.read_text())  # a module beside the case
    mode, extra, reason, timeout = HOW[how]
    reason = {"crash": "raised at bench time 1.000 s: RuntimeError: filter diverged at 1.00 s",
              "exit": "called exit(3) at bench time 1.000 s", "hang": HANG["in_process"],
              "flood": "floods: 5000 epochs"}[how]
    config = _toml(_config(tmp_path, mode, extra))
    _write(tmp_path, f'kind = "in_process"\nname = "misbehave:Misbehave"\nconfig = {config}', timeout=timeout)
    _failed(tmp_path, tmp_path / "out", reason)
    if how == "crash":  # and the certification report a reviewer signs says it too
        bench("report", str(tmp_path / "out"), "-o", str(tmp_path / "report"), "--no-pdf", "-q", cwd=tmp_path,
              expect=1)
        html = (tmp_path / "report" / "report.html").read_text()
        assert "DUT: " in html and "filter diverged at 1.00 s" in html and 'data-verdict="FAIL"' in html


def test_the_in_process_estimator_behaving_passes(tmp_path):
    (tmp_path / "misbehave.py").write_text(MISBEHAVE.read_text())
    _write(tmp_path, f'kind = "in_process"\nname = "misbehave:Misbehave"\n'
                     f'config = {_toml(_config(tmp_path, "slow", {}))}')
    _passed(tmp_path, tmp_path / "out")


# --------------------------------------------------------------------- external (a netns)
def _external(tmp_path: Path, mode: str, extra: dict, timeout: str = "60 s") -> None:
    channel = f"239.74.168.{uuid.uuid4().int % 250 + 1}"
    command = dut_command(None, None, MISBEHAVE)
    _write(tmp_path, f'kind = "external"\ncommand = "{command}"\nconfig = {_toml(_config(tmp_path, mode, extra))}',
           links=f'\n[dut.links]\ncan = {{ interface = "udp_multicast", channel = "{channel}" }}\n', timeout=timeout)


@pytest.mark.parametrize("how", list(HOW))
def test_an_external_dut_that_crashes_exits_hangs_or_floods_fails(ns, tmp_path, how):
    mode, extra, reason, timeout = HOW[how]
    reason = {"crash": "the DUT process exited with code 1 at bench time 1.0", "exit": "exited with code 3",
              "hang": HANG["external"], "flood": "the DUT floods the bus"}[how]
    _external(tmp_path, mode, extra, timeout)
    _failed(tmp_path, tmp_path / "out", reason, ns=ns)


def test_the_external_dut_behaving_passes(ns, tmp_path):
    _external(tmp_path, "slow", {})
    _passed(tmp_path, tmp_path / "out", ns=ns)


# --------------------------------------------------------------------- hardware (a netns)
class _Unit:
    """The hardware stand-in (hardware_unit.py) running in the namespace, started by the test."""

    def __init__(self, ns: str, tmp_path: Path, config: dict):
        self.channel = f"239.74.169.{uuid.uuid4().int % 250 + 1}"
        cfg = tmp_path / "unit.json"
        cfg.write_text(json.dumps(config))
        self.proc = subprocess.Popen(["ip", "netns", "exec", ns, sys.executable, str(UNIT), "--channel", self.channel,
                                      "--config", str(cfg)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                     env={**os.environ, "PYTHONPATH": str(HERE.parent.parent)})
        assert self.proc.stdout is not None
        self.ports = json.loads(self.proc.stdout.readline())

    def links(self) -> str:
        return (f'\n[dut.links]\ncan = {{ interface = "udp_multicast", channel = "{self.channel}" }}\n'
                f'imu = {{ port = "{self.ports["imu"]}", baud = 460800 }}\n'
                f'gnss = {{ port = "{self.ports["gnss"]}", baud = 115200 }}\n')

    def close(self) -> None:
        self.proc.terminate()  # a hung unit acts on it only after its sleep: killed after a while
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def _hardware(ns: str, tmp_path: Path, mode: str, extra: dict, timeout: str = "60 s") -> _Unit:
    unit = _Unit(ns, tmp_path, _config(tmp_path, mode, extra))
    _write(tmp_path, 'kind = "hardware"', links=unit.links(), timeout=timeout)
    return unit


@pytest.mark.parametrize("how", list(HOW))
def test_a_hardware_dut_that_crashes_exits_hangs_or_floods_fails(ns, tmp_path, how):
    mode, extra, _, timeout = HOW[how]
    # a unit that dies goes silent on its links: the bench sees no DUT_READY, as for a hang
    reason = {"crash": "no DUT_READY for bench time 1.0", "exit": "no DUT_READY for bench time 1.0",
              "hang": HANG["hardware"], "flood": "the DUT floods the bus"}[how]
    if how in ("crash", "exit"):
        timeout = "3 s"
    unit = _hardware(ns, tmp_path, mode, extra, timeout)
    try:
        _failed(tmp_path, tmp_path / "out", reason, ns=ns)
    finally:
        unit.close()


def test_the_hardware_dut_behaving_passes(ns, tmp_path):
    unit = _hardware(ns, tmp_path, "slow", {})
    try:
        _passed(tmp_path, tmp_path / "out", ns=ns)
    finally:
        unit.close()


# ------------------------------------------------------------------------------- batch
def _batch(tmp_path: Path, mode: str, timeout: str = "60 s") -> None:
    text = BATCH_CASE.read_text().replace('id = "BATCH"', 'id = "DF"')
    text = text.replace('"batch_dut.py"', json.dumps(str(BATCH_DUT))).replace('"truth"]', f'"{mode}"]')
    text = text.replace('duration = "30 s"', 'duration = "5 s"').replace('timeout = "60 s"', f'timeout = "{timeout}"')
    (tmp_path / "case.toml").write_text(text)


@pytest.mark.parametrize(
    ("mode", "timeout", "reason"),
    [
        ("fail", "60 s", "the batch DUT exited with code 3 (last output: fatal: no GNSS fix to initialise from)"),
        ("hang", "1 s", "the batch DUT did not finish within its timeout of 1 s (killed)"),
        ("flood", "60 s", "floods"),
    ],
    ids=["crash", "hang", "flood"],
)
def test_a_batch_dut_that_crashes_hangs_or_floods_fails(tmp_path, mode, timeout, reason):
    _batch(tmp_path, mode, timeout)
    _failed(tmp_path, tmp_path / "out", reason)


def test_the_batch_dut_behaving_passes(tmp_path):
    _batch(tmp_path, "truth")
    _passed(tmp_path, tmp_path / "out")
