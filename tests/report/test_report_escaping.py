"""DUT-provided text in the reports: summary.txt/md, junit.xml escaped; results.json raw."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

from bench.acceptance.judge import CaseResult, RunResult
from bench.acceptance.verdict import Verdict
from bench.report.outputs import write_reports

# what a crashed DUT's last lines bring into a run's reason
DUT_TEXT = "fatal \x1b[31mred\x1b[0m\x1b]0;pwned\x07 <script>alert(1)</script> ]]> a|b \x00 \udc80 end"
RAW_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\ud800-\udfff]")


def _cases() -> list[CaseResult]:
    issue = f"the DUT process exited ({DUT_TEXT})"
    run = RunResult("/x/C1-s1.mcap", "C1", None, 1, Verdict.ERROR, bench_issues=[issue])
    return [CaseResult("C1", "title <b>|</b>", "c1.toml", ("R1",), Verdict.ERROR, runs=[run], errors=[DUT_TEXT])]


def test_reports_escape_dut_text_and_results_json_keeps_it(tmp_path):
    written = write_reports(_cases(), tmp_path, plots=False)
    junit = ET.parse(written["junit"]).getroot()  # parses: no NUL or ESC written raw
    text = "".join(junit.itertext()) + "".join(v for el in junit.iter() for v in el.attrib.values())
    assert "<script>alert(1)</script>" in text and "\\x1b[31mred" in text and "\\x00" in text
    assert not RAW_CONTROL.search(text)
    md = (tmp_path / "summary.md").read_text()
    assert "<script>" not in md and "&lt;script&gt;" in md and "<b>" not in md
    assert not RAW_CONTROL.search(md)
    for row in md.splitlines():
        if row.startswith("|"):
            assert len(re.findall(r"(?<!\\)\|", row)) == 10  # nine columns: no pipe of the DUT splits a cell
    txt = (tmp_path / "summary.txt").read_text()
    assert not RAW_CONTROL.search(txt) and "\\x1b]0;pwned\\x07" in txt
    raw = json.loads((tmp_path / "results.json").read_text())
    assert raw["cases"][0]["errors"][0] == DUT_TEXT  # raw: JSON escapes it
