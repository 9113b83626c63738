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


def test_a_key_reaches_arrays_of_tables_and_sensors_named_by_their_set(tmp_path, swept):
    text = swept.read_text().replace(SWEEP, "") + '''
[sensors]
doppler = "seed000"

[[sweep]]
key = "criterion[1].at_most"
values = ["7 m"]

[[sweep]]
key = "dut.synthetic.error[0].tau"
values = ["20 s"]

[[sweep]]
key = "sensors.doppler.scale_factor_markov"
values = ["0.3 %"]
'''
    swept.write_text(text)
    (point,) = sweep_points(swept)
    case = case_at(swept, point)
    assert [c.limit.high for c in case.criteria if c.id == "POS-RMS"] == [7.0]
    assert [c.limit.high for c in case.criteria if c.id == "POS"] == [2.5]  # the other criterion as written
    assert case.dut.synthetic.errors[0].tau_s == 20.0
    assert case.sensors["doppler"].params == {"model": "seed000", "scale_factor_markov": "0.3 %"}
    assert load_case(swept).sensors["doppler"].params == {"model": "seed000"}


@pytest.mark.parametrize(("key", "message"), [
    ("criterion[5].at_most", "has 2 entries"),
    ("case[0].id", "not an array of tables"),
    ("case.id.x", "is not a table"),
    ("dut..rate", "expected a dotted key"),
    ("criterion[x].at_most", "expected a dotted key"),
])
def test_a_key_that_reaches_nothing_names_itself(swept, key, message):
    swept.write_text(swept.read_text().replace('"dut.synthetic.latency"', f'"{key}"'))
    with pytest.raises(ConfigError, match=message):
        for point in sweep_points(swept):
            case_at(swept, point)


def test_the_recording_of_a_swept_run_carries_the_swept_case(tmp_path, swept):
    """bench score re-judges a swept run with the values it ran with: here the limit of
    POS is swept, so re-judging with the file's own limit would give another verdict."""
    from bench.acceptance.judge import score_recording

    swept.write_text(swept.read_text().replace(SWEEP, "") + '''
[[sweep]]
key = "criterion[0].at_most"
values = ["0.001 m", "1000 m"]
''')
    result = run_campaign(CampaignOptions([str(swept)], tmp_path / "out", runs=1, workers=1))
    groups = result["aggregate"]["cases"]
    tight, loose = groups['CMP-SYN{criterion[0].at_most="0.001 m"}'], groups['CMP-SYN{criterion[0].at_most="1000 m"}']
    assert tight["criteria"]["POS"]["verdicts"] == {"FAIL": 1}
    assert loose["criteria"]["POS"]["verdicts"] == {"PASS": 1}
    for group, limit, verdict in ((tight, 0.001, "FAIL"), (loose, 1000.0, "PASS")):
        path = tmp_path / "out" / group["criteria"]["POS"]["worst"][0]["recording"]
        case, run = score_recording(path)
        assert [c.limit.high for c in case.criteria if c.id == "POS"] == [limit]
        assert run.values["POS"].verdict.value == verdict
