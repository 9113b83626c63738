"""junit.xml carries each criterion's measurement as properties equal to the results
record's values (full precision), with the value of every Monte Carlo seed."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from bench.report.junit import PROPERTIES


def _expected(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return "" if value is None else str(value) if not isinstance(value, float) else repr(value)


def _number(text: str) -> float | None:
    return None if text == "" else float(text)


def _record_number(value: object) -> float | None:
    return None if value is None else float(value)  # "inf" and "-inf" parse too


def test_every_criterion_testcase_carries_the_record_values(suite):
    doc = suite["doc"]
    root = ET.parse(suite["out"] / "junit.xml").getroot()
    case = doc["cases"][0]
    (ts,) = [s for s in root.iter("testsuite") if s.get("name") == case["id"]]
    testcases = [tc for tc in ts.iter("testcase") if tc.get("name") != "load" and "(waived)" not in tc.get("name")]
    assert len(testcases) == len(case["criteria"]) > 3
    for tc, crit in zip(testcases, case["criteria"], strict=True):
        assert tc.get("name").split("[")[0] == crit["id"]
        props = [(p.get("name"), p.get("value")) for p in tc.find("properties")]
        named = dict(props)
        assert [v for k, v in props if k == "requirement"] == crit["requirements"]
        for key in PROPERTIES:
            head, _, tail = key.partition(".")
            want = crit[head][tail] if tail else crit[key]
            assert named[key] == _expected(want), key
        for key in ("value", "value_si", "margin", "marginal_band", "limit_si.high"):
            head, _, tail = key.partition(".")
            want = _record_number(crit[head][tail] if tail else crit[key])
            got = _number(named[key])
            assert got == want or (got is not None and want is not None and math.isinf(got) and got == want), key
        runs = [k for k, _ in props if k.startswith("run.")]
        assert runs == [f"run.{r['seed']}.{f}" for r in crit["runs"] for f in ("value", "verdict")]
        for r in crit["runs"]:
            assert _number(named[f"run.{r['seed']}.value"]) == _record_number(r["value"])
            assert named[f"run.{r['seed']}.verdict"] == r["verdict"]
    by_id = {tc.get("name"): tc for tc in testcases}
    mc = {p.get("name"): p.get("value") for p in by_id["HMAX"].find("properties")}
    assert {"run.1.value", "run.2.value"} <= set(mc) and mc["monte_carlo"] == "at least 2 runs"


def test_the_suite_names_its_recordings_by_sha256(suite):
    root = ET.parse(suite["out"] / "junit.xml").getroot()
    (ts,) = root.iter("testsuite")
    props = {p.get("name"): p.get("value") for p in ts.find("properties")}
    for run in suite["doc"]["cases"][0]["runs"]:
        assert props[f"recording.{run['recording']}.sha256"] == run["identity"]["recording"]["sha256"]
