"""Run records: written only for a finished run; an interrupted run leaves none and is lost."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.plan import plan_campaign
from bench.campaign.work import RECORD_VERSION, execute_run, load_record, record_path

HERE = Path(__file__).parent


def _copy(tmp_path: Path, status: str | None = None) -> Path:
    (tmp_path / "drive.toml").write_bytes((HERE / "drive.toml").read_bytes())
    text = (HERE / "case.toml").read_text()
    if status:
        text = text.replace("[dut.synthetic]\n", f'[dut.synthetic]\nbench_status = "{status}"\n', 1)
    case = tmp_path / "case.toml"
    case.write_text(text)
    return case


def test_a_record_is_small_and_complete(tmp_path):
    (run,) = plan_campaign([_copy(tmp_path)], runs=1)
    out = tmp_path / "out"
    rec = execute_run(run, str(out))
    assert load_record(out, run.key) == rec
    assert rec["complete"] and rec["key"] == run.key and rec["seed"] == run.seed
    assert (out / rec["recording"]).is_file()
    pos = rec["criteria"]["POS"]
    assert set(pos) == {"value", "verdict", "reason", "worse", "unit", "display", "comparator", "limit_text",
                        "limit", "marginal_band", "metric", "window", "requirements"}
    assert pos["unit"] == "m" and pos["limit"] == {"low": None, "high": 2.5} and pos["limit_text"] == "<= 2.5 m"
    assert pos["metric"] == "accuracy.horizontal.max" and pos["requirements"] == ["CMP"]
    assert pos["display"] == pytest.approx(pos["value"])  # metres: display unit = SI
    invalid = rec["criteria"]["INTEGRITY-missing"]  # a fraction shown in %
    assert invalid["unit"] == "%" and invalid["limit"]["high"] == pytest.approx(0.1)
    assert rec["version"] == RECORD_VERSION == 3 and rec["sweep_axes"] is None
    assert not list((out / "runs").glob("*.tmp"))
    record_path(out, run.key).write_text(json.dumps({**rec, "complete": False}))
    assert load_record(out, run.key) is None  # an incomplete record runs again
    record_path(out, run.key).write_text(json.dumps({**rec, "version": 2}))
    assert load_record(out, run.key) is None  # a record of another version runs again
    result = run_campaign(CampaignOptions([str(tmp_path / "case.toml")], out, runs=1, workers=1))
    assert result["invocation"]["executed"] == 1 and load_record(out, run.key)["version"] == 3


def test_an_interrupted_run_writes_no_record_and_the_campaign_is_incomplete(tmp_path):
    case = _copy(tmp_path, "interrupted")
    out = tmp_path / "out"
    result = run_campaign(CampaignOptions([str(case)], out, runs=2, workers=1))
    assert result["invocation"]["executed"] == 0 and len(result["invocation"]["lost"]) == 2
    assert not result["campaign"]["complete"] and len(result["campaign"]["missing"]) == 2
    assert not list((out / "runs").glob("*.json")) if (out / "runs").exists() else True


def test_stale_records_are_named_and_pruned_only_when_asked(tmp_path):
    case = _copy(tmp_path)
    out = tmp_path / "out"
    first = run_campaign(CampaignOptions([str(case)], out, runs=2, workers=1))
    assert first["campaign"]["stale"] == []
    keys = first["aggregate"]["keys"]
    case.write_text(case.read_text().replace('at_most = "5 m"', 'at_most = "6 m"'))  # every key changes
    (run,) = plan_campaign([case], seeds=(1,))
    kept = run_campaign(CampaignOptions([str(case)], out, seeds=(1,), workers=1))
    assert kept["campaign"]["stale"] == sorted(keys) and kept["aggregate"]["keys"] == [run.key]
    assert all(record_path(out, k).exists() for k in keys)  # named, not deleted
    old_recordings = [out / load_record(out, k)["recording"] for k in keys]
    assert all(p.exists() for p in old_recordings)
    pruned = run_campaign(CampaignOptions([str(case)], out, seeds=(1,), workers=1, prune=True))
    assert pruned["campaign"]["stale"] == [] and pruned["invocation"]["executed"] == 0
    assert not any(record_path(out, k).exists() for k in keys) and not any(p.exists() for p in old_recordings)
    assert (out / load_record(out, run.key)["recording"]).exists()  # the campaign's own run kept


def test_a_run_that_cannot_run_is_an_error_record_with_its_traceback(tmp_path):
    case = _copy(tmp_path)
    (run,) = plan_campaign([case], runs=1)
    case.unlink()  # the case file gone after planning: the worker cannot load it
    out = tmp_path / "out"
    rec = execute_run(run, str(out))
    assert rec["verdict"] == "ERROR" and rec["complete"] and rec["criteria"] == {}
    assert "case.toml" in rec["bench_issues"][0]
    (log,) = (out / "recordings").rglob("bench-error.log")
    text = log.read_text()
    assert f"bench campaign: {run.label}" in text and "Traceback" in text
    assert load_record(out, run.key) == rec
