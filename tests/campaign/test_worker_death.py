"""A run that kills its worker process is recorded ERROR naming the worker, and the runs
beside it are not lost (local processes and a Dask LocalCluster)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.guard import DEATH

from .conftest import bench_env

HERE = Path(__file__).parent


@pytest.mark.parametrize("scheduler", [None, "local"])
def test_a_run_that_kills_its_worker_is_an_error_naming_it(tmp_path, scheduler):
    env = {"PYTHONPATH": bench_env()["PYTHONPATH"], "BENCH_TEST_CRASH_DUT": "1"}
    result = run_campaign(CampaignOptions([str(HERE / "crash_case.toml")], tmp_path, workers=2,
                                          scheduler=scheduler, env=env))
    assert result["campaign"]["complete"] and result["invocation"]["lost"] == []
    groups = result["aggregate"]["cases"]
    assert groups["CMP-CRASH[crash]"]["verdicts"] == {"ERROR": 2}
    assert groups["CMP-CRASH[origin]"]["verdicts"] == {"PASS": 2}  # run to their end beside the crashes
    assert result["verdicts"]["CMP-CRASH"]["verdict"] == "ERROR"
    records = [json.loads(p.read_text()) for p in (tmp_path / "runs").glob("*.json")]
    crashed = [r for r in records if r["variant"] == "crash"]
    assert len(crashed) == 2
    for r in crashed:
        (issue,) = r["bench_issues"]
        assert issue.startswith(DEATH) and f"process {r['worker']['pid']} on {r['worker']['host']}" in issue
    assert not list((tmp_path / "runs").glob("*.running"))
    # a second start reuses the ERROR records; --retry-errors runs exactly those again
    again = run_campaign(CampaignOptions([str(HERE / "crash_case.toml")], tmp_path, workers=2, env=env))
    assert again["invocation"]["executed"] == 0
    retried = run_campaign(CampaignOptions([str(HERE / "crash_case.toml")], tmp_path, workers=2, env=env,
                                           retry_errors=True))
    assert retried["invocation"]["executed"] == 2
    assert retried["aggregate"]["cases"]["CMP-CRASH[crash]"]["verdicts"] == {"ERROR": 2}
