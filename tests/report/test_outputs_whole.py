"""write_reports (bench.report.outputs): every file whole or not at all, an exact account of
what was written and what was not, no report of an earlier run left beside the new ones,
and an interrupt that cuts the plots but never the four records."""

from __future__ import annotations

import errno
import json

import pytest

import bench.report.outputs as outputs
from bench import shield
from bench.acceptance.judge import CaseResult, RunResult
from bench.acceptance.verdict import Verdict
from bench.report.outputs import Ledger, ReportError, write_reports

RECORDS = ["results.json", "junit.xml", "summary.txt", "summary.md"]


def _cases(tmp_path, n: int = 2) -> list[CaseResult]:
    """One case with ``n`` runs whose recordings exist (their plots are stubbed)."""
    runs = []
    for seed in range(1, n + 1):
        rec = tmp_path / "recordings" / "C1" / f"C1-s{seed}.mcap"
        rec.parent.mkdir(parents=True, exist_ok=True)
        rec.write_bytes(b"stub")
        runs.append(RunResult(str(rec), "C1", None, seed, Verdict.PASS))
    return [CaseResult("C1", "a case", "c1.toml", ("R1",), Verdict.PASS, runs=runs)]


def _stub_plots(monkeypatch, fail_on: str | None = None, error: BaseException | None = None) -> list[str]:
    drawn: list[str] = []

    def plot(rec, out, title=""):
        if fail_on is not None and fail_on in str(rec):
            raise error  # type: ignore[misc]
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(b"\x89PNG")
        drawn.append(out.name)
        return out

    monkeypatch.setattr(outputs, "plot_run", plot)
    return drawn


def test_a_report_that_fails_is_named_and_its_earlier_copy_removed(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "junit.xml").write_text("<testsuites verdict='PASS' from='an earlier run'/>")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs, "write_junit", full)
    _stub_plots(monkeypatch)
    ledger = Ledger(out)
    files = write_reports(_cases(tmp_path), out, plots=True, ledger=ledger)
    assert set(files) == {"json", "summary", "markdown", "plots"}
    assert ledger.written == ["results.json", "summary.txt", "summary.md", "plots/C1-s1.png", "plots/C1-s2.png"]
    assert ledger.not_written == ["junit.xml"]
    assert ledger.failures == ledger.notes == [
        "junit.xml: OSError: [Errno 28] No space left on device (the earlier junit.xml was removed)"]
    assert not (out / "junit.xml").exists()  # the earlier run's PASS cannot pass for this run's
    assert ledger.line() == (f"reports in {out}: written: results.json, summary.txt, summary.md, plots/C1-s1.png, "
                             "plots/C1-s2.png; not written: junit.xml")


def test_without_a_ledger_the_error_lists_what_was_and_was_not_written(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise OSError(errno.EFBIG, "File too large")

    monkeypatch.setattr(outputs, "write_json", broken)
    with pytest.raises(ReportError) as caught:
        write_reports(_cases(tmp_path), tmp_path / "out", plots=False)
    assert str(caught.value) == (f"could not write results.json: OSError: [Errno 27] File too large (reports in "
                                 f"{tmp_path / 'out'}: written: junit.xml, summary.txt, summary.md; "
                                 "not written: results.json)")


def test_a_plot_that_fails_is_listed_but_does_not_count_as_a_failed_report(tmp_path, monkeypatch):
    _stub_plots(monkeypatch, fail_on="C1-s2", error=ValueError("no finite axis limits"))
    ledger = Ledger(tmp_path)
    write_reports(_cases(tmp_path), tmp_path, plots=True, ledger=ledger)
    assert ledger.failures == []
    assert ledger.not_written == ["plots/C1-s2.png"] and "plots/C1-s2.txt" in ledger.written
    assert (tmp_path / "plots" / "C1-s2.txt").read_text() == "no plot: ValueError: no finite axis limits\n"


def test_an_interrupt_while_plotting_stops_there_and_the_ledger_lists_the_rest(tmp_path, monkeypatch):
    drawn = _stub_plots(monkeypatch, fail_on="C1-s2", error=KeyboardInterrupt("SIGINT"))
    ledger = Ledger(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        write_reports(_cases(tmp_path, 3), tmp_path, plots=True, ledger=ledger)
    assert drawn == ["C1-s1.png"]
    assert ledger.written == [*RECORDS, "plots/C1-s1.png"]
    assert ledger.not_written == ["plots/C1-s2.png", "plots/C1-s3.png"]
    assert ledger.notes == ["plots/C1-s2.png: interrupted by SIGINT", "plots/C1-s3.png: interrupted by SIGINT"]


def test_an_interrupt_while_the_records_are_written_is_held_until_all_four_are(tmp_path, monkeypatch):
    """The signal handler of ``bench`` holds the first interrupt inside a shielded section
    (bench.shield.hold) and raises it when the section ends: after the four records, before
    the plots."""
    real = outputs.results_json

    def results_then_signal(*args, **kwargs):
        assert shield.hold("SIGTERM")  # what the handler does on a signal arriving now
        return real(*args, **kwargs)

    monkeypatch.setattr(outputs, "results_json", results_then_signal)
    drawn = _stub_plots(monkeypatch)
    ledger = Ledger(tmp_path)
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        write_reports(_cases(tmp_path), tmp_path, plots=True, ledger=ledger)
    assert ledger.written == RECORDS and drawn == []
    assert ledger.not_written == ["plots/C1-s1.png", "plots/C1-s2.png"]
    assert json.loads((tmp_path / "results.json").read_text())["verdict"] == "PASS"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*RECORDS, "recordings"])  # no temporary left


def test_the_report_of_an_interrupted_suite_has_the_incomplete_banner_and_a_complete_one_none(tmp_path):
    from bench.acceptance.interrupted import Interruption
    from bench.report.build import build_report
    from bench.report.results import results_json

    cases = [CaseResult("C1", "a case", "c1.toml", ("R1",), Verdict.PASS),
             CaseResult("C2", "next", "c2.toml", ("R2",), Verdict.ERROR, errors=["interrupted by SIGINT: not run"])]
    done: list = []
    files = build_report(results_json(cases, interrupted=Interruption("SIGINT", ("C1",), (), ("C2",))),
                         tmp_path / "i", pdf=False, figures=False, written=done.append)
    assert done == [files.html]
    html = files.html.read_text(encoding="utf-8")
    assert "<title>Acceptance report — ERROR — INCOMPLETE</title>" in html
    banner = html.split('id="incomplete">', 1)[1].split("</p>", 1)[0]
    assert banner.startswith("INCOMPLETE SUITE: interrupted by SIGINT. 1 case(s) finished (C1); not run: C2.")
    html = build_report(results_json(cases[:1]), tmp_path / "c", pdf=False, figures=False).html.read_text()
    assert 'id="incomplete"' not in html and "INCOMPLETE" not in html
