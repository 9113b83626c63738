"""Output integrity judged in every case by default: a DUT whose output goes bad in the
last 4 s of a 10 s run FAILs on the named INTEGRITY criterion; loosening is explicit."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bench.acceptance.case import load_case
from bench.acceptance.integrity_criteria import CHECKS, REQUIREMENT
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.cli import main
from bench.errors import ConfigError
from bench.report.junit import junit_xml
from bench.report.results import case_json
from tests.acceptance.degradations import KINDS

DRIVE = """
[scenario]
id = "T-10"
title = "ten seconds"

[initial]
latitude = 30.0
longitude = 110.0
height = "50 m"
speed = "10 m/s"
heading = "0 deg"

[[segment]]
kind = "uniform"
duration = "10 s"
"""

CASE = """
[case]
id = "T10"
title = "ten seconds of output"
requirements = ["R"]

[scenario]
script = "drive.toml"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"
{defect}
{scoring}
[[criterion]]
id = "H"
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "1 m"
"""



def _defect(kind: str | None) -> str:
    if kind is None:
        return ""
    extra = 'amount = "1e6 s"\n' if kind == "time_jump" else ""
    return f'[[dut.synthetic.output]]\nkind = "{kind}"\nstart = "6 s"\n{extra}'


@pytest.fixture
def write(tmp_path: Path):
    (tmp_path / "drive.toml").write_text(DRIVE)

    def make(kind: str | None = None, scoring: str = "", name: str = "case.toml") -> Path:
        p = tmp_path / name
        p.write_text(CASE.format(defect=_defect(kind), scoring=scoring))
        return p

    return make


def _judge(path: Path, out: Path):
    result = run_case(load_case(path), SuiteOptions(out))
    return result, {c.criterion.id: c.verdict for c in result.criteria}


def test_every_case_gets_every_default_check(write):
    case = load_case(write())
    ids = [c.id for c in case.criteria]
    assert ids == ["H", *(c.id for c in CHECKS)]
    assert REQUIREMENT in case.requirements
    assert all(c.requirements == (REQUIREMENT,) for c in case.criteria[1:])


def test_healthy_output_passes_every_default(write, tmp_path):
    result, verdicts = _judge(write(), tmp_path / "out")
    assert result.verdict is Verdict.PASS, verdicts


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_output_bad_in_the_last_4_s_fails_on_the_named_criterion(write, tmp_path, kind):
    result, verdicts = _judge(write(kind), tmp_path / "out")
    assert verdicts[KINDS[kind]] is Verdict.FAIL, verdicts
    assert result.verdict is Verdict.FAIL
    # the case's own accuracy criterion cannot see it (the DUT's values stay true), except
    # for a latitude out of range
    assert verdicts["H"] is (Verdict.FAIL if kind == "out_of_range" else Verdict.PASS)


def test_the_failure_is_named_in_results_and_junit(write, tmp_path):
    result, _ = _judge(write("time_frozen"), tmp_path / "out")
    j = case_json(result)
    row = next(c for c in j["criteria"] if c["id"] == "INTEGRITY-repeated")
    assert row["verdict"] == "FAIL" and row["metric"] == "output.repeated" and row["value"] == 400
    assert row["requirements"] == [REQUIREMENT]
    xml = ET.tostring(junit_xml([result]), encoding="unicode")
    failures = [tc.get("name") for tc in ET.fromstring(xml).iter("testcase") if tc.find("failure") is not None]
    assert "INTEGRITY-repeated" in failures and "H" not in failures


def test_bench_accept_exits_1_and_names_the_check(write, tmp_path, capsys):
    path = write("counter_stuck")
    out = tmp_path / "reports"
    assert main(["accept", str(path), "-o", str(out), "--no-plots", "-q"]) == 1
    summary = (out / "summary.txt").read_text()
    assert "INTEGRITY-counter" in summary and "FAIL" in summary
    results = json.loads((out / "results.json").read_text())
    assert results["verdict"] == "FAIL"


# -- loosening is explicit and reasoned ------------------------------------------------------
def test_a_limit_loosened_with_a_reason_is_written_into_the_criterion(write, tmp_path):
    scoring = '[scoring.integrity]\nmissing_fraction = "50 %"\nmax_gap = "5 s"\nreason = "the DUT sleeps"\n'
    case = load_case(write("drop", scoring))
    c = next(c for c in case.criteria if c.id == "INTEGRITY-missing")
    assert c.limit.high == 0.5 and "the DUT sleeps" in c.description and "0.1 %" in c.description
    result, verdicts = _judge(write("drop", scoring), tmp_path / "out")
    assert verdicts["INTEGRITY-missing"] is Verdict.PASS and result.verdict is Verdict.PASS


def test_loosening_without_a_reason_is_refused(write):
    with pytest.raises(ConfigError) as info:
        load_case(write(scoring='[scoring.integrity]\nmissing_fraction = "2 %"\n'))
    assert info.value.key == "scoring.integrity.missing_fraction" and "reason" in info.value.reason
    with pytest.raises(ConfigError) as info:
        load_case(write(scoring='[scoring.integrity]\ninvalid_after = "5 s"\n'))
    assert info.value.key == "scoring.integrity.invalid_after"
    # tightening needs no reason
    case = load_case(write(scoring='[scoring.integrity]\nmax_gap = "0.5 s"\n'))
    assert next(c for c in case.criteria if c.id == "INTEGRITY-gap").limit.high == 0.5


def test_a_check_switched_off_needs_a_reason_that_reaches_the_results(write, tmp_path):
    with pytest.raises(ConfigError) as info:
        load_case(write(scoring="[scoring.integrity]\nbad_frames = { check = false }\n"))
    assert info.value.key == "scoring.integrity.bad_frames.reason"
    off = '[scoring.integrity]\nbad_frames = { check = false, reason = "the link is noisy by design" }\n'
    case = load_case(write("bad_crc", off))
    assert "INTEGRITY-bad-frames" not in [c.id for c in case.criteria]
    result, verdicts = _judge(write("bad_crc", off), tmp_path / "out")
    assert verdicts["INTEGRITY-missing"] is Verdict.FAIL  # the other checks still judge it
    assert case_json(result)["integrity_waived"] == [
        {"check": "bad_frames", "criterion": "INTEGRITY-bad-frames", "reason": "the link is noisy by design"}
    ]


def test_invalid_flags_are_judged_after_alignment(write, tmp_path):
    aligning = '[[dut.synthetic.output]]\nkind = "invalid"\nend = "3 s"\n'
    case_text = CASE.format(defect=aligning, scoring="")
    p = write()
    p.write_text(case_text)
    _, verdicts = _judge(p, tmp_path / "a")
    assert verdicts["INTEGRITY-invalid"] is Verdict.FAIL  # no convergence time: invalid epochs count
    p.write_text(CASE.format(defect=aligning, scoring='[scoring]\nconvergence = "3 s"\n'))
    result, verdicts = _judge(p, tmp_path / "b")
    assert verdicts["INTEGRITY-invalid"] is Verdict.PASS and result.verdict is Verdict.PASS


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("[scoring.integrity]\nmissing_fraction = nan\nreason = 'x'\n", "scoring.integrity.missing_fraction"),
        ("[scoring.integrity]\nmissing_fraction = '200 %'\nreason = 'x'\n", "scoring.integrity.missing_fraction"),
        ("[scoring.integrity]\nbad_frames = -1\n", "scoring.integrity.bad_frames"),
        ("[scoring.integrity]\nmax_gap = '2 m'\nreason = 'x'\n", "scoring.integrity.max_gap"),
        ("[scoring.integrity]\nmissing = '2 %'\n", "scoring.integrity.missing"),
        ("[scoring.integrity]\nbad_frames = { check = true, reason = 'x' }\n", "scoring.integrity.bad_frames.check"),
        ("[scoring.integrity]\nheight = ['1 km']\nreason = 'x'\n", "scoring.integrity.height"),
        ("[scoring.integrity]\nspeed = inf\nreason = 'x'\n", "scoring.integrity.speed"),
    ],
)
def test_bad_integrity_settings_name_the_key(write, text, key):
    with pytest.raises(ConfigError) as info:
        load_case(write(scoring=text))
    assert info.value.key == key


def test_a_case_cannot_take_over_a_default_id_nor_drop_a_default_by_its_own_criterion(write):
    p = write()
    own = (
        '\n[[criterion]]\nid = "OUT-MISSING"\nrequirement = "R"\nmetric = "output.missing_fraction"\nat_most = "50 %"\n'
    )
    p.write_text(p.read_text() + own)
    case = load_case(p)
    ids = [c.id for c in case.criteria]
    assert "OUT-MISSING" in ids and "INTEGRITY-missing" in ids  # the looser own criterion adds, never replaces
    p.write_text(p.read_text().replace('id = "OUT-MISSING"', 'id = "INTEGRITY-missing"'))
    with pytest.raises(ConfigError) as info:
        load_case(p)
    assert info.value.key == "criterion[1].id"


def test_what_broken_output_leaves_unmeasurable_is_the_dut_failure(write, tmp_path):
    p = write("drop")
    tail = (
        '\n[[criterion]]\nid = "TAIL"\nrequirement = "R"\nmetric = "accuracy.horizontal.max"\n'
        'window = { start = "7 s" }\nat_most = "1 m"\n'
    )
    p.write_text(p.read_text() + tail)
    result, verdicts = _judge(p, tmp_path / "out")
    tail_result = next(c for c in result.criteria if c.criterion.id == "TAIL")
    assert verdicts["TAIL"] is Verdict.FAIL and "its output failed INTEGRITY-missing" in tail_result.aggregate.reason
    assert result.verdict is Verdict.FAIL
    # with the check switched off the bench cannot judge that window: ERROR, as before
    off = (
        '[scoring.integrity]\nmissing_fraction = { check = false, reason = "t" }\n'
        'max_gap = { check = false, reason = "t" }\n'
    )
    p.write_text(CASE.format(defect=_defect("drop"), scoring=off) + tail)
    _, verdicts = _judge(p, tmp_path / "off")
    assert verdicts["TAIL"] is Verdict.ERROR
