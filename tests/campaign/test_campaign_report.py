"""The campaign report: its figures mark the aggregate's numbers, its page names every group
and criterion (and an incomplete campaign), its PDF is made; and a real swept campaign run
through ``bench campaign`` ends with the sweep's figures in its report."""

from __future__ import annotations

import html
import json
import subprocess

import pypdf
import pytest

from bench.campaign.aggregate import aggregate
from bench.report.campaign_figures import campaign_figures
from bench.report.campaign_report import build_campaign_report
from tests.campaign.conftest import HERE, bench_command, bench_env
from tests.campaign.test_aggregate_sweep import rec

KEY = "sensors.bds.latency"


def _campaign(complete: bool = True) -> dict:
    axes = [[KEY, ["80 ms", "20 ms", "150 ms"]]]
    values = {"20 ms": [10.0, 12.0, 30.0], "80 ms": [40.0, 60.0, 45.0], "150 ms": [70.0, 90.0, 80.0]}
    recs = [rec(f"{x}{i}", i, [[KEY, x]], v, axes) for x, vs in values.items() for i, v in enumerate(vs)]
    recs.append({**rec("plain", 7, [], 20.0), "case_id": "S000"})
    missing = [] if complete else ["f" * 64]
    doc = {"campaign": {"paths": ["test_cases/"], "planned": len(recs) + len(missing), "complete": complete,
                        "missing": missing},
           "aggregate": aggregate(recs),
           "invocation": {"executed": len(recs), "reused": 0, "lost": [], "workers": 2, "scheduler": "processes"}}
    return json.loads(json.dumps(doc))  # as read back from campaign.json


def test_the_figures_mark_the_aggregates_numbers():
    doc = _campaign()
    agg = doc["aggregate"]
    figs = campaign_figures(agg)
    assert set(figs) == {*agg["cases"], "sweep:S001"}
    dist = {f.key: f for f in figs["S000"]}["dist-LAT"]
    assert dist.values["limit_high"] == 50.0 == agg["cases"]["S000"]["criteria"]["LAT"]["limit"]["high"]
    assert dist.values["limit_lines"] == [50.0] and dist.values["p50"] == 20.0
    rates = {f.key: f for f in figs["S000"]}["pass-rates"]
    assert rates.values["names"] == ["(run)", "LAT"] and rates.values["pass_rate"] == [1.0, 1.0]
    sweep = {f.key: f for f in figs["sweep:S001"]}
    axis = agg["sweeps"]["S001"]["axes"][0]
    metric = sweep["sweep-0-LAT"]
    assert metric.values["x"] == [80.0, 20.0, 150.0]  # the parsed values, in declaration order
    assert metric.values["limit_high"] == 50.0 and metric.values["median"] == [45.0, 12.0, 80.0]
    curve = sweep["sweep-0-pass-rate"]
    assert curve.values["x"] == [80.0, 20.0, 150.0]
    assert curve.values["pass_rate"] == [p["pass_rate"] for p in axis["points"]]
    assert curve.values["pass_rate:LAT"] == [p["criteria"]["LAT"]["pass_rate"] for p in axis["points"]]
    assert curve.values["interval_low"] == [p["pass_rate_interval"][0] for p in axis["points"]]
    assert all(f.alt and f.caption and f.png.startswith(b"\x89PNG") for fs in figs.values() for f in fs)


def test_a_categorical_sweep_is_drawn_at_its_positions():
    recs = [rec("a", 1, [["scenario.defaults.gnss", "urban"]], 10.0, [["scenario.defaults.gnss", ["urban", "open"]]]),
            rec("b", 2, [["scenario.defaults.gnss", "open"]], 60.0, [["scenario.defaults.gnss", ["urban", "open"]]])]
    curve = {f.key: f for f in campaign_figures(aggregate(recs))["sweep:S001"]}["sweep-0-pass-rate"]
    assert curve.values["x"] == [0.0, 1.0] and curve.values["pass_rate"] == [1.0, 0.0]


def test_the_report_names_every_group_and_criterion_and_says_it_is_incomplete(tmp_path):
    files = build_campaign_report(_campaign(complete=False), tmp_path, workers=2)
    page = html.unescape(files.html.read_text(encoding="utf-8"))
    for label in _campaign()["aggregate"]["cases"]:
        assert f'data-group="{label}"' in page
    assert 'data-criterion="LAT"' in page and "&lt;= 50 ms" not in page and "<= 50 ms" in page
    assert 'id="incomplete"' in page and "10 of 11 planned runs" in page
    assert 'data-figure="sweep-0-pass-rate"' in page and 'data-figure="dist-LAT"' in page
    text = "".join(p.extract_text() for p in pypdf.PdfReader(files.pdf).pages)
    assert "S000" in text and "S001" in text and "INCOMPLETE" in text
    complete = build_campaign_report(_campaign(), tmp_path / "c", pdf=False, workers=1)
    assert complete.pdf is None and 'id="incomplete"' not in complete.html.read_text(encoding="utf-8")


SWEEP = '''
[[sweep]]
key = "dut.synthetic.rate"
values = ["100 Hz", "10 Hz", "0.5 Hz"]
'''


def test_a_swept_campaign_through_the_command_ends_with_its_report(tmp_path):
    (tmp_path / "drive.toml").write_bytes((HERE / "drive.toml").read_bytes())
    case = tmp_path / "case.toml"
    case.write_text((HERE / "case.toml").read_text() + SWEEP)
    out = tmp_path / "out"
    done = subprocess.run(bench_command("campaign", str(case), "--runs", "2", "--workers", "2", "-o", str(out),
                                        "-q", "--no-pdf"), env=bench_env(), capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 1, done.stderr  # a point's case FAILs
    assert "campaign_report.html" in done.stdout
    doc = json.loads((out / "campaign.json").read_text())
    judged = {label: v["verdict"] for label, v in doc["verdicts"].items()}
    assert judged['CMP-SYN{dut.synthetic.rate="100 Hz"}'] == "PASS"
    assert judged['CMP-SYN{dut.synthetic.rate="0.5 Hz"}'] == "FAIL"
    (axis,) = doc["aggregate"]["sweeps"]["CMP-SYN"]["axes"]
    assert axis["key"] == "dut.synthetic.rate" and axis["unit"] == "Hz"
    assert [p["x"] for p in axis["points"]] == [100.0, 10.0, 0.5]
    gap = [p["criteria"]["INTEGRITY-gap"]["median"] for p in axis["points"]]
    assert gap == pytest.approx([0.01, 0.1, 2.0])  # the output's gap follows the swept rate
    assert [p["pass_rate"] for p in axis["points"]][::2] == [1.0, 0.0]  # a 2 s gap fails its 1 s limit
    page = (out / "campaign_report.html").read_text(encoding="utf-8")
    for label, verdict in judged.items():  # the case verdicts' table
        row = html.unescape(page).split(f'<tr data-case="{label}">', 1)[1].split("</tr>", 1)[0]
        assert f'data-verdict="{verdict}"' in row
    assert 'data-figure="dist-POS"' in page  # values that differ between runs are drawn
    assert 'data-figure="dist-INTEGRITY-order"' not in page  # 0 in every run: its table row says all
    assert 'data-figure="sweep-0-pass-rate"' in page and 'data-figure="sweep-0-INTEGRITY-gap"' in page
    curve = {f.key: f for f in campaign_figures(doc["aggregate"])["sweep:CMP-SYN"]}["sweep-0-pass-rate"]
    assert curve.values["pass_rate"] == [p["pass_rate"] for p in axis["points"]]
    assert html.escape(curve.alt) in page  # the figure on the page is drawn from campaign.json's rates
    assert "100 Hz: 100 %" in curve.alt and "0.5 Hz: 0 %" in curve.alt
    (out / "campaign_report.html").unlink()
    old = {**doc, "aggregate": {k: v for k, v in doc["aggregate"].items() if k != "sweeps"}}
    (out / "campaign.json").write_text(json.dumps(old))  # as an older bench wrote it: no sweeps
    again = subprocess.run(bench_command("campaign-report", str(out), "--no-pdf"), env=bench_env(),
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert html.escape(curve.alt) in (out / "campaign_report.html").read_text(encoding="utf-8")
    assert not list((out / "runs").glob("*.tmp"))
    (out / "campaign_report.html").unlink()
    quiet = subprocess.run(bench_command("campaign", str(case), "--runs", "2", "-o", str(out), "-q", "--no-report"),
                           env=bench_env(), capture_output=True, text=True, timeout=120)
    assert quiet.returncode == done.returncode and "6 reused" in quiet.stdout  # nothing run again
    assert not (out / "campaign_report.html").exists() and "report:" not in quiet.stdout
    missing = subprocess.run(bench_command("campaign-report", str(tmp_path / "nothing")), env=bench_env(),
                             capture_output=True, text=True, timeout=60)
    assert missing.returncode == 2 and "campaign.json" in missing.stderr

