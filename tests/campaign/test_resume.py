"""An interrupted campaign (SIGINT, SIGKILL) continues where it stopped: the second start
runs only the missing runs, and the aggregate equals an uninterrupted campaign's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from bench.campaign.campaign import CampaignOptions, run_campaign
from tests.campaign.conftest import CASE, bench_command, bench_env

RUNS = 8


def _records(out: Path) -> list[Path]:
    return sorted((out / "runs").glob("*.json")) if (out / "runs").is_dir() else []


def _start(out: Path) -> subprocess.Popen:
    cmd = bench_command("campaign", str(CASE), "--runs", str(RUNS), "--workers", "1", "-o", str(out), "-q")
    return subprocess.Popen(cmd, env=bench_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=_as_from_a_terminal)


def _as_from_a_terminal() -> None:
    """SIGINT handled as in a terminal (a test runner started in the background ignores it,
    and an ignored SIGINT stays ignored in the campaign, as bench.cli.app documents)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for_first_record(proc: subprocess.Popen, out: Path, limit_s: float = 240.0) -> None:
    end = time.monotonic() + limit_s  # a bound against a hang, not a timing assertion
    while not _records(out):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, "no run record appeared"
        time.sleep(0.02)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("whole")
    return run_campaign(CampaignOptions([str(CASE)], out, runs=RUNS, workers=2,
                                        env={"PYTHONPATH": bench_env()["PYTHONPATH"]}))


@pytest.mark.parametrize("how", ["SIGINT", "SIGKILL"])
def test_an_interrupted_campaign_runs_only_what_is_missing(tmp_path, uninterrupted, how):
    out = tmp_path / "campaign"
    proc = _start(out)
    _wait_for_first_record(proc, out)
    if how == "SIGINT":
        os.kill(proc.pid, signal.SIGINT)  # the campaign's Ctrl-C: it stops its workers
    else:
        os.killpg(proc.pid, signal.SIGKILL)  # the campaign and its workers die at once
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0, err
    first = len(_records(out))
    assert 1 <= first < RUNS, f"{first} of {RUNS} runs recorded before the {how}"
    if how == "SIGINT":  # the campaign wrote what it had before it stopped
        stopped = json.loads((out / "campaign.json").read_text())
        assert not stopped["campaign"]["complete"] and stopped["aggregate"]["runs"] == first

    again = subprocess.run(bench_command("campaign", str(CASE), "--runs", str(RUNS), "--workers", "2", "-o",
                                         str(out), "-q"), env=bench_env(), capture_output=True, text=True,
                           timeout=600)
    assert again.returncode in (0, 1), again.stderr
    result = json.loads((out / "campaign.json").read_text())
    assert result["invocation"]["executed"] == RUNS - first
    assert result["invocation"]["reused"] == first
    assert result["campaign"]["complete"]
    assert result["aggregate"] == uninterrupted["aggregate"]


def test_a_complete_campaign_runs_nothing_again(tmp_path):
    out = tmp_path / "c"
    options = CampaignOptions([str(CASE)], out, runs=2, workers=1)
    run_campaign(options)
    again = run_campaign(options)
    assert again["invocation"] == {**again["invocation"], "executed": 0, "reused": 2}
