"""The report's first page: the verdict with cases, criteria and requirements counted
apart (every verdict kind, N/A and NOT JUDGED included), then everything that is not PASS,
then the summary and the coverage matrix; the identification after them.

On 57b1bce the headline read "PASS -- 9 case(s), 369 criteria: 9 PASS, 0 MARGINAL, 0 FAIL,
0 ERROR": the nine were cases, N/A appeared nowhere, and a FAIL sat on page 30 or so."""

from __future__ import annotations

import re

import pypdf

from bench.report.build import build_report
from bench.report.model import report_model


def _criterion(cid: str, verdict: str = "PASS", value: float | None = 0.0, req: str = "R") -> dict:
    return {"id": cid, "requirements": [req], "metric": "accuracy.horizontal.max", "window": "all", "value": value,
            "unit": "m", "limit": "<= 1 m", "margin": 1.0, "verdict": verdict, "reason": "", "runs": []}


def _suite(fail_in: str | None = "C7") -> dict:
    cases = []
    for k in range(1, 10):
        cid = f"C{k}"
        crit = [_criterion(f"ACC-{j}", req=f"{cid}-R{j % 3}") for j in range(20)]
        crit += [_criterion(f"INTEGRITY-{j}", req="BENCH-INTEGRITY") for j in range(10)]
        if k <= 5:
            crit.append(_criterion("OUT-LATENCY", "N/A", None, req="BENCH-INTEGRITY"))
        verdict = "PASS"
        if cid == fail_in:
            crit[17] = {**_criterion("ACC-17", "FAIL", 3.25, req=f"{cid}-R2"), "reason": "above the limit"}
            crit[20] = {**_criterion("INTEGRITY-0", "FAIL", 2.0, req="BENCH-INTEGRITY"), "reason": "2 epochs missing"}
            verdict = "FAIL"
        cases.append({"id": cid, "title": f"case {k}", "file": f"{cid}.toml", "verdict": verdict, "errors": [],
                      "requirements": sorted({c["requirements"][0] for c in crit}), "integrity_waived": [],
                      "dut": {"kind": "in_process", "name": "est"}, "criteria": crit, "runs": []})
    verdict = "FAIL" if fail_in else "PASS"
    counts = {"PASS": 9 - bool(fail_in), "MARGINAL": 0, "FAIL": int(bool(fail_in)), "ERROR": 0, "N/A": 0}
    return {"schema": "bench.results/1", "verdict": verdict, "counts": counts, "cases": cases, "run_info": {},
            "identification": {}}


def test_the_headline_counts_cases_criteria_and_requirements_apart_with_n_a():
    m = report_model(_suite(fail_in=None))
    assert m["case_counts"] == {"PASS": 9, "MARGINAL": 0, "FAIL": 0, "ERROR": 0, "N/A": 0}
    assert m["criterion_counts"] == {"PASS": 270, "MARGINAL": 0, "FAIL": 0, "ERROR": 0, "N/A": 5}
    assert sum(m["requirement_counts"].values()) == len(m["coverage"]) == 9 * 3 + 1
    # the N/A criteria are listed as not PASS, a reviewer sees them
    assert [(r["case"], r["id"], r["verdict"]) for r in m["not_pass"]] == [
        (f"C{k}", "OUT-LATENCY", "N/A") for k in range(1, 6)]


def test_a_fail_among_nine_cases_is_on_the_first_page(tmp_path):
    files = build_report(_suite(), tmp_path, figures=False, workers=1)
    pages = [p.extract_text() for p in pypdf.PdfReader(files.pdf).pages]
    first = re.sub(r"\s+", " ", pages[0])
    assert "Overall verdict FAIL" in first, first[:400]
    assert "Cases 9: 8 PASS, 0 MARGINAL, 1 FAIL, 0 ERROR, 0 N/A" in first, first[:600]
    assert "Criteria 275: 268 PASS, 0 MARGINAL, 2 FAIL, 0 ERROR, 5 N/A" in first, first[:600]
    fail = first.index("FAIL C7 criterion ACC-17")
    assert first[fail:].startswith("FAIL C7 criterion ACC-17 value 3.25 m; limit <= 1 m; above the limit FAIL C7 "
                                   "criterion INTEGRITY-0 value 2 m; limit <= 1 m; 2 epochs missing N/A C1")
    assert "N/A C5 criterion OUT-LATENCY limit <= 1 m" in first  # an N/A has no value to show
    # before the identification, which follows the summary and the coverage matrix
    text = "\n".join(pages)
    assert text.index("Not PASS") < text.index("Requirement coverage") < text.index("Identification")
    # the integrity checks of a case that all PASS are one line; C7's failing one keeps its row
    html = files.html.read_text()
    assert html.count('class="integrity-line"') == 8 and 'data-criterion="INTEGRITY-0"' in html
