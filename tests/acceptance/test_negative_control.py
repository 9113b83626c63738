"""Negative controls (``must_fail_on``): a criterion must FAIL on a variant run without what
it checks; a control that passes makes the criterion FAIL; a control never turns the DUT's
own FAIL into a PASS; the case file refuses malformed controls; results, tables and JUnit
show the control; re-scoring the recordings gives the same."""

from __future__ import annotations

import json

import pytest

from bench.acceptance.case import load_case
from bench.acceptance.criteria import Criterion, Limit, RunValue
from bench.acceptance.judge import _controls
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.cli.score import score_files
from bench.errors import ConfigError
from bench.report.junit import junit_xml
from bench.report.results import case_json
from bench.report.table import text_table
from bench.scoring.windows import WindowSpec
from tests.acceptance.conftest import DRIVE, base_case

VARIANTS = """
[dut.variants.good]
description = "small error"

[dut.variants.poor]
description = "a 5 m bias: what the criteria below must see"

[[dut.variants.poor.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["3 m", "4 m", "0 m"]
"""

# a variant's errors replace the base case's (a 5 m bias): the good variant's is 0.5 m
GOOD = """
[[dut.variants.good.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["0.3 m", "0.4 m", "0 m"]
"""


def _case(tmp_path, criteria: str, seeds: str = "[1, 2]"):
    (tmp_path / "drive.toml").write_text(DRIVE)
    text = base_case(limit="20 m").replace("seeds = [1]", f"seeds = {seeds}") + VARIANTS + GOOD + criteria
    (tmp_path / "case.toml").write_text(text)
    return load_case(tmp_path / "case.toml")


SEES = """
[[criterion]]
id = "SEES"
variant = "good"
must_fail_on = ["poor"]
requirement = "R2"
metric = "accuracy.horizontal.mean"
at_most = "2 m"
marginal = "0.5 m"
"""

BLIND = """
[[criterion]]
id = "BLIND"
variant = "good"
must_fail_on = "poor"
requirement = "R2"
metric = "accuracy.horizontal.mean"
at_most = "50 m"
"""


STRICT = """
[[criterion]]
id = "STRICT"
variant = "good"
must_fail_on = ["poor"]
requirement = "R2"
metric = "accuracy.horizontal.mean"
at_most = "0.2 m"
"""


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    d = tmp_path_factory.mktemp("control")
    case = _case(d, SEES + BLIND + STRICT)
    return case, run_case(case, SuiteOptions(d / "out"))


def _by(result):
    return {(c.criterion.id, c.variant, c.control): c for c in result.criteria}


def test_a_control_that_fails_passes_and_a_control_that_passes_fails(live):
    _, result = live
    by = _by(result)
    good = by["SEES", "good", False]
    assert good.verdict is Verdict.PASS and good.aggregate.value == pytest.approx(0.5, abs=0.1)
    sees = by["SEES", "poor", True]
    # the poor variant's horizontal error is 5 m beyond a 2 m limit: the criterion sees it
    assert sees.verdict is Verdict.PASS
    assert sees.aggregate.value == pytest.approx(5.0, abs=0.1) and sees.aggregate.margin == pytest.approx(3.0, abs=0.1)
    assert [r.verdict for r in sees.runs] == [Verdict.PASS, Verdict.PASS] and [r.seed for r in sees.runs] == [1, 2]
    blind = by["BLIND", "poor", True]
    assert blind.verdict is Verdict.FAIL and "cannot tell" in blind.aggregate.reason
    assert by["BLIND", "good", False].verdict is Verdict.PASS
    # the controls never judged the poor runs as the DUT: their run verdicts are their
    # integrity and the base case's H (20 m), which they meet; the good runs FAIL STRICT
    assert {r.variant: r.verdict for r in result.runs} == {"good": Verdict.FAIL, "poor": Verdict.PASS}
    assert by["BLIND", "poor", True].aggregate.value == pytest.approx(5.0, abs=0.1)  # fails by the control
    assert ("SEES", "poor", False) not in by and ("H", "poor", False) in by


def test_results_table_and_junit_name_the_control(live):
    _, result = live
    j = case_json(result)
    rows = [c for c in j["criteria"] if c["id"] == "BLIND"]
    assert {(c["variant"], c["control"]) for c in rows} == {("good", False), ("poor", True)}
    assert all(c["must_fail_on"] == ["poor"] for c in rows)
    table = text_table([result], width=200)
    assert "negative control: must FAIL" in table and "BLIND[poor, must FAIL]: FAIL" in table
    root = junit_xml([result])
    names = [tc.get("name") for tc in root.iter("testcase")]
    assert "SEES[poor, must FAIL]" in names and "BLIND[poor, must FAIL]" in names


def test_rescoring_the_recordings_gives_the_live_controls(live):
    _, result = live
    again = score_files([r.recording for r in result.runs])
    assert json.dumps(case_json(again[0]), sort_keys=True) == json.dumps(case_json(result), sort_keys=True)


def _crit(**kw) -> Criterion:
    base = dict(id="C", requirements=("R",), metric="accuracy.horizontal.mean", window=WindowSpec("all"),
                limit=Limit("at_most", None, 2.0), unit="m", dimension="length", marginal=0.5,
                variant="good", must_fail_on=("poor",))
    base.update(kw)
    return Criterion(**base)


@pytest.mark.parametrize(
    ("values", "verdict"),
    [
        ([5.0, 6.0], Verdict.PASS),  # fails on every control run beyond the band
        ([5.0, 2.3], Verdict.MARGINAL),  # one control run fails only inside the band
        ([5.0, 1.0], Verdict.FAIL),  # one control run meets the limit
        ([5.0, 2.0], Verdict.FAIL),  # on the limit is meeting it
    ],
)
def test_every_control_run_must_fail_beyond_the_band(values, verdict):
    runs = [RunValue(s, v, Verdict.FAIL if v > 2.0 else Verdict.PASS) for s, v in enumerate(values, 1)]
    agg = _controls(_crit(), runs)
    assert agg.verdict is verdict
    assert agg.value == min(values)  # the control run nearest to passing


@pytest.mark.parametrize(
    ("values", "verdict"),
    [
        ([5.0, 1.0], Verdict.PASS),  # mean 3.0: the aggregate fails beyond the band, one run alone would not
        ([2.4, 2.2], Verdict.MARGINAL),  # mean 2.3: fails inside the band
        ([3.0, 0.0], Verdict.FAIL),  # mean 1.5 meets the limit
    ],
)
def test_in_an_aggregate_mode_the_controls_aggregate_must_fail(values, verdict):
    from bench.acceptance.criteria import MonteCarlo

    crit = _crit(monte_carlo=MonteCarlo("aggregate", aggregate="mean"))
    runs = [RunValue(s, v, Verdict.FAIL if v > 2.0 else Verdict.PASS) for s, v in enumerate(values, 1)]
    agg = _controls(crit, runs)
    assert agg.verdict is verdict and agg.value == pytest.approx(sum(values) / 2)
    assert agg.margin == pytest.approx(sum(values) / 2 - 2.0)


@pytest.mark.parametrize(
    ("run", "verdict"),
    [
        (RunValue(1, float("nan"), Verdict.ERROR, "link lost"), Verdict.ERROR),
        (RunValue(1, float("nan"), Verdict.FAIL, "every epoch invalid"), Verdict.FAIL),
    ],
)
def test_an_unmeasured_control_is_never_a_pass(run, verdict):
    assert _controls(_crit(), [RunValue(2, 9.0, Verdict.FAIL), run]).verdict is verdict
    assert _controls(_crit(), []).verdict is Verdict.ERROR
    na = RunValue(1, float("nan"), Verdict.NA, "not applicable in lockstep")
    assert _controls(_crit(), [na, na]).verdict is Verdict.NA  # as for the DUT's own runs


def test_a_control_never_turns_the_dut_fail_into_a_pass(live):
    _, result = live
    by = _by(result)
    # 0.5 m against 0.2 m: the DUT's own FAIL stands beside its control's PASS
    assert by["STRICT", "good", False].verdict is Verdict.FAIL
    assert by["STRICT", "poor", True].verdict is Verdict.PASS
    assert result.verdict is Verdict.FAIL


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ('variant = "good"\nmust_fail_on = ["nosuch"]', "unknown variant 'nosuch'"),
        ('variant = "good"\nmust_fail_on = ["good"]', "cannot be both judged and a negative control"),
        ('variant = "good"\nrelative_to = "poor"\nmust_fail_on = ["poor"]', "takes no negative control"),
        ('variant = "good"\nmust_fail_on = ["poor", "poor"]', "listed twice"),
        ('variant = "good"\nmust_fail_on = [1]', "must_fail_on"),
    ],
)
def test_malformed_controls_are_refused_naming_the_key(tmp_path, extra, needle):
    crit = f"""
[[criterion]]
id = "X"
{extra}
requirement = "R2"
metric = "accuracy.horizontal.mean"
at_most = "2 m"
"""
    with pytest.raises(ConfigError) as exc:
        _case(tmp_path, crit)
    assert needle in str(exc.value) and "criterion" in str(exc.value)


def test_a_criterion_of_every_variant_leaves_its_controls_out(tmp_path):
    case = _case(tmp_path, """
[[criterion]]
id = "ALL"
must_fail_on = ["poor"]
requirement = "R2"
metric = "accuracy.horizontal.mean"
at_most = "2 m"
""", seeds="[1]")
    result = run_case(case, SuiteOptions(tmp_path / "out"))
    got = {(c.criterion.id, c.variant, c.control): c.verdict for c in result.criteria if c.criterion.id == "ALL"}
    assert got == {("ALL", "good", False): Verdict.PASS, ("ALL", "poor", True): Verdict.PASS}
    assert result.verdict is Verdict.PASS
