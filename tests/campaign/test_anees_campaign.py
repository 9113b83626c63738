"""A criterion judged by ANEES over the runs (``monte_carlo = { anees = ... }``) through
``bench accept`` and through ``bench campaign``: the same verdicts, the campaign's records
carrying each run's sampled NEES (record version 3; a record of version 2 runs again), and
the campaign report drawing the ANEES against its band."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scipy.stats import chi2

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, prepare_case, run_case
from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.work import RECORD_VERSION, load_record, record_path
from bench.report.campaign_figures import campaign_figures
from bench.report.campaign_report import build_campaign_report
from bench.report.results import case_json

HERE = Path(__file__).parent


def _case(tmp_path: Path) -> Path:
    for name in ("drive.toml", "anees_case.toml"):
        (tmp_path / name).write_bytes((HERE / name).read_bytes())
    return tmp_path / "anees_case.toml"


@pytest.fixture(scope="module")
def campaign20(tmp_path_factory) -> tuple[Path, dict]:
    """The case's campaign of 20 runs (the band of fewer runs cannot tell an error twice the
    sigma, whose control the case has: at 99 % the band of 6 runs reaches 3.1)."""
    tmp = tmp_path_factory.mktemp("anees20")
    case_file = _case(tmp)
    return case_file, run_campaign(CampaignOptions([str(case_file)], tmp / "campaign", runs=20, workers=2))


def _verdicts(items) -> dict[tuple[str, str | None, bool], tuple[str, float | None]]:
    return {(c["id"], c["variant"], c["control"]): (c["verdict"], c["value"]) for c in items}


def test_accept_and_campaign_judge_the_anees_mode_alike(tmp_path, campaign20):
    case_file, result = campaign20
    judged = result["verdicts"]["ANEES-SYN"]
    accepted = run_case(prepare_case(load_case(case_file), SuiteOptions(tmp_path / "accept", runs=20)),
                        SuiteOptions(tmp_path / "accept"))
    doc = case_json(accepted)
    assert _verdicts(judged["criteria"]) == _verdicts(doc["criteria"])
    assert judged["verdict"] == accepted.verdict.value == "PASS"
    got = {(c["id"], c["control"]): c for c in judged["criteria"]}
    honest, control = got["NEES-POS", False], got["NEES-POS", True]
    assert honest["verdict"] == "PASS" and control["verdict"] == "PASS"  # the overconfident DUT FAILs it
    assert honest["monte_carlo"] == "ANEES over 20 runs in its 99 % band"
    band = [chi2.ppf(0.005, 20) / 20, chi2.ppf(0.995, 20) / 20]  # chi-square(N) / N, N = 20 runs
    assert honest["anees"]["band"] == pytest.approx(band) and honest["anees"]["runs"] == 20
    assert control["anees"]["above"] == 1.0
    # the same series and band in results.json's criterion
    acc = {(c["id"], c["control"]): c for c in doc["criteria"]}
    assert acc["NEES-POS", False]["anees"] == honest["anees"]


def test_records_carry_the_series_and_a_record_of_version_2_runs_again(tmp_path):
    case_file = _case(tmp_path)
    out = tmp_path / "campaign"
    first = run_campaign(CampaignOptions([str(case_file)], out, runs=2, workers=1))
    assert RECORD_VERSION == 3
    recs = {k: json.loads(record_path(out, k).read_text()) for k in first["aggregate"]["keys"]}
    honest = next(k for k, r in recs.items() if r["variant"] == "honest")
    control = next(k for k, r in recs.items() if r["variant"] == "overconfident")
    series = recs[honest]["criteria"]["NEES-POS"]["series"]
    assert series["dof"] == 3 and series["nees_grid"]["step_s"] == 1.0 and len(series["nees_grid"]["values"]) >= 15
    assert "series" in recs[control]["raw"]["NEES-POS"]  # the negative control's too
    assert "series" not in recs[honest]["criteria"]["NEES-POS-RUN"]  # judged run by run: no series
    # a record of the previous version (no series) is not reused: the run runs again
    old = {**recs[honest], "version": 2}
    old["criteria"] = {k: {f: x for f, x in v.items() if f != "series"} for k, v in old["criteria"].items()}
    record_path(out, honest).write_text(json.dumps(old))
    assert load_record(out, honest) is None
    again = run_campaign(CampaignOptions([str(case_file)], out, runs=2, workers=1))
    assert again["invocation"]["executed"] == 1
    assert again["verdicts"]["ANEES-SYN"] == first["verdicts"]["ANEES-SYN"]  # the same recording, judged alike
    assert "series" in load_record(out, honest)["criteria"]["NEES-POS"]


def test_a_record_without_its_series_makes_the_case_error(tmp_path):
    """A record of the current version that lost a series (damaged, edited) is never judged
    on fewer runs: the ANEES criterion is ERROR, and so is the case."""
    case_file = _case(tmp_path)
    out = tmp_path / "campaign"
    first = run_campaign(CampaignOptions([str(case_file)], out, runs=2, workers=1))
    key = next(k for k in first["aggregate"]["keys"] if load_record(out, k)["variant"] == "honest")
    rec = load_record(out, key)
    del rec["criteria"]["NEES-POS"]["series"]
    record_path(out, key).write_text(json.dumps(rec))
    again = run_campaign(CampaignOptions([str(case_file)], out, runs=2, workers=1))
    judged = {(c["id"], c["control"]): c for c in again["verdicts"]["ANEES-SYN"]["criteria"]}
    assert judged["NEES-POS", False]["verdict"] == "ERROR"
    assert "carries no sampled NEES series" in judged["NEES-POS", False]["reason"]
    assert again["verdicts"]["ANEES-SYN"]["verdict"] == "ERROR"


def test_the_campaign_report_draws_the_anees_against_its_band(tmp_path, campaign20):
    _case_file, doc = campaign20
    figs = campaign_figures(doc["aggregate"], doc["verdicts"])
    honest = {f.key: f for f in figs["ANEES-SYN[honest]"]}
    control = {f.key: f for f in figs["ANEES-SYN[overconfident]"]}
    fig = honest["anees-NEES-POS"]
    band = [chi2.ppf(0.005, 20) / 20, chi2.ppf(0.995, 20) / 20]
    assert [fig.values["band_low"], fig.values["band_high"]] == pytest.approx(band)
    assert fig.values["runs"] == 20 and fig.png.startswith(b"\x89PNG") and "ANEES" in fig.caption
    assert control["anees-NEES-POS-control"].values["above"] == 1.0
    assert {"anees-NEES-HDG", "anees-NEES-POS"} <= set(honest)
    files = build_campaign_report(doc, tmp_path / "report", pdf=False, workers=1)
    html = files.html.read_text()
    assert "NEES-POS, ANEES over 20 runs" in html and "NEES-POS, must FAIL, ANEES over 20 runs" in html
    assert "99 % band of 20 runs, chi-square(20) / 20" in html
