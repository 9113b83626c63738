"""A crash is contained to its case: ``bench accept`` with one broken case among five
judges the other four, exits 3 (ERROR) and writes every report; a report that cannot be
written does not stop the others (bench.acceptance.suite, bench.report.outputs)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

import bench.acceptance.runner as runner
from bench.acceptance.synthetic import SyntheticRunner
from bench.cli import main
from bench.crashlog import LOG_NAME
from tests.acceptance.conftest import base_case


class CrashingRunner:
    """The synthetic runner, except for the case ``CRASH``, whose run divides by zero."""

    def run(self, case, seed, out_dir, *, progress=None):
        if case.id == "CRASH":
            return 1 / 0
        return SyntheticRunner().run(case, seed, out_dir, progress=progress)


@pytest.fixture
def five_cases(make_case, monkeypatch, tmp_path) -> list[Path]:
    """Five synthetic cases (T1..T4 pass, CRASH crashes in its runner)."""
    monkeypatch.setitem(runner._FACTORIES, "synthetic", CrashingRunner)
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    paths = []
    for i, name in enumerate(["T1", "T2", "CRASH", "T3", "T4"]):
        text = base_case("6 m", "0.5 m").replace('id = "T1"', f'id = "{name}"')
        paths.append(make_case(text, f"{i}_{name}.toml"))
    return paths


def _reports(out: Path) -> tuple[dict, ET.Element, str, str]:
    return (
        json.loads((out / "results.json").read_text()),
        ET.parse(out / "junit.xml").getroot(),
        (out / "summary.txt").read_text(),
        (out / "summary.md").read_text(),
    )


def test_one_crashing_case_among_five_is_error_the_others_are_judged_and_every_report_written(
    five_cases, tmp_path, capsys
):
    out = tmp_path / "out"
    assert main(["accept", *map(str, five_cases), "-o", str(out), "-q"]) == 3
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err + captured.out
    results, junit, txt, md = _reports(out)
    verdicts = {c["id"]: c["verdict"] for c in results["cases"]}
    assert verdicts == {"T1": "PASS", "T2": "PASS", "CRASH": "ERROR", "T3": "PASS", "T4": "PASS"}
    crashed = next(c for c in results["cases"] if c["id"] == "CRASH")
    issue = crashed["runs"][0]["bench_issues"][0]
    assert issue == f"the run of seed 1 crashed: ZeroDivisionError: division by zero (traceback in {out / LOG_NAME})"
    assert "in run" in (out / LOG_NAME).read_text() and "1 / 0" in (out / LOG_NAME).read_text()
    assert {s.get("name") for s in junit.iter("testsuite")} == set(verdicts)
    assert int(junit.get("errors")) >= 1
    assert "ZeroDivisionError" in txt and "ZeroDivisionError" in md and "ERROR" in txt
    assert len(list((out / "plots").glob("*.png"))) == 4  # the four judged runs


def test_a_crash_while_scoring_or_plotting_one_run_is_contained(five_cases, tmp_path, monkeypatch, capsys):
    import bench.acceptance.judge as judge
    import bench.acceptance.suite as suite
    import bench.report.outputs as outputs

    real_score, real_plot = judge.score_recording, outputs.plot_run

    def score(path, case=None):
        if case.id == "T2":
            raise RecursionError("maximum recursion depth exceeded")
        return real_score(path, case)

    def plot(rec, out, title=""):
        if "T3" in str(rec):
            raise ValueError("no finite axis limits")
        return real_plot(rec, out, title)

    monkeypatch.setattr(suite, "score_recording", score)
    monkeypatch.setattr(outputs, "plot_run", plot)
    out = tmp_path / "out"
    assert main(["accept", *map(str, five_cases), "-o", str(out), "-q"]) == 3
    results, *_ = _reports(out)
    verdicts = {c["id"]: c["verdict"] for c in results["cases"]}
    assert verdicts == {"T1": "PASS", "T2": "ERROR", "CRASH": "ERROR", "T3": "PASS", "T4": "PASS"}
    t2 = next(c for c in results["cases"] if c["id"] == "T2")
    assert t2["runs"][0]["bench_issues"][0].startswith("the run of seed 1 crashed: RecursionError")
    assert (out / "plots" / "T3-s1.txt").read_text() == "no plot: ValueError: no finite axis limits\n"
    assert (out / "plots" / "T1-s1.png").exists()


def test_a_report_that_cannot_be_written_does_not_stop_the_others(five_cases, tmp_path, monkeypatch, capsys):
    import bench.report.outputs as outputs

    def broken(cases, *args, **kwargs):
        raise ZeroDivisionError("markdown")

    monkeypatch.setattr(outputs, "markdown_table", broken)
    monkeypatch.setitem(runner._FACTORIES, "synthetic", SyntheticRunner)  # every case passes
    out = tmp_path / "out"
    assert main(["accept", *map(str, five_cases), "-o", str(out), "-q", "--no-plots"]) == 3
    err = capsys.readouterr().err
    assert "bench accept: could not write summary.md: ZeroDivisionError: markdown (traceback in" in err
    results = json.loads((out / "results.json").read_text())
    junit = ET.parse(out / "junit.xml").getroot()
    txt = (out / "summary.txt").read_text()
    assert results["verdict"] == "PASS" and junit.get("errors") == "0" and "PASS" in txt
    assert not (out / "summary.md").exists()


def test_a_case_file_that_crashes_the_loader_is_error_and_the_suite_goes_on(five_cases, tmp_path, monkeypatch):
    import bench.acceptance.suite as suite

    real_load = suite.load_case

    def load(path):
        if "T3" in str(path):
            raise KeyError("scenario")
        return real_load(path)

    monkeypatch.setattr(suite, "load_case", load)
    monkeypatch.setitem(runner._FACTORIES, "synthetic", SyntheticRunner)
    out = tmp_path / "out"
    assert main(["accept", *map(str, five_cases), "-o", str(out), "-q", "--no-plots"]) == 3
    results, *_ = _reports(out)
    verdicts = {c["id"]: c["verdict"] for c in results["cases"]}
    assert verdicts == {"T1": "PASS", "T2": "PASS", "CRASH": "PASS", "3_T3": "ERROR", "T4": "PASS"}
    t3 = next(c for c in results["cases"] if c["id"] == "3_T3")
    assert t3["errors"][0].startswith("the case file ") and "KeyError: 'scenario' (traceback in" in t3["errors"][0]
