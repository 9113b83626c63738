"""The fault matrix (issue 32), reports: a full disk while the reports are written, and an
acceptance suite interrupted between its cases (what every row checks:
tests/fault_matrix/test_inputs.py).

A report file is never left empty or torn: each is written to a temporary name beside it
and renamed into place, and the message lists exactly which files were written and which
were not. An interrupted ``bench accept`` still writes the reports of the cases that
finished, marked incomplete, and exits 3.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import time
import uuid
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bench.report.results import validate_results
from tests.fault_matrix.matrix import BENCH, DRIVE, EXIT_CODES, MARK, Outcome, _marked, bench, case, readable

RECORDS = ("results.json", "junit.xml", "summary.txt", "summary.md")


def _ledger(text: str, command: str) -> tuple[Path, list[str], list[str]]:
    """The output folder, the files written and those not written, as the message lists them
    (``bench CMD: reports in OUT: written: a, b; not written: c``)."""
    lines = [ln for ln in text.splitlines() if ln.startswith(f"bench {command}: reports in ")]
    assert len(lines) == 1, text
    head, _, rest = lines[0].removeprefix(f"bench {command}: reports in ").partition(": written: ")
    done, _, missing = rest.partition("; not written: ")

    def names(s: str) -> list[str]:
        return [] if s in ("", "none") else s.split(", ")

    return Path(head), names(done), names(missing)


def _on_disk(out: Path) -> dict[str, int]:
    """Every file under ``out`` but the recordings and the traceback log, with its size."""
    return {p.relative_to(out).as_posix(): p.stat().st_size for p in sorted(out.rglob("*"))
            if p.is_file() and "recordings" not in p.relative_to(out).parts and p.name != "bench-error.log"}


def _whole(out: Path, name: str) -> None:
    """``name`` holds a complete report (parsed as what it is)."""
    p = out / name
    assert p.stat().st_size > 0, name
    if name == "results.json":
        validate_results(json.loads(p.read_text(encoding="utf-8")))
    elif name == "junit.xml":
        ET.parse(p)
    elif name in ("summary.txt", "summary.md"):
        assert "M10" in p.read_text(encoding="utf-8")
    elif name.endswith(".png"):
        assert p.read_bytes().startswith(b"\x89PNG") and p.read_bytes().endswith(b"IEND\xaeB`\x82")
    elif name == "report.pdf":
        assert p.read_bytes().startswith(b"%PDF") and b"%%EOF" in p.read_bytes()[-64:]
    elif name == "report.html":
        assert p.read_text(encoding="utf-8").rstrip().endswith("</html>")


# ------------------------------------------------------------------------ a full disk
@pytest.mark.parametrize("fsize", [0, 8192], ids=["nothing-fits", "summaries-fit"])
@pytest.mark.parametrize("command", ["run", "accept"])
def test_a_full_disk_leaves_no_empty_or_torn_report_and_the_message_names_what_was_and_was_not_written(
        tmp_path, command, fsize):
    """With every file limited to ``fsize`` bytes (EFBIG, as on a full disk: 0, nothing fits;
    8 KiB, the two summaries fit but neither results.json nor junit.xml, ~15 KiB each), no
    report is left empty or torn, no temporary file is left, and the message names exactly
    the files on disk as written and the others as not written."""
    out = tmp_path / "out"
    extra = ("--no-plots",) if command == "run" else ()  # accept: its plots and report.html/.pdf too
    r = bench(command, str(case(tmp_path)), "-o", str(out), "-q", *extra, cwd=tmp_path, fsize=fsize, expect=3)
    files = _on_disk(out)
    assert all(size > 0 for size in files.values()), f"empty report files {files}\n{r.text}"
    assert not [f for f in files if f.endswith(".tmp") or Path(f).name.startswith(".")], f"{files}\n{r.text}"
    for name in files:
        try:
            _whole(out, name)
        except Exception as exc:
            pytest.fail(f"{name} ({files[name]} bytes) is torn: {exc!r}\n{r.text}")
    folder, done, missing = _ledger(r.text, command)
    assert folder == out, r.text
    assert sorted(done) == sorted(files), f"on disk {files}\n{r.text}"
    meant = {*RECORDS}
    if command == "accept":
        meant |= {"report.html", "report.pdf"}  # and a plot per recording that has something to plot
    assert {*done, *missing} >= meant and not set(done) & set(missing), r.text
    assert {f for f in missing if not f.startswith("plots/")} == meant - set(done), r.text
    if fsize:
        assert set(done) >= {"summary.txt", "summary.md"} and {"results.json", "junit.xml"} <= set(missing), r.text
    else:
        assert done == [], r.text
    for name in missing:
        assert f"could not write {name}" in r.text or "not attempted" in r.text, r.text


# --------------------------------------------------------------- an interrupted suite
def _accept_interrupted(tmp_path: Path, sig: signal.Signals, *options: str) -> tuple[Outcome, Path]:
    """``bench accept`` of M0 (10 s), M1 (an hour's drive) and M2 (10 s), sent ``sig`` once M0
    is judged and M1's run is recording (its first progress line, drawn from inside the
    recording)."""
    cases = tmp_path / "cases"
    for k in (0, 1, 2):
        p = case(cases, f"c{k}.toml", script="long.toml" if k == 1 else "drive.toml")
        p.write_text(p.read_text().replace('id = "M10"', f'id = "M{k}"'))
    (cases / "long.toml").write_text(DRIVE.format(duration="3600 s", extra=""))
    out = tmp_path / "reports"
    mark = uuid.uuid4().hex
    p = subprocess.Popen([*BENCH, "accept", str(cases), "-o", str(out), "--no-plots", *options], cwd=tmp_path,
                         env={**os.environ, MARK: mark, "COLUMNS": "200"}, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    guard = threading.Timer(300, p.kill)  # a hang guard, not a timing assertion
    guard.start()
    try:
        seen: list[str] = []
        for line in p.stderr:  # type: ignore[union-attr]
            seen.append(line)
            if line.startswith("  M1 seed 1:"):
                break
        else:
            pytest.fail("".join(seen))
        assert any("=> M0: PASS" in ln for ln in seen), "".join(seen)
        p.send_signal(sig)
        out_text, err_text = p.communicate()
    finally:
        guard.cancel()
    outcome = Outcome(p.returncode, out_text, "".join(seen) + err_text)
    assert p.returncode in EXIT_CODES and "Traceback" not in outcome.text, outcome.text
    deadline = time.monotonic() + 60.0  # processes being reaped by the kernel (a hang guard)
    while _marked(mark) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _marked(mark)
    return outcome, out


@pytest.mark.parametrize(("sig", "options"), [(signal.SIGINT, ()), (signal.SIGTERM, ("--no-report",))],
                         ids=["SIGINT-with-report", "SIGTERM"])
def test_an_interrupted_accept_writes_the_finished_cases_reports_marked_incomplete(tmp_path, sig, options):
    r, out = _accept_interrupted(tmp_path, sig, *options)
    assert r.code == 3, r.text
    assert f"interrupted by {sig.name}" in r.text, r.text
    assert (out / "results.json").is_file(), f"no results.json; {sorted(os.listdir(out))}\n{r.text}"
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    validate_results(results)
    assert results["interrupted"] == {"by": sig.name, "finished": ["M0"], "unfinished": ["M1"],
                                      "not_run": ["M2"]}, results.get("interrupted")
    assert results["verdict"] == "ERROR"
    verdicts = {c["id"]: c["verdict"] for c in results["cases"]}
    assert verdicts == {"M0": "PASS", "M1": "ERROR", "M2": "ERROR"}, verdicts
    m0 = next(c for c in results["cases"] if c["id"] == "M0")
    assert m0["criteria"] and [run["seed"] for run in m0["runs"]] == [1]  # judged as if nothing happened
    errors = {c["id"]: " ".join(c["errors"]) for c in results["cases"]}
    assert "interrupted" in errors["M1"] and "did not finish" in errors["M1"], errors
    assert "interrupted" in errors["M2"] and "not run" in errors["M2"], errors
    readable(out / "recordings" / "M1" / "M1-s1.mcap", tmp_path)  # the interrupted run, finished as far as it got

    junit = ET.parse(out / "junit.xml").getroot()
    marks = [tc for tc in junit.iter("testcase") if tc.get("name") == "interrupted"]
    assert len(marks) == 1 and marks[0].find("error") is not None
    assert "M1" in marks[0].find("error").text and "M2" in marks[0].find("error").text
    m0_suite = next(s for s in junit.iter("testsuite") if s.get("name") == "M0")
    assert m0_suite.get("errors") == "0" and m0_suite.get("failures") == "0"
    for name in ("summary.txt", "summary.md"):
        first = (out / name).read_text(encoding="utf-8").lstrip("#*- ").splitlines()[0]
        assert first.startswith("INCOMPLETE") and sig.name in first and "M1" in first and "M2" in first, first
    folder, done, missing = _ledger(r.text, "accept")
    assert folder == out and missing == [], r.text
    if "--no-report" in options:
        assert sorted(done) == sorted(RECORDS) and not (out / "report.html").exists(), r.text
    else:
        assert sorted(done) == sorted([*RECORDS, "report.html", "report.pdf"]), r.text
        html = (out / "report.html").read_text(encoding="utf-8")
        assert 'id="incomplete"' in html and "INCOMPLETE" in html.split("<body>", 1)[1][:4000]
