"""The fault matrix (issue 32), campaigns: a campaign folder is held by one campaign at a
time. A second `bench campaign` on the same folder is refused at once (exit 2) naming the
holder; a campaign killed with SIGKILL leaves a lock the next start takes over; a case
that ends ERROR says why in campaign.json (what every row checks: test_inputs.py).

The rows synchronise on files appearing (a run's marker, a run's record) and on a stopped
process (SIGSTOP: a campaign that cannot move still holds its folder), never on sleeps."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import time
import uuid
from pathlib import Path

import pytest

from tests.fault_matrix.matrix import BENCH, MARK, _marked, bench, case

RUNS = 3


def _args(path: Path, out: Path, runs: int = RUNS) -> list[str]:
    return ["campaign", str(path), "--runs", str(runs), "--workers", "1", "-o", str(out), "-q", "--no-report"]


def _start(path: Path, out: Path, mark: str, runs: int = RUNS) -> subprocess.Popen:
    """``bench campaign`` in the background, its output in files beside ``out`` (a pipe would
    be held open by any process it leaves behind)."""
    log = out.parent / f"{out.name}.log"
    with open(log, "w") as fh:
        return subprocess.Popen([*BENCH, *_args(path, out, runs)], cwd=out.parent, text=True,
                                env={**os.environ, MARK: mark, "COLUMNS": "200"}, stdout=fh, stderr=fh)


def _output(out: Path) -> str:
    return (out.parent / f"{out.name}.log").read_text()


def _wait_for(proc: subprocess.Popen, folder: Path, pattern: str) -> None:
    end = time.monotonic() + 240.0  # a bound against a hang, not a timing assertion
    while not (folder.is_dir() and any(folder.glob(pattern))):
        assert proc.poll() is None, _output(folder.parent)
        assert time.monotonic() < end, f"no {pattern} appeared in {folder}"
        time.sleep(0.02)


def _end_marked(mark: str) -> None:
    """Kill what this row started and left running (only processes carrying its marker)."""
    for pid in _marked(mark):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def _records(out: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*.json"))]


def test_a_second_campaign_on_a_folder_is_refused_at_once_and_the_first_finishes_clean(tmp_path):
    path = case(tmp_path / "cases")
    out = tmp_path / "campaign"
    mark = uuid.uuid4().hex
    first = _start(path, out, mark)
    try:
        _wait_for(first, out / "runs", "*.running")  # the first campaign is running a run
        os.kill(first.pid, signal.SIGSTOP)  # stopped, it still holds the folder, however long the second takes
        try:
            second = bench(*_args(path, out), cwd=tmp_path)
        finally:
            os.kill(first.pid, signal.SIGCONT)
        first.wait(timeout=240)
    finally:
        _end_marked(mark)
    assert second.code == 2, second.text
    assert f"pid {first.pid}" in second.err and socket.gethostname() in second.err and "since" in second.err
    assert str(out) in second.err
    assert first.returncode == 0, _output(out)
    records = _records(out)
    assert len(records) == RUNS and {r["verdict"] for r in records} == {"PASS"}
    result = json.loads((out / "campaign.json").read_text())
    assert result["campaign"]["complete"] and result["invocation"]["executed"] == RUNS
    assert result["verdicts"]["M10"]["verdict"] == "PASS" and result["verdicts"]["M10"]["errors"] == []
    assert not list(out.rglob("bench-error.log"))
    assert not list((out / "runs").glob("*.running"))


def test_a_campaign_killed_midway_leaves_a_lock_the_next_start_takes_over(tmp_path):
    path = case(tmp_path / "cases")
    out = tmp_path / "campaign"
    runs = 6  # the kill comes within the second run of six
    mark = uuid.uuid4().hex
    first = _start(path, out, mark, runs)
    try:
        _wait_for(first, out / "runs", "*.json")  # a run recorded, the next one under way
        os.kill(first.pid, signal.SIGKILL)  # `kill -9 PID`: the campaign alone; its workers must end with it
        first.wait(timeout=120)
        end = time.monotonic() + 60.0  # the kernel reaping the workers (a hang guard)
        while (left := _marked(mark)) and time.monotonic() < end:
            time.sleep(0.05)
        assert not left, f"workers of the killed campaign left running: {left}"
    finally:
        _end_marked(mark)
    recorded = len(_records(out))
    assert 1 <= recorded < runs
    lock = out / "campaign.lock"
    assert lock.is_file(), sorted(p.name for p in out.iterdir())
    assert json.loads(lock.read_text())["pid"] == first.pid  # the killed campaign named in its lock

    again = bench(*_args(path, out, runs), cwd=tmp_path, expect=0)
    assert "taken over" in again.err and f"pid {first.pid}" in again.err, again.text
    result = json.loads((out / "campaign.json").read_text())
    assert result["campaign"]["complete"] and result["verdicts"]["M10"]["verdict"] == "PASS"
    assert result["invocation"]["executed"] == runs - recorded and result["invocation"]["reused"] == recorded
    assert result["invocation"]["took_over"]["pid"] == first.pid
    assert {r["verdict"] for r in _records(out)} == {"PASS"} and len(_records(out)) == runs
    assert not list(out.rglob("bench-error.log")) and not list((out / "runs").glob("*.running"))
    assert lock.read_text() == ""  # released: the next start finds it free
    assert "lock" not in bench(*_args(path, out, runs), cwd=tmp_path, expect=0).err  # free: nothing to say


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        # 2 runs cannot show the 5 passing runs the criterion asks for: every run PASSes, the case is ERROR
        ({"limit": 'at_most = "1 m"\nmonte_carlo = { pass_runs = 5 }', "run": "seeds = [1, 2, 3, 4, 5]"},
         "criterion H: ERROR: 2 runs cannot show 5 passing runs"),
        # the bench missed its timing budget in every run (the synthetic DUT's test hook): runs ERROR
        ({"dut_extra": 'bench_status = "timing_budget"'}, "run ERROR (seeds 1, 2): run ended with status "
                                                           "'timing_budget'"),
    ],
    ids=["criterion", "run"],
)
def test_a_case_that_ends_error_says_why_in_campaign_json(tmp_path, edit, said):
    path = case(tmp_path / "cases", **edit)
    out = tmp_path / "campaign"
    r = bench(*_args(path, out, 2), cwd=tmp_path, expect=3)
    judged = json.loads((out / "campaign.json").read_text())["verdicts"]["M10"]
    assert judged["verdict"] == "ERROR"
    assert any(e.startswith(said) for e in judged["errors"]), judged["errors"]
    assert said in r.out  # and on the terminal
    assert len(_records(out)) == 2 and not list(out.rglob("bench-error.log"))  # an ERROR verdict, not a crash
