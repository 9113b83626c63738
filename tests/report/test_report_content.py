"""The certification report shows the results record and nothing else: every criterion
value and margin in report.html equals the record's (exactly, beside the shown figure);
the PDF has the same sections and numbers; DUT text is escaped; ``bench report`` on the
recordings alone gives the same content as the live run."""

from __future__ import annotations

import json
import re
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pypdf
import pytest

from bench.cli.app import run as cli
from bench.report.model import fmt_num
from tests.report.suite import HOSTILE_NAME, HOSTILE_VERSION

SECTIONS = ("Identification", "Summary", "Requirement coverage", "Reproduction", "Approval")


class _Cells(HTMLParser):
    """The criteria rows of report.html: per (case, criterion, variant) the value and
    margin cells, exact (data-) and shown (text); the per-seed cells."""

    def __init__(self) -> None:
        super().__init__()
        self.case = ""
        self.rows: dict[tuple[str, str, str, str], dict[str, tuple[str, str]]] = {}
        self.seeds: dict[str, list[tuple[str, str]]] = {}
        self._row: tuple[str, str, str, str] | None = None
        self._cell: tuple[str, str] | None = None
        self._text = ""

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section" and "data-case" in a:
            self.case = a["data-case"]
        if tag == "tr" and "data-criterion" in a:
            self._row = (self.case, a["data-criterion"], a["data-variant"], a["data-control"])
            self.rows[self._row] = {}
        if tag == "td" and ("data-value" in a or "data-margin" in a):
            self._cell = ("value", a["data-value"]) if "data-value" in a else ("margin", a["data-margin"])
            self._text = ""

    def handle_data(self, data):
        if self._cell is not None:
            self._text += data

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            kind, exact = self._cell
            if self._row is not None and kind not in self.rows[self._row]:
                self.rows[self._row][kind] = (exact, self._text.strip())
            elif kind == "value":
                self.seeds.setdefault(self.case, []).append((exact, self._text.strip()))
            self._cell = None
        if tag == "tr":
            self._row = None


def _record(out: Path) -> dict:
    return json.loads((out / "results.json").read_text())


def test_every_criterion_value_and_margin_in_the_html_equals_the_record(report_dir):
    record = _record(report_dir)
    cells = _Cells()
    cells.feed((report_dir / "report.html").read_text())
    html = (report_dir / "report.html").read_text()
    expected = {}
    for case in record["cases"]:
        integrity = [cr for cr in case["criteria"] if cr["id"].startswith("INTEGRITY-")]
        summarised = bool(integrity) and all(cr["verdict"] == "PASS" for cr in integrity)
        if summarised:  # one line per case: the checks with their worst values (issue 34)
            line = re.search(rf'<section class="case" id="case-{re.escape(case["id"])}".*?'
                             r'<p class="integrity-line" data-integrity="(\d+)">(.*?)</p>', html, re.S)
            assert line is not None and int(line.group(1)) == len(integrity), case["id"]
            for cr in integrity:
                worst = max(float(v) for v in [cr["value"], *[r["value"] for r in cr["runs"]]] if v is not None)
                assert f"{cr['id'][len('INTEGRITY-'):]} {fmt_num(worst)}" in line.group(2), (cr["id"], line.group(2))
        for cr in case["criteria"]:
            if summarised and cr in integrity:
                continue
            key = (case["id"], cr["id"], cr["variant"] or "", str(bool(cr["control"])).lower())
            expected[key] = {"value": (json.dumps(cr["value"]), fmt_num(cr["value"])),
                             "margin": (json.dumps(cr["margin"]), fmt_num(cr["margin"]))}
    assert len(expected) >= 5 and cells.rows == expected
    # the values per seed of every criterion judged over the runs or not PASS on every run
    for case in record["cases"]:
        seeds = [(json.dumps(r["value"]), fmt_num(r["value"])) for cr in case["criteria"] if len(cr["runs"]) > 1
                 and ((cr.get("monte_carlo") or "every run") != "every run"
                      or any(r["verdict"] != "PASS" for r in cr["runs"]))
                 for r in cr["runs"]]
        assert cells.seeds.get(case["id"], []) == seeds


def test_the_report_names_the_verdicts_the_gaps_and_the_dut_text_escaped(suite_out):
    html = (suite_out / "report.html").read_text()
    assert "<script" not in html.lower()  # the page has no script, and the DUT's markup is text
    assert "&lt;script&gt;alert(&#39;dut&#39;)&lt;/script&gt; filter" in html
    record = _record(suite_out)
    # the DUT's declared version is identified, as text
    assert {"kind": "synthetic", "name": HOSTILE_NAME, "command": None, "version": HOSTILE_VERSION} in record[
        "identification"]["duts"]
    assert "1.2.0-rc1 &lt;b&gt;beta&lt;/b&gt;" in html and "<b>beta" not in html
    assert record["verdict"] == "ERROR" and 'data-verdict="FAIL"' in html and 'data-verdict="ERROR"' in html
    # R-NEVER is named by RPT-B and judged by nothing: the case is ERROR saying so, its
    # failing criterion still FAIL, and the gap flagged in the coverage matrix
    b = next(c for c in record["cases"] if c["id"] == "RPT-B")
    assert b["verdict"] == "ERROR" and any(e.startswith("requirement R-NEVER not judged: no criterion of the case "
                                                        "names it") for e in b["errors"]), b["errors"]
    assert any(c["verdict"] == "FAIL" for c in b["criteria"])
    assert "requirement R-NEVER not judged" in html
    row = re.search(r'<tr class="gap"><td class="req-id">R-NEVER</td>.*?</tr>', html, re.S)
    assert row is not None and "never judged" in row.group(0) and 'data-verdict="NOT JUDGED"' in row.group(0)
    # R-LATENCY is waived by RPT-A, with its reason: shown, not a gap, and RPT-A PASSes
    a = next(c for c in record["cases"] if c["id"] == "RPT-A")
    assert a["verdict"] == "PASS" and a["requirements_waived"] == [
        {"requirement": "R-LATENCY", "reason": "judged in the real-time case RPT-RT, not in lockstep"}]
    row = re.search(r'<tr><td class="req-id">R-LATENCY</td>.*?</tr>', html, re.S)
    assert row is not None and "waived: judged in the real-time case RPT-RT" in row.group(0)
    assert 'data-verdict="WAIVED"' in row.group(0)
    # requirements in words, with their source, in the record and the report; the case's
    # reference and assumptions too (57b1bce: ids only)
    assert a["requirements_text"][0] == {
        "id": "R-ACC", "statement": "The estimator shall keep its horizontal position error within 5 m RMS over the "
        "drive.", "source": "paper", "citation": "report-test paper, table 1"}
    assert a["reference"].startswith("the report tests' own drive") and a["assumed"][0].startswith("the synthetic DUT")
    row = re.search(r'<tr><td class="req-id">R-FDI</td>.*?</tr>', html, re.S)
    assert row is not None and "shall detect each odometer fault within 1 s" in row.group(0)
    assert "(bench" in row.group(0)
    assert "Assumed by the bench" in html and "its errors are drawn, not estimated" in html
    assert all(c.get("limit_source") in ("paper", "standard", "bench") for c in a["criteria"])
    assert html.count('<section class="case"') == 2
    for title in SECTIONS:
        assert f">{title}<" in html


def _squash(text: str) -> str:
    return re.sub(r"\s+", "", text)


def _pdf_pages(pdf: Path) -> list[str]:
    return [p.extract_text() for p in pypdf.PdfReader(pdf).pages]


def test_the_pdf_has_the_same_sections_and_numbers_and_renders_to_pages(report_dir, tmp_path):
    pdf = report_dir / "report.pdf"
    assert pdf.stat().st_size < 10 * 1024 * 1024
    pages = _pdf_pages(pdf)
    text = "\n".join(pages)
    for title in SECTIONS:
        assert title in text
    record = _record(report_dir)
    for case in record["cases"]:
        # a long title wraps, anywhere (even after a "/"): headings found with the whitespace out
        flat = [_squash(p) for p in pages]
        start = next(i for i, p in enumerate(flat) if _squash(f"{case['id']}: {case['title']}") in p)
        end = next((i for i in range(start + 1, len(pages)) if any(
            _squash(f"{c['id']}: {c['title']}") in flat[i] for c in record["cases"] if c is not case)), len(pages))
        case_text = "\n".join(pages[start:end])
        for cr in case["criteria"]:
            shown = fmt_num(cr["value"])
            assert re.search(rf"(?<![\d.]){re.escape(shown)}(?![\d])", case_text), (case["id"], cr["id"], shown)
    if record["cases"][0]["id"] == "RPT-A":
        assert HOSTILE_NAME in text  # as text
    # every page renders (poppler), and none is blank
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(pdf), str(tmp_path / "p")], check=True)
    import matplotlib.image as mpimg

    rendered = sorted(tmp_path.glob("p-*.png"))
    assert len(rendered) == len(pages) >= 4
    assert all(mpimg.imread(p).std() > 0.01 for p in rendered)


def _sections(html: str) -> dict[str, str]:
    """The report's sections whose content comes from the recordings (summary, cases)."""
    out = {"summary": re.search(r'<section id="summary">.*?</section>', html, re.S).group(0)}
    for m in re.finditer(r'<section class="case" id="(case-[^"]+)".*?</section>', html, re.S):
        out[m.group(1)] = m.group(0)
    return out


def test_bench_report_on_the_recordings_alone_gives_the_live_report(suite_out, tmp_path):
    live = _sections((suite_out / "report.html").read_text())
    code = cli(["report", str(suite_out / "recordings"), "-o", str(tmp_path / "again"), "--no-pdf", "-q"])
    assert code == 3  # the verdict's code: RPT-B is ERROR (a requirement not judged)
    assert _sections((tmp_path / "again" / "report.html").read_text()) == live
    again = json.loads((tmp_path / "again" / "results.json").read_text())
    assert again["cases"] == _record(suite_out)["cases"]
    # from the record, re-judging the recordings beside it
    assert cli(["report", str(suite_out), "-o", str(tmp_path / "rescored"), "--rescore", "--no-pdf", "-q"]) == 3
    assert _sections((tmp_path / "rescored" / "report.html").read_text()) == live


@pytest.mark.parametrize("bad", ["missing.json", "not_json.json", "no_cases.json", "notes.txt", "invalid.json"])
def test_a_bad_input_is_a_usage_error_naming_it(suite_out, tmp_path, capsys, bad):
    (tmp_path / "not_json.json").write_text("{ nope")
    (tmp_path / "no_cases.json").write_text('{"verdict": "PASS"}')
    (tmp_path / "notes.txt").write_text("x")
    record = _record(suite_out)
    record["cases"][1]["criteria"][0]["value"] = "five"
    (tmp_path / "invalid.json").write_text(json.dumps(record))
    assert cli(["report", str(tmp_path / bad), "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert bad in err
    if bad == "invalid.json":
        assert "cases[1].criteria[0].value" in err
