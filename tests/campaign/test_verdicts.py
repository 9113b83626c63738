"""A campaign judges each case over its runs exactly as ``bench accept`` does: a Monte
Carlo mode over the runs, a comparison of two variants seed by seed, a negative control
the other way round; a case with a run missing is ERROR, never judged on fewer runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, prepare_case, run_case
from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.work import record_path

HERE = Path(__file__).parent

EXTRA = '''
[dut.variants.good]
description = "as the case's synthetic DUT"

[dut.variants.noisy]
synthetic = { error = [{ kind = "markov", quantity = "position", sigma = ["30 m", "30 m", "10 m"], tau = "10 s" }] }

# every run of the good variant fails this limit (2.5 m max over the seeds' 3 m sigma),
# but two runs of three meeting it is all it asks for (at 1.5 m it is met by none)
[[criterion]]
id = "POS-2-OF-3"
requirement = "CMP"
variant = "good"
metric = "accuracy.horizontal.max"
at_most = "9 m"
monte_carlo = { pass_runs = 2 }

[[criterion]]
id = "GOOD-BETTER"
requirement = "CMP"
variant = "good"
relative_to = "noisy"
metric = "accuracy.horizontal.rms"
at_most = 0.5

[[criterion]]
id = "CONTROL"
requirement = "CMP"
metric = "accuracy.horizontal.rms"
at_most = "8 m"
must_fail_on = ["noisy"]
'''


def _case(tmp_path: Path) -> Path:
    (tmp_path / "drive.toml").write_bytes((HERE / "drive.toml").read_bytes())
    text = (HERE / "case.toml").read_text().replace("seeds = [1]", "seeds = [1, 2, 3]")
    text = text.replace('at_most = "2.5 m"', 'at_most = "2.5 m"\nvariant = "good"').replace(
        'at_most = "5 m"', 'at_most = "5 m"\nvariant = "good"')
    case = tmp_path / "case.toml"
    case.write_text(text + EXTRA)
    return case


def _criteria(items) -> dict[tuple[str, str | None, bool], str]:
    return {(c["id"], c["variant"], c["control"]): c["verdict"] for c in items}


def test_a_campaign_judges_each_case_as_bench_accept_does(tmp_path):
    case_file = _case(tmp_path)
    result = run_campaign(CampaignOptions([str(case_file)], tmp_path / "campaign", runs=3, workers=2))
    judged = result["verdicts"]["CMP-SYN"]
    case = prepare_case(load_case(case_file), SuiteOptions(tmp_path / "accept", runs=3))
    accepted = run_case(case, SuiteOptions(tmp_path / "accept"))
    expected = {(cr.criterion.id, cr.variant, cr.control): cr.verdict.value for cr in accepted.criteria}
    assert _criteria(judged["criteria"]) == expected
    assert judged["verdict"] == accepted.verdict.value
    # what makes this case worth the comparison: the case-level criteria are judged over the runs
    got = _criteria(judged["criteria"])
    assert got["CONTROL", "noisy", True] == "PASS"  # the noisy DUT fails the control's limit, as it must
    assert got["GOOD-BETTER", "good", False] == "PASS"
    runs_of = result["aggregate"]["cases"]["CMP-SYN[noisy]"]
    assert "CONTROL" not in runs_of["criteria"]  # a control's value is no run verdict of its own


def test_a_case_missing_a_run_is_error(tmp_path):
    case_file = _case(tmp_path)
    out = tmp_path / "campaign"
    first = run_campaign(CampaignOptions([str(case_file)], out, workers=2))
    assert first["verdicts"]["CMP-SYN"]["verdict"] != "ERROR"
    record_path(out, first["aggregate"]["keys"][0]).unlink()

    def interrupt(state):
        if state.executed == 0 and state.done < state.total:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_campaign(CampaignOptions([str(case_file)], out, workers=1), interrupt)
    left = json.loads((out / "campaign.json").read_text())
    judged = left["verdicts"]["CMP-SYN"]
    assert not left["campaign"]["complete"]
    assert judged["verdict"] == "ERROR" and "1 of 6 planned runs have no record" in judged["errors"][0]


def test_a_record_lacking_a_criterion_makes_its_case_error(tmp_path):
    """A damaged record (valid, complete, but without a criterion its run judged, or without
    the raw value of a comparison) is never judged on fewer runs: the case is ERROR."""
    case_file = _case(tmp_path)
    out = tmp_path / "campaign"
    first = run_campaign(CampaignOptions([str(case_file)], out, workers=2))
    assert first["verdicts"]["CMP-SYN"]["verdict"] in ("PASS", "MARGINAL")
    records = {k: json.loads(record_path(out, k).read_text()) for k in first["aggregate"]["keys"]}
    good = next(k for k, r in records.items() if r["variant"] == "good")
    noisy = next(k for k, r in records.items() if r["variant"] == "noisy")
    for key, section, cid in ((good, "criteria", "POS-2-OF-3"), (noisy, "raw", "GOOD-BETTER")):
        damaged = dict(records[key])
        damaged[section] = {k: v for k, v in damaged[section].items() if k != cid}
        record_path(out, key).write_text(json.dumps(damaged))
        again = run_campaign(CampaignOptions([str(case_file)], out, workers=2))
        assert again["invocation"]["executed"] == 0  # the damaged record is reused, not run again
        judged = again["verdicts"]["CMP-SYN"]
        assert judged["verdict"] == "ERROR", (section, cid)
        assert any(f"lacks {cid}" in e for e in judged["errors"])
        record_path(out, key).write_text(json.dumps(records[key]))
