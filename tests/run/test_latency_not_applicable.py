"""In lockstep the DUT's output latency (arrival minus time of validity) is set by the
bench's wait for each answer, so ``output.latency_*`` is always 0 there and could never
fail: such a criterion is N/A in a lockstep run, neither PASS nor FAIL, shown as N/A in
the results, the summary and the JUnit file (a ``skipped`` test case); the case's verdict
comes from its other criteria, and a case whose own criteria are all N/A is an ERROR
(the bench's integrity defaults passing say nothing of the case's requirements)."""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET

import pytest

from bench.acceptance.case import parse_case
from bench.acceptance.integrity_criteria import CHECKS
from bench.acceptance.judge import judge_case, score_recording
from bench.acceptance.verdict import Verdict, worst
from bench.faults.schedule import FaultSchedule
from bench.report.junit import junit_xml
from bench.report.results import results_json
from bench.report.table import markdown_table, text_table
from bench.run.engine import run
from bench.run.spec import DutSpec, RunSpec
from bench.scenario.loader import load_scenario
from tests.run.robust_util import SHORT, TABLES

HEAD = f"""
[case]
id = "{{id}}"
title = "latency criteria in lockstep"
requirements = ["BENCH-OUT"]

[scenario]
script = "{SHORT}"

[dut]
kind = "in_process"
name = "decode_only"

[clock]
mode = "lockstep"
"""
LATENCY = """
[[criterion]]
id = "OUT-LATENCY-MAX"
requirement = "BENCH-OUT"
metric = "output.latency_max"
at_most = "1 ns"

[[criterion]]
id = "OUT-LATENCY-P95"
requirement = "BENCH-OUT"
metric = "output.latency_p95"
at_least = "1 s"
"""
RATE = """
[[criterion]]
id = "OUT-RATE"
requirement = "BENCH-OUT"
metric = "output.rate"
at_least = "1 Hz"
"""
DECODE_ONLY = """
[scoring.integrity]
invalid_fraction = { check = false, reason = "decode_only flags every epoch invalid" }
quality_unmatched = { check = false, reason = "decode_only sends no NAV_QUALITY" }
"""
NO_INTEGRITY = "\n[scoring.integrity]\n" + "".join(
    f'{c.key} = {{ check = false, reason = "latency only" }}\n' for c in CHECKS
)


@pytest.fixture(scope="module")
def lockstep_recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("na") / "lockstep.mcap"
    res = run(RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), out=out,
                      dut=DutSpec("in_process", name="decode_only"), duration_ns=5_000_000_000))
    assert res.ok, res.reason
    return out


def test_a_latency_criterion_in_lockstep_is_not_applicable_and_shown_so(lockstep_recording):
    case = parse_case(HEAD.format(id="NA-MIXED") + LATENCY + RATE + DECODE_ONLY, file="na.toml", check_files=False)
    _, run_result = score_recording(lockstep_recording, case)
    lat = run_result.values["OUT-LATENCY-MAX"]
    assert lat.verdict is Verdict.NA and math.isnan(lat.value) and "lockstep" in lat.reason
    assert run_result.values["OUT-LATENCY-P95"].verdict is Verdict.NA  # would FAIL (0 s < 1 s) if judged
    others = [v.verdict for k, v in run_result.values.items() if not k.startswith("OUT-LATENCY")]
    assert run_result.verdict is worst(others) and run_result.verdict.passed
    cr = judge_case(case, [run_result])
    by_id = {c.criterion.id: c for c in cr.criteria}
    assert by_id["OUT-LATENCY-MAX"].verdict is Verdict.NA and by_id["OUT-RATE"].verdict is Verdict.PASS
    assert cr.verdict is worst(c.verdict for c in cr.criteria if not c.criterion.id.startswith("OUT-LATENCY"))
    # shown as N/A everywhere
    doc = results_json([cr])
    crit = {c["id"]: c for c in doc["cases"][0]["criteria"]}
    assert crit["OUT-LATENCY-MAX"]["verdict"] == "N/A" and doc["cases"][0]["verdict"] == str(cr.verdict)
    json.dumps(doc, allow_nan=False)
    assert any("OUT-LATENCY-MAX" in line and "N/A" in line for line in markdown_table([cr]).splitlines())
    assert "N/A: not applicable in lockstep" in text_table([cr])
    suite = junit_xml([cr]).find("testsuite")
    cases = {tc.get("name"): tc for tc in suite.findall("testcase")}
    assert cases["OUT-LATENCY-MAX"].find("skipped") is not None
    assert cases["OUT-LATENCY-MAX"].find("failure") is None and cases["OUT-LATENCY-MAX"].find("error") is None
    assert suite.get("skipped") == "2" and suite.get("failures") == "0"
    ET.fromstring(ET.tostring(junit_xml([cr])))


def test_a_case_whose_criteria_are_all_not_applicable_is_an_error(lockstep_recording):
    case = parse_case(HEAD.format(id="NA-ONLY") + LATENCY + NO_INTEGRITY, file="na.toml", check_files=False)
    _, run_result = score_recording(lockstep_recording, case)
    assert {v.verdict for v in run_result.values.values()} == {Verdict.NA}
    cr = judge_case(case, [run_result])
    assert cr.verdict is Verdict.ERROR  # a case may not PASS on latency criteria in lockstep
    assert any("N/A" in e for e in cr.errors)


def test_a_case_whose_own_criteria_are_all_not_applicable_is_an_error_despite_passing_integrity(
    lockstep_recording,
):
    case = parse_case(HEAD.format(id="NA-OWN") + LATENCY + DECODE_ONLY, file="na.toml", check_files=False)
    _, run_result = score_recording(lockstep_recording, case)
    integrity = [v.verdict for k, v in run_result.values.items() if k.startswith("INTEGRITY-")]
    assert integrity and all(v.passed for v in integrity)  # the defaults alone would pass it
    cr = judge_case(case, [run_result])
    assert cr.verdict is Verdict.ERROR
    assert any("N/A" in e for e in cr.errors)
