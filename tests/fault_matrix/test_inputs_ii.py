"""The fault matrix (issue 32), inputs II: every number a command reads from a file is finite
or refused, and every input is bounded (size, nesting depth, lines), with the file, the
field and the limit named; ``bench import-nav`` refuses a result larger than it can stream
(what every row checks: tests/fault_matrix/test_inputs.py).

Before issue 32 a results record with a NaN value compared SAME ("no regression", exit 0),
``bench compare /dev/zero`` read until MemoryError, deeply nested JSON was "internal error:
RecursionError" (exit 3), and a 10-million-line ``.nav`` took 6.9 GB to import.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import pytest

from tests.fault_matrix import matrix
from tests.fault_matrix.matrix import SHORT_DR, bench

CAMPAIGN_CASE = Path(__file__).parent.parent / "campaign" / "case.toml"
#: a bench whose address space is limited: a reader that slurps /dev/zero fails fast instead
#: of taking the machine's memory (on a fixed bench the file is refused before it is read)
LIMITED = [sys.executable, "-c", "import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30)); "
           "from bench.cli import main; sys.exit(main())"]
DEEP = 100_000  # levels of nesting: far beyond any parser's recursion
#: a value of a results record (or of a campaign's run record) as a raw JSON token
TOKENS = ["NaN", "Infinity", "-Infinity", "1e999"]


def _clean(r: matrix.Outcome) -> None:
    """Neither an internal error nor Python's own exceptions reach the user."""
    for word in ("internal error", "RecursionError", "MemoryError"):
        assert word not in r.text, r.text


@pytest.fixture(scope="module")
def results(recording) -> Path:
    """The results record of the shared recording's run (a real one, PASS)."""
    return recording.parents[2] / "results.json"


def _with_token(src: Path, dst: Path, token: str, where=lambda d: d["cases"][0]["criteria"][0], key="value") -> Path:
    """``src`` with the field ``key`` of the object ``where`` picks set to a raw JSON token."""
    data = json.loads(src.read_text())
    where(data)[key] = "@@TOKEN@@"
    dst.write_text(json.dumps(data, indent=1).replace('"@@TOKEN@@"', token))
    return dst


def _deep(path: Path, open_: str = "[", close: str = "]") -> Path:
    path.write_text(open_ * DEEP + close * DEEP)
    return path


# ----------------------------------------------------------------------- bench compare
@pytest.mark.parametrize("token", TOKENS)
def test_compare_of_a_record_with_a_non_finite_value_is_refused_naming_file_and_field(results, tmp_path, token):
    b = _with_token(results, tmp_path / "b.json", token)
    r = bench("compare", str(results), str(b), cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text  # never SAME, "no regression", exit 0
    assert str(b) in r.err and "cases[0].criteria[0].value" in r.err and "finite" in r.err, r.err
    assert "no regression" not in r.out


@pytest.mark.parametrize("what", ["dev-zero", "fifo", "huge", "deep-array", "deep-object"])
def test_compare_reads_no_unbounded_input(results, tmp_path, monkeypatch, what):
    if what == "dev-zero":
        bad = Path("/dev/zero")
    elif what == "fifo":
        bad = tmp_path / "pipe.json"
        os.mkfifo(bad)
    elif what == "huge":  # a sparse file: large on paper, nothing to write
        bad = tmp_path / "huge.json"
        with open(bad, "wb") as fh:
            fh.truncate(300 << 20)
    elif what == "deep-array":
        bad = _deep(tmp_path / "deep.json")
    else:
        bad = _deep(tmp_path / "deep.json", '{"a":', "}")
    monkeypatch.setattr(matrix, "BENCH", LIMITED)
    r = bench("compare", str(results), str(bad), cwd=tmp_path, timeout=60)
    _clean(r)
    assert r.code == 2, r.text
    assert str(bad) in r.err, r.err
    expected = {"dev-zero": "character device", "fifo": "FIFO", "huge": "256 MiB", "deep-array": "64 levels",
                "deep-object": "64 levels"}[what]
    assert expected in r.err, r.err
    if what in ("dev-zero", "fifo"):
        assert "256 MiB" in r.err, r.err  # the limit named


# ------------------------------------------------------------------------ bench report
@pytest.mark.parametrize("token", ["NaN", "Infinity"])
def test_report_of_a_record_with_a_non_finite_value_is_refused(results, tmp_path, token):
    b = _with_token(results, tmp_path / "results.json", token)
    r = bench("report", str(b), "-o", str(tmp_path / "rep"), "--no-pdf", "--no-figures", "-q", cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text
    assert str(b) in r.err and "cases[0].criteria[0].value" in r.err, r.err
    assert not (tmp_path / "rep" / "report.html").exists()


def test_report_of_a_deeply_nested_record_is_refused(tmp_path):
    bad = _deep(tmp_path / "results.json", '{"cases":', "}")
    r = bench("report", str(bad), "-o", str(tmp_path / "rep"), "--no-pdf", "--no-figures", "-q", cwd=tmp_path)
    _clean(r)
    assert r.code == 2 and str(bad) in r.err and "64 levels" in r.err, r.text


# ----------------------------------------------------------- bench campaign, campaign-report
@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    """A finished one-run campaign of the campaign tests' synthetic case (no report)."""
    out = tmp_path_factory.mktemp("campaign") / "c"
    bench("campaign", str(CAMPAIGN_CASE), "-o", str(out), "--runs", "1", "-q", "--no-report", cwd=out.parent)
    assert len(list((out / "runs").glob("*.json"))) == 1
    return out


def _copy_campaign(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("recordings"))
    return dst


@pytest.mark.parametrize("token", ["NaN", "1e999"])
def test_campaign_report_refuses_a_run_record_with_a_non_finite_number(campaign, tmp_path, token):
    out = _copy_campaign(campaign, tmp_path / "c")
    rec = next((out / "runs").glob("*.json"))
    _with_token(rec, rec, token, where=lambda d: d["criteria"]["POS"])
    r = bench("campaign-report", str(out), "--no-pdf", cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text
    assert str(rec) in r.err and "criteria.POS.value" in r.err, r.err


@pytest.mark.parametrize("what", ["nan", "deep"])
def test_campaign_report_refuses_a_campaign_json_with_a_nan_or_too_deep(campaign, tmp_path, what):
    out = _copy_campaign(campaign, tmp_path / "c")
    camp = out / "campaign.json"
    if what == "nan":
        _with_token(camp, camp, "NaN", where=lambda d: d["campaign"]["options"], key="runs")
    else:
        _deep(camp, '{"campaign":', "}")
    r = bench("campaign-report", str(out), "--no-pdf", cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text
    assert str(camp) in r.err and ("campaign.options.runs" if what == "nan" else "64 levels") in r.err, r.err


def test_a_campaign_never_reuses_a_run_record_with_a_nan_it_runs_the_run_again(campaign, tmp_path):
    out = tmp_path / "c"
    shutil.copytree(campaign, out)
    rec = next((out / "runs").glob("*.json"))
    _with_token(rec, rec, "NaN", where=lambda d: d["criteria"]["POS"])
    r = bench("campaign", str(CAMPAIGN_CASE), "-o", str(out), "--runs", "1", "-q", "--no-report", cwd=tmp_path)
    _clean(r)
    assert "(1 run now, 0 reused)" in r.out, r.text  # the damaged record is not judged as if fine
    assert rec.name in r.err and "criteria.POS.value" in r.err, r.err  # and the user is told why
    assert "NaN" not in rec.read_text()


# ------------------------------------------------------------------ bench score --case
SCORE_CASE_EDITS = {
    "nan-in-dut-config": ('alignment = "4 s" }', 'alignment = "4 s", gain = nan }', "dut.config.gain"),
    "inf-in-dut-config": ('alignment = "4 s" }', 'alignment = "4 s", gain = -inf }', "dut.config.gain"),
    "deep": ('[run]', "deep = " + "[" * DEEP + "]" * DEEP + "\n[run]", "64 levels"),
}


@pytest.mark.parametrize("edit", list(SCORE_CASE_EDITS))
def test_score_with_a_case_holding_a_non_finite_number_or_nested_too_deep_is_refused(recording, tmp_path, edit):
    old, new, named = SCORE_CASE_EDITS[edit]
    text = SHORT_DR.read_text()
    assert old in text
    case = tmp_path / "case.toml"
    case.write_text(text.replace(old, new, 1))
    r = bench("score", str(recording), "--case", str(case), cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text
    assert str(case) in r.err and named in r.err, r.err


# -------------------------------------------------------------------- bench import-nav
def _export(recording: Path, folder: Path) -> Path:
    bench("export", str(recording), "--dut", "-o", str(folder), cwd=folder.parent, expect=0)
    return folder


@pytest.mark.parametrize(("file", "value"), [("dut.nav", "nan"), ("dut.nav", "inf"), ("dut.nav", "1e999"),
                                             ("dut_std.txt", "nan"), ("dut_std.txt", "-inf")])
def test_import_nav_refuses_a_non_finite_column_naming_file_line_and_column(recording, tmp_path, file, value):
    folder = _export(recording, tmp_path / "x")
    p = folder / file
    lines = p.read_text().splitlines(keepends=True)
    parts = lines[100].split()
    parts[3] = value
    lines[100] = " ".join(parts) + "\n"
    p.write_text("".join(lines))
    out = tmp_path / "imp.mcap"
    r = bench("import-nav", str(folder / "dut.nav"), "--std", str(folder / "dut_std.txt"), "--run", str(recording),
              "-o", str(out), cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text
    assert str(p) in r.err and "line 101, column 4" in r.err and "finite" in r.err, r.err
    assert not out.exists()


def test_import_nav_refuses_a_result_with_more_lines_than_a_run_can_hold(recording, tmp_path):
    """A 90 s run holds at most 10 kHz x (90 s + 1 s) = 910,000 lines: one more is refused,
    the limit named, before anything is decoded or written (before: imported, in ~0.8 GB)."""
    text = _export(recording, tmp_path / "x").joinpath("dut.nav").read_text()
    first = text.splitlines(keepends=True)[500]
    nav = tmp_path / "big.nav"
    with open(nav, "w") as fh:
        for _ in range(91):
            fh.write(first * 10_000)
        fh.write(first)
    out = tmp_path / "imp.mcap"
    r = bench("import-nav", str(nav), "--run", str(recording), "-o", str(out), cwd=tmp_path)
    _clean(r)
    assert r.code == 2, r.text
    assert str(nav) in r.err and "910,000 lines" in r.err, r.err
    assert not out.exists()


@pytest.mark.parametrize("what", ["long-line", "dev-zero"])
def test_import_nav_refuses_a_line_or_file_it_cannot_bound(recording, tmp_path, monkeypatch, what):
    if what == "dev-zero":
        nav = Path("/dev/zero")
    else:
        nav = tmp_path / "long.nav"
        nav.write_text("2408 " + "1" * (8 << 20) + "\n")
    monkeypatch.setattr(matrix, "BENCH", LIMITED)
    r = bench("import-nav", str(nav), "--run", str(recording), "-o", str(tmp_path / "o.mcap"), cwd=tmp_path,
              timeout=60)
    _clean(r)
    assert r.code == 2 and str(nav) in r.err, r.text
    assert ("4096 bytes" if what == "long-line" else "character device") in r.err, r.err
