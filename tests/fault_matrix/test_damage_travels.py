"""The fault matrix (issue 32), damage travels: every command that copies or derives from a
recording (``bench import-nav``, ``bench views``, ``bench export``, ``bench report`` from
recordings, the batch DUT) carries the source's unfinished or damaged state into what it
writes and into the verdict (ERROR unless ``--accept-damaged-source``, then recorded in the
results, as ``bench replay`` does); a copy of a copy keeps the mark. And a batch DUT's
placeholders are absolute paths, whatever ``-o`` is. (What every row checks:
tests/fault_matrix/test_inputs.py.)"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from bench.record.mcap_io import RecordingReader
from tests.fault_matrix.matrix import bench, readable
from tests.record.damage import chunk_flipped, footer_damaged, killed

DAMAGES = pytest.mark.parametrize("damage", [killed, footer_damaged, chunk_flipped],
                                  ids=["killed", "footer", "flipped"])
FLAG = "--accept-damaged-source"
EXCHANGE = Path(__file__).parent.parent / "exchange"


@pytest.fixture(scope="module")
def result(recording, tmp_path_factory) -> tuple[Path, Path]:
    """The recording's own DUT output as a ``.nav`` result and its STD file (``bench export
    --dut`` of the undamaged recording): a result that PASSes on it."""
    out = tmp_path_factory.mktemp("result")
    bench("export", str(recording), "-o", str(out / "exp"), "--dut", cwd=out, expect=0)
    return out / "exp" / "dut.nav", out / "exp" / "dut_std.txt"


def _import(result: tuple[Path, Path], run: Path, out: Path, *extra: str, expect: int | None):
    nav, std = result
    return bench("import-nav", str(nav), "--std", str(std), "--run", str(run), "-o", str(out), *extra,
                 cwd=out.parent, expect=expect)


def _scored(rec: Path, expect: int | None) -> dict:
    """``bench score REC --json``: the case of the results."""
    js = rec.with_suffix(".score.json")
    r = bench("score", str(rec), "--json", str(js), cwd=rec.parent, expect=expect)
    case = json.loads(js.read_text())["cases"][0]
    case["_printed"], case["_code"] = r.text, r.code
    return case


def _marked(rec: Path, source: str, accepted: bool) -> list[str]:
    """The source's problems ``rec`` carries in its ``run_start`` (asserted there)."""
    start = readable(rec, rec.parent)["metadata"]["run_start"]
    assert start["source_complete"] == "false", start
    assert start["accept_damaged_source"] == ("true" if accepted else "false"), start
    problems = json.loads(start["source_problems"])
    assert any(source in p for p in problems), problems
    return problems


def _untrusted(rec: Path, source: str) -> None:
    """``bench score`` of ``rec`` is ERROR naming the source ``source`` that cannot be trusted."""
    case = _scored(rec, expect=3)
    assert case["verdict"] == "ERROR", case["_printed"]
    issues = case["runs"][0]["bench_issues"]
    assert any(source in i and FLAG in i for i in issues), issues


def _accepted(rec: Path, verdict: str = "PASS") -> None:
    """``bench score`` of ``rec``, made with ``--accept-damaged-source``: judged on what it
    holds (``verdict``), with the note in ``runs[].notes``."""
    case = _scored(rec, expect={"PASS": 0, "FAIL": 1}[verdict])
    run = case["runs"][0]
    assert case["verdict"] == verdict and not run["bench_issues"], case["_printed"]
    assert any("cannot be trusted" in n and FLAG in n for n in run["notes"]), run["notes"]


# ----------------------------------------------------------------------- import-nav
@DAMAGES
def test_import_nav_onto_a_damaged_recording_carries_the_damage_into_the_copy_and_its_verdict(
        recording, result, tmp_path, damage):
    src = damage(recording, tmp_path / "src.mcap")
    copy = tmp_path / "copy.mcap"
    r = _import(result, src, copy, expect=3)
    assert "src.mcap" in r.err and FLAG in r.err and "cannot be trusted" in r.err
    _marked(copy, "src.mcap", accepted=False)
    _untrusted(copy, "src.mcap")
    # a copy of the copy keeps the mark: views of it, import-nav onto it
    again = tmp_path / "again.mcap"
    bench("views", str(copy), "-o", str(again), cwd=tmp_path, expect=3)
    _untrusted(again, "src.mcap")
    third = tmp_path / "third.mcap"
    _import(result, again, third, expect=3)
    _untrusted(third, "src.mcap")
    # accepted: judged, and the results say so
    ok = tmp_path / "accepted.mcap"
    r = _import(result, src, ok, FLAG, expect=0)
    assert "cannot be trusted" in r.err and "src.mcap" in r.err
    _marked(ok, "src.mcap", accepted=True)
    _accepted(ok)


# ---------------------------------------------------------------------------- views
@DAMAGES
def test_views_of_a_damaged_recording_carries_the_damage_into_the_copy_and_its_verdict(recording, tmp_path, damage):
    src = damage(recording, tmp_path / "src.mcap")
    copy = tmp_path / "views.mcap"
    r = bench("views", str(src), "-o", str(copy), cwd=tmp_path, expect=3)
    assert "src.mcap" in r.err and FLAG in r.err
    info = readable(copy, tmp_path)
    assert any(t.startswith("/foxglove/") for t in info["topics"])  # the views of what could be read
    _marked(copy, "src.mcap", accepted=False)
    _untrusted(copy, "src.mcap")
    again = tmp_path / "again.mcap"
    bench("views", str(copy), "-o", str(again), cwd=tmp_path, expect=3)
    _untrusted(again, "src.mcap")
    ok = tmp_path / "accepted.mcap"
    bench("views", str(src), "-o", str(ok), FLAG, cwd=tmp_path, expect=0)
    _marked(ok, "src.mcap", accepted=True)
    # judged on what could be read: the killed or flipped source lost some of its DUT output
    # (INTEGRITY-missing, -gap); the footer-damaged one lost nothing
    _accepted(ok, "PASS" if damage is footer_damaged else "FAIL")


# --------------------------------------------------------------------------- export
@DAMAGES
def test_export_of_a_damaged_recording_is_refused_unless_accepted_then_its_files_say_so(
        recording, result, tmp_path, damage):
    src = damage(recording, tmp_path / "src.mcap")
    out = tmp_path / "exp"
    r = bench("export", str(src), "-o", str(out), "--dut", cwd=tmp_path, expect=3)
    assert "src.mcap" in r.err and FLAG in r.err
    assert not (out / "imu.txt").exists() and not (out / "export.json").exists()
    r = bench("export", str(src), "-o", str(out), "--dut", FLAG, cwd=tmp_path, expect=0)
    assert "cannot be trusted" in r.text and "src.mcap" in r.text
    meta = json.loads((out / "export.json").read_text())
    assert meta["source_complete"] is False and meta["accept_damaged_source"] is True
    assert any("src.mcap" in p for p in meta["source_problems"]), meta
    note = (out / "SOURCE_PROBLEMS.txt").read_text()
    assert "src.mcap" in note and FLAG in note
    # the export of a copy of the damaged recording is refused too (the copy keeps the mark)
    copy = tmp_path / "copy.mcap"
    _import(result, src, copy, FLAG, expect=0)
    r = bench("export", str(copy), "-o", str(tmp_path / "exp2"), cwd=tmp_path, expect=3)
    assert "src.mcap" in r.err and FLAG in r.err
    # an export of the undamaged recording into the same folder drops the note
    bench("export", str(recording), "-o", str(out), cwd=tmp_path, expect=0)
    assert not (out / "SOURCE_PROBLEMS.txt").exists()
    assert json.loads((out / "export.json").read_text())["source_complete"] is True


# --------------------------------------------------------------------------- report
def test_a_report_of_recordings_shows_a_damaged_one_and_its_copies_as_error_with_the_damage_named(
        recording, result, tmp_path):
    recs = tmp_path / "recs"
    recs.mkdir()
    shutil.copy(recording, recs / "good.mcap")
    chunk_flipped(recording, tmp_path / "flipped.mcap")
    killed(recording, tmp_path / "killed.mcap")
    bench("views", str(tmp_path / "killed.mcap"), "-o", str(recs / "killed-views.mcap"), cwd=tmp_path)
    _import(result, tmp_path / "flipped.mcap", recs / "flipped-import.mcap", expect=None)
    out = tmp_path / "report"
    r = bench("report", str(recs), "-o", str(out), "--no-pdf", "--no-figures", "-q", cwd=tmp_path, expect=3)
    case = json.loads((out / "results.json").read_text())["cases"][0]
    runs = {Path(x["recording"]).name: x for x in case["runs"]}
    assert case["verdict"] == "ERROR", r.text
    assert runs["good.mcap"]["verdict"] == "PASS"
    for name, what in (("killed-views.mcap", "killed.mcap was never finished"),
                       ("flipped-import.mcap", "flipped.mcap is damaged")):
        assert runs[name]["verdict"] == "ERROR", (name, runs[name])
        assert any(what in i for i in runs[name]["bench_issues"]), runs[name]["bench_issues"]
    html = (out / "report.html").read_text()
    assert "killed.mcap was never finished" in html and "flipped.mcap is damaged" in html


# ------------------------------------------------------------------------ batch DUT
def test_a_right_batch_dut_passes_with_a_relative_output_folder(tmp_path):
    folder = tmp_path / "case"
    folder.mkdir()
    shutil.copy(EXCHANGE / "batch_case.toml", folder / "batch_case.toml")
    shutil.copy(EXCHANGE / "batch_dut.py", folder / "batch_dut.py")
    # the bench runs in tmp_path, the command in the case's folder: -o is relative to the first
    r = bench("run", "case/batch_case.toml", "-o", "out", "-q", "--no-plots", cwd=tmp_path, expect=0)
    case = json.loads((tmp_path / "out" / "results.json").read_text())["cases"][0]
    assert case["verdict"] == "PASS", r.text
    start = readable(tmp_path / "out" / "recordings" / "BATCH" / "BATCH-s1.mcap", tmp_path)["metadata"]["run_start"]
    argv = json.loads(start["batch_command"])
    assert Path(argv[2]) == tmp_path / "out" / "recordings" / "BATCH" / "BATCH-s1.batch" / "input"
    assert Path(argv[3]).is_absolute() and Path(argv[3]).is_file()  # {output}: the result it wrote


def test_a_report_of_a_results_record_whose_recording_is_now_damaged_is_error_never_its_last_verdict(
        recording, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(recording.parent.parent.parent, run)  # a bench run's folder: results.json, recordings/
    rec = run / "recordings" / "SHORT-DR" / recording.name
    chunk_flipped(recording, rec)  # damaged after it was judged PASS
    out = tmp_path / "report"
    r = bench("report", str(run), "-o", str(out), "--no-pdf", "-q", cwd=tmp_path, expect=3)
    assert f"{recording.name} is damaged" in r.err and "--rescore" in r.err
    html = (out / "report.html").read_text()
    assert f"{recording.name} is damaged" in html
    # re-judged, it is ERROR too
    bench("report", str(run), "-o", str(tmp_path / "again"), "--no-pdf", "--no-figures", "--rescore", "-q",
          cwd=tmp_path, expect=3)


# ------------------------------------------- import-nav onto a run whose own DUT failed
FAILING = """
[case]
id = "DF"
title = "a run whose in-process DUT fails at 5 s"
requirements = ["R"]
shortened = "10 s are enough"

[scenario]
script = "{short}"
duration = "10 s"

[sensors]
imu = {{ grade = "navigation", rate = "200 Hz" }}

[dut]
kind = "in_process"
name = "misbehave:Misbehave"
config = {{ mode = "crash_raise", at_s = 5.0 }}

[run]
seeds = [1]

[scoring.integrity]
quality_unmatched = {{ check = false, reason = "a .nav result without its STD file" }}

[[criterion]]
id = "H"
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "1 m"
"""


def test_import_nav_onto_a_run_whose_dut_failed_is_not_judged_on_that_dut_s_failure(tmp_path):
    """The run's own DUT failing is not the imported DUT's ending: the copy ends complete and
    the run that stopped early is a problem of its source (ERROR unless accepted), never the
    old DUT's FAIL charged to the new one (on 57b1bce the copy kept the ending)."""
    from tests.run.robust_util import MISBEHAVE, SHORT

    (tmp_path / "misbehave.py").write_text(MISBEHAVE.read_text())
    (tmp_path / "case.toml").write_text(FAILING.format(short=SHORT))
    out = tmp_path / "out"
    bench("run", str(tmp_path / "case.toml"), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, expect=1)
    rec = out / "recordings" / "DF" / "DF-s1.mcap"
    exp = tmp_path / "exp"
    bench("export", str(rec), "-o", str(exp), FLAG, cwd=tmp_path, expect=0)  # its truth, as a perfect result
    copy = tmp_path / "copy.mcap"
    bench("import-nav", str(exp / "truth.nav"), "--run", str(rec), "-o", str(copy), cwd=tmp_path, expect=3)
    with RecordingReader(copy) as r:
        assert r.metadata()["run_end"]["status"] == "complete"
    _marked(copy, "run ended with status 'dut_failed'", accepted=False)
    _untrusted(copy, "run ended with status 'dut_failed'")
    accepted = tmp_path / "accepted.mcap"
    bench("import-nav", str(exp / "truth.nav"), "--run", str(rec), "-o", str(accepted), FLAG, cwd=tmp_path,
          expect=0)
    _accepted(accepted)
