"""``[[sweep]]`` in a case: its points expand into their own runs, keys and aggregate groups."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.acceptance.case import load_case
from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.plan import plan_campaign
from bench.campaign.sweep import case_at, sweep_points
from bench.errors import ConfigError

HERE = Path(__file__).parent

SWEEP = '''
[[sweep]]
key = "dut.synthetic.latency"
values = ["2 ms", "30 ms"]
'''


@pytest.fixture
def swept(tmp_path) -> Path:
    (tmp_path / "drive.toml").write_bytes((HERE / "drive.toml").read_bytes())
    case = tmp_path / "case.toml"
    case.write_text((HERE / "case.toml").read_text() + SWEEP)
    return case


def test_sweep_points_and_the_case_at_each(swept):
    points = sweep_points(swept)
    assert points == [(("dut.synthetic.latency", "2 ms"),), (("dut.synthetic.latency", "30 ms"),)]
    assert load_case(swept).dut.synthetic.latency_ns == 4_000_000  # bench accept runs it as written
    assert case_at(swept, points[1]).dut.synthetic.latency_ns == 30_000_000
    assert sweep_points(HERE / "case.toml") == [()]


def test_a_bad_sweep_is_a_configuration_error(tmp_path, swept):
    swept.write_text(swept.read_text().replace('values = ["2 ms", "30 ms"]', "values = []"))
    with pytest.raises(ConfigError, match="non-empty"):
        sweep_points(swept)


def test_a_swept_campaign_has_a_group_per_point(swept, tmp_path):
    plan = plan_campaign([swept], runs=2)
    assert len(plan) == 4 and len({r.key for r in plan}) == 4
    result = run_campaign(CampaignOptions([str(swept)], tmp_path / "out", runs=2, workers=2))
    groups = result["aggregate"]["cases"]
    assert sorted(groups) == ['CMP-SYN{dut.synthetic.latency="2 ms"}', 'CMP-SYN{dut.synthetic.latency="30 ms"}']
    assert all(g["runs"] == 2 for g in groups.values())
    assert result["invocation"]["executed"] == 4
