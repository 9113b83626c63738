"""An interrupted suite keeps what finished (bench.acceptance.suite: CaseInterrupted,
SuiteInterrupted; bench.cli.accept writes the reports from them, marked incomplete).

The interrupt is raised by a runner wrapping the synthetic one, at a chosen run, as the
signal handler of ``bench`` raises it (``KeyboardInterrupt("SIGTERM")``)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import pytest

import bench.acceptance.runner as runner
import bench.acceptance.suite as suite
from bench.acceptance.interrupted import Interruption
from bench.acceptance.suite import CaseInterrupted, SuiteInterrupted, SuiteOptions, run_case, run_suite
from bench.acceptance.synthetic import SyntheticRunner
from bench.acceptance.verdict import Verdict
from bench.cli import main
from bench.report.results import results_json, validate_results
from tests.acceptance.conftest import base_case


class StoppingRunner:
    """The synthetic runner, interrupted (after writing part of its recording) at ``AT``."""

    AT: tuple[str, int] = ("B", 2)

    def run(self, case, seed, out_dir, *, progress=None):
        if (case.id, seed) == self.AT:
            raise KeyboardInterrupt("SIGTERM")
        return SyntheticRunner().run(case, seed, out_dir, progress=progress)


@pytest.fixture
def three_cases(make_case, monkeypatch):
    """A (seed 1), B (seeds 1, 2, 3), C (seed 1), run by :class:`StoppingRunner`."""
    monkeypatch.setitem(runner._FACTORIES, "synthetic", StoppingRunner)
    paths = []
    for name, seeds in (("A", "[1]"), ("B", "[1, 2, 3]"), ("C", "[1]")):
        text = base_case().replace('id = "T1"', f'id = "{name}"').replace("seeds = [1]", f"seeds = {seeds}")
        paths.append(make_case(text, f"{name}.toml"))
    return paths


def test_the_case_in_progress_keeps_the_runs_that_finished_and_the_rest_is_not_run(three_cases, tmp_path):
    with pytest.raises(SuiteInterrupted) as caught:
        run_suite(three_cases, SuiteOptions(tmp_path / "out"))
    exc = caught.value
    assert isinstance(exc, KeyboardInterrupt) and exc.args == ("SIGTERM",)
    assert exc.interruption == Interruption("SIGTERM", ("A",), ("B",), ("C",))
    a, b, c = exc.results
    assert (a.case_id, a.verdict) == ("A", Verdict.PASS) and a.criteria
    assert b.verdict is Verdict.ERROR and not b.criteria
    assert [r.seed for r in b.runs] == [1] and b.runs[0].verdict is Verdict.PASS  # seed 1 finished, is kept
    assert b.errors == ["interrupted by SIGTERM: the case did not finish (1 of 3 run(s) finished; the run of seed 2 "
                        "was interrupted); not judged"]
    assert (c.case_id, c.title, c.verdict, c.errors) == ("C", "test case", Verdict.ERROR,
                                                         ["interrupted by SIGTERM: not run"])
    assert c.requirements[:2] == ("R1", "R2")  # named from its file, for the coverage matrix
    record = results_json(exc.results, interrupted=exc.interruption)
    validate_results(record)
    assert record["verdict"] == "ERROR" and record["interrupted"] == {
        "by": "SIGTERM", "finished": ["A"], "unfinished": ["B"], "not_run": ["C"]}


def test_an_interrupt_after_a_case_was_judged_keeps_its_verdict(three_cases, tmp_path, monkeypatch):
    """Interrupted while reporting B's end (a progress callback): B finished."""

    class Reporter:
        def case_started(self, case, runs): ...
        def run_started(self, case, seed): ...
        def run_finished(self, case, result): ...

        def case_finished(self, result):
            if result.case_id == "B":
                raise KeyboardInterrupt("SIGINT")

    monkeypatch.setattr(StoppingRunner, "AT", ("none", 0))
    with pytest.raises(SuiteInterrupted) as caught:
        run_suite(three_cases, SuiteOptions(tmp_path / "out"), Reporter())
    assert caught.value.interruption == Interruption("SIGINT", ("A", "B"), (), ("C",))
    assert [r.verdict for r in caught.value.results] == [Verdict.PASS, Verdict.PASS, Verdict.ERROR]


def test_an_interrupt_while_loading_a_case_file_leaves_it_not_run(three_cases, tmp_path, monkeypatch):
    real = suite.load_case
    calls: list[str] = []

    def load(path, *a, **kw):
        calls.append(path.stem)
        if calls.count("B") == 1 and path.stem == "B":  # the first load, by the suite; not the one naming it
            raise KeyboardInterrupt("SIGINT")
        return real(path, *a, **kw)

    monkeypatch.setattr(suite, "load_case", load)
    with pytest.raises(SuiteInterrupted) as caught:
        run_suite(three_cases, SuiteOptions(tmp_path / "out"))
    assert caught.value.interruption == Interruption("SIGINT", ("A",), (), ("B", "C"))
    assert [r.case_id for r in caught.value.results] == ["A", "B", "C"]


def test_run_case_alone_raises_the_case_with_its_finished_runs(three_cases, tmp_path):
    from bench.acceptance.case import load_case

    with pytest.raises(CaseInterrupted) as caught:
        run_case(load_case(three_cases[1]), SuiteOptions(tmp_path / "out"))
    assert caught.value.finished is False and [r.seed for r in caught.value.result.runs] == [1]


def test_bench_accept_interrupted_writes_every_record_marked_incomplete_and_exits_3(three_cases, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["accept", *map(str, three_cases), "-o", str(out), "-q", "--no-plots", "--no-report"]) == 3
    err = capsys.readouterr().err
    assert f"bench accept: reports in {out}: written: results.json, junit.xml, summary.txt, summary.md; " \
           "not written: none" in err
    assert "bench: interrupted by SIGTERM" in err.splitlines()[-1]
    results = json.loads((out / "results.json").read_text())
    assert results["interrupted"]["unfinished"] == ["B"] and results["verdict"] == "ERROR"
    junit = ET.parse(out / "junit.xml").getroot()
    assert junit.get("errors") != "0"
    error = junit.find("testsuite[@name='bench accept: interrupted']/testcase[@name='interrupted']/error")
    assert error is not None and error.get("type") == "INTERRUPTED" and "did not finish: B" in error.get("message")
    headline = "INCOMPLETE: the suite was interrupted by SIGTERM; 1 case(s) finished (A); did not finish: B; not run: C"
    assert (out / "summary.txt").read_text().splitlines()[0] == headline
    assert (out / "summary.md").read_text().splitlines()[0] == f"**{headline}**"


def test_bench_run_interrupted_writes_the_seeds_that_finished(three_cases, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(three_cases[1]), "-o", str(out), "-q", "--no-plots"]) == 3
    results = json.loads((out / "results.json").read_text())
    assert results["interrupted"] == {"by": "SIGTERM", "finished": [], "unfinished": ["B"], "not_run": []}
    assert [r["seed"] for r in results["cases"][0]["runs"]] == [1]
    assert "bench: interrupted by SIGTERM" in capsys.readouterr().err
