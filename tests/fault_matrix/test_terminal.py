"""The fault matrix (issue 34, items 11 and 8): what ``bench accept`` and ``bench run`` print
for a person at a terminal and for a log, and the reproduction command their reports print.

Every row runs ``bench`` as a user would (tests/fault_matrix/matrix.py: exit code, no
traceback, nothing left running) on the 10 s synthetic case, a few seconds each:

* progress is a bar only when stderr is a terminal (a pseudo-terminal here); in a log it is
  plain lines, never a carriage-return frame (on 57b1bce the log held tqdm's ``\\r`` frames);
* the summary on stdout lists the criteria that are not PASS and counts the rest (on
  57b1bce it printed every criterion, the default integrity checks at zero included);
* Ctrl-C (SIGINT, raised halfway through a run) ends the bar's line and prints
  ``bench: interrupted by SIGINT`` on a line of its own, in a log and on a terminal;
* a DUT that never loaded (an in-process estimator that does not exist) has no recording,
  and nothing printed names one (on 57b1bce ``bench run`` printed ``recording: PATH`` of a
  file never written);
* the reproduction command of a report (``results.json`` and the HTML report), run as
  printed from where the suite ran, exits as the original did and writes into a fresh
  output folder (on 57b1bce it exited 2: the recordings are not overwritten without
  ``--force``), and the report names the bench version; its re-judging command runs as
  printed too (on 57b1bce ``bench report results.json --rescore`` lacked ``-o``: exit 2).
"""

from __future__ import annotations

import html
import json
import os
import pty
import re
import select
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from bench import __version__
from tests.fault_matrix.matrix import BENCH, EXIT_CODES, MARK, Outcome, _marked, bench, case

SHORT_DR = Path(__file__).parent.parent / "run" / "data" / "short_dr.toml"


def _suite(folder: Path, *, fail: bool = False) -> Path:
    """Cases M0 (PASS) and, with ``fail``, M1 whose accuracy limit (1 mm) it FAILs."""
    p = case(folder, "c0.toml")
    p.write_text(p.read_text().replace('id = "M10"', 'id = "M0"'))
    if fail:
        p = case(folder, "c1.toml", limit='at_most = "1 mm"')
        p.write_text(p.read_text().replace('id = "M10"', 'id = "M1"'))
    return folder


def _screen(raw: str) -> list[str]:
    """What a terminal shows for ``raw``: a carriage return goes back to the line's start,
    what follows overwrites it (escape sequences are dropped: none is expected)."""
    raw = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", raw)
    lines, col = [""], 0
    for ch in raw:
        if ch == "\n":
            lines.append("")
            col = 0
        elif ch == "\r":
            col = 0
        else:
            line = lines[-1].ljust(col)
            lines[-1] = line[:col] + ch + line[col + 1:]
            col += 1
    return [ln.rstrip() for ln in lines]


def _on_terminal(cmd: list[str], cwd: Path, *, columns: int = 120) -> Outcome:
    """Run ``cmd`` with stderr on a pseudo-terminal of ``columns`` (stdout a pipe); the
    outcome's ``err`` is the raw bytes the terminal received, decoded."""
    import fcntl
    import struct
    import termios

    mark = uuid.uuid4().hex
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, columns, 0, 0))
    p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL,
                         env={**os.environ, MARK: mark, "COLUMNS": str(columns)})
    os.close(slave)
    chunks: list[bytes] = []
    out = b""
    watched = [master, p.stdout]
    try:
        while True:
            ready, _, _ = select.select(watched, [], [], 240)  # a hang guard
            if not ready:
                p.kill()
                pytest.fail("bench did not finish within 240 s")
            if p.stdout in ready:
                data = p.stdout.read1(65536)  # type: ignore[union-attr]
                out += data
                if not data:  # stdout closed: only the terminal is left to read
                    watched.remove(p.stdout)
            if master in ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # the slave side closed: bench ended
                    data = b""
                if not data:
                    break
                chunks.append(data)
        out += p.stdout.read()  # type: ignore[union-attr]
        p.wait(timeout=240)
    finally:
        os.close(master)
    outcome = Outcome(p.returncode, out.decode(), b"".join(chunks).decode(errors="replace"))
    assert p.returncode in EXIT_CODES and "Traceback" not in outcome.text, outcome.text
    assert not _marked(mark)
    return outcome


# ------------------------------------------------------ progress: a bar only on a terminal
def test_in_a_log_progress_is_plain_lines_without_carriage_returns(tmp_path):
    cases = _suite(tmp_path / "cases")
    r = bench("accept", str(cases), "-o", str(tmp_path / "out"), cwd=tmp_path, expect=0)
    assert "\r" not in r.err, repr(r.err[:400])
    lines = r.err.splitlines()
    assert "  M0 seed 1: 10/10 s (100%)" in lines, r.err  # the run's progress, in words
    assert "report: figures: 1/1 recordings (100%)" in lines, r.err
    progress = [ln for ln in lines if re.fullmatch(r".*: \d+/\d+ \w+ \(\d+%\)", ln)]
    assert 2 <= len(progress) <= 2 * 11, r.err  # the start, each tenth passed: bounded, not a frame per update


def test_on_a_terminal_progress_is_a_bar_drawn_in_place(tmp_path):
    cases = _suite(tmp_path / "cases")
    r = _on_terminal([*BENCH, "accept", str(cases), "-o", str(tmp_path / "out"), "--no-report"], tmp_path)
    assert r.code == 0, r.text
    assert "\r" in r.err  # redrawn in place
    bars = [ln for ln in _screen(r.err) if ln.startswith("  M0 seed 1:") and "%|" in ln]
    assert len(bars) == 1 and "100%|" in bars[0] and "10/10 s" in bars[0], _screen(r.err)


# ------------------------------------------ the summary: what is not PASS, and a count of the rest
def test_the_summary_lists_the_criteria_not_pass_and_counts_the_rest(tmp_path):
    cases = _suite(tmp_path / "cases", fail=True)
    out = tmp_path / "out"
    r = bench("accept", str(cases), "-o", str(out), "-q", "--no-report", "--no-plots", cwd=tmp_path, expect=1)
    table = [ln for ln in r.out.splitlines() if ln.startswith(("M0 ", "M1 "))]
    assert len(table) == 1 and table[0].split()[1] == "H" and table[0].split()[-1] == "FAIL", r.out
    assert "INTEGRITY-" not in r.out, r.out  # twenty integrity checks at zero, each PASS: counted, not listed
    assert "22 criteria: 21 PASS, 1 FAIL" in r.out, r.out
    assert "21 criteria PASS, not listed (20 of them default integrity checks)" in r.out, r.out
    assert "FAIL     M1" in r.out and "PASS     M0" in r.out, r.out  # one line per case
    assert str(out / "summary.txt") in r.out
    full = (out / "summary.txt").read_text(encoding="utf-8")
    assert full.count("INTEGRITY-") == 20, full  # the file keeps every row


# --------------------------------------------------------------------------- Ctrl-C
INTERRUPTING = """
import os
import signal
import sys
import time

import bench.acceptance.runner as runner
from bench.acceptance.synthetic import SyntheticRunner
from bench.cli import main


class Interrupting:
    def run(self, case, seed, out_dir, *, progress=None):
        progress(3.0, 10.0)
        progress(5.0, 10.0)
        os.kill(os.getpid(), signal.SIGINT)  # the user's Ctrl-C, halfway through the run
        # the handler runs between two bytecodes of the main thread: wait for it here (a
        # sleep is cut by it) so that a loaded machine cannot carry the run on past it
        for _ in range(3000):  # a hang guard, not a timing bound
            time.sleep(0.01)
        progress(6.0, 10.0)
        return SyntheticRunner().run(case, seed, out_dir, progress=progress)


runner._FACTORIES["synthetic"] = Interrupting
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("where", ["log", "terminal"])
@pytest.mark.parametrize("command", ["accept", "run"])
def test_ctrl_c_prints_interrupted_on_a_line_of_its_own(tmp_path, command, where):
    cases = _suite(tmp_path / "cases")
    script = tmp_path / "interrupting_bench.py"
    script.write_text(INTERRUPTING)
    cmd = [sys.executable, str(script), command, str(cases if command == "accept" else cases / "c0.toml"),
           "-o", str(tmp_path / "out"), *(["--no-report"] if command == "accept" else [])]
    if where == "log":
        p = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=240)
        r = Outcome(p.returncode, p.stdout, p.stderr)
        assert "Traceback" not in r.text, r.text
        assert "\r" not in r.err, repr(r.err)
        shown = r.err.splitlines()
        assert "  M0 seed 1: 5/10 s (50%)" in shown, r.err
        assert not any("6/10" in ln for ln in shown), r.err  # nothing drawn past the interrupt
    else:
        r = _on_terminal(cmd, tmp_path)
        shown = _screen(r.err)
        bars = [ln for ln in shown if "%|" in ln]
        assert len(bars) == 1 and bars[0].startswith("  M0 seed 1: "), shown  # left where it stood
        assert bars[0].endswith("]"), shown  # nothing written onto the bar's line after it
    assert r.code == 3, r.text
    assert "bench: interrupted by SIGINT" in shown, shown  # a line of its own
    assert shown.count("bench: interrupted by SIGINT") == 1, shown


# ------------------------------------------------- a DUT that never loaded has no recording
@pytest.mark.parametrize("command", ["run", "accept"])
def test_a_dut_that_never_loaded_prints_no_recording_path(tmp_path, command):
    bad = tmp_path / "bad.toml"
    text = SHORT_DR.read_text().replace('name = "dead_reckoning"', 'name = "no_such_estimator"')
    bad.write_text(text.replace("../../data/short_drive.toml", str(SHORT_DR.parent.parent.parent / "data"
                                                                    / "short_drive.toml")))
    out = tmp_path / "out"
    r = bench(command, str(bad), "-o", str(out), "--no-plots", cwd=tmp_path, expect=2)  # a configuration error
    assert "no estimator 'no_such_estimator'" in r.text, r.text
    assert not (out / "recordings" / "SHORT-DR" / "SHORT-DR-s3.mcap").exists()
    named = re.findall(r"(?:^|[\s:,])((?:/|out/)[^\s,;:()]+\.(?:mcap|json|xml|txt|md|html|pdf|png))", r.text,
                       flags=re.M)
    assert named, r.text
    for name in named:  # every file named on the terminal exists
        path = Path(name) if Path(name).is_absolute() else tmp_path / name
        assert path.is_file(), f"{name} is named but was not written\n{r.text}"
    assert ".mcap" not in r.text, r.text
    if command == "accept":  # the report of a suite whose DUT never loaded is written too
        assert (out / "report.html").is_file() and "could not write" not in r.err, r.text


# ----------------------------------------------------- the reproduction command reproduces
def _rerun(command: str, cwd: Path) -> subprocess.CompletedProcess:
    """``command`` as printed, through a shell from ``cwd``, with this environment's
    ``bench`` first on PATH."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    return subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True, timeout=240)


@pytest.mark.parametrize(("command", "fail", "report"), [
    ("accept", False, True), ("accept", True, False), ("run", True, False)],
    ids=["accept-pass-html", "accept-fail-json", "run-fail-json"])
def test_the_reproduction_command_runs_as_printed_and_exits_as_the_original(tmp_path, command, fail, report):
    work = tmp_path / "work"
    cases = _suite(work / "cases", fail=fail)
    target = ["accept", "cases"] if command == "accept" else ["run", "cases/c1.toml"]
    extra = [] if report else ["--no-report"] if command == "accept" else []
    first = bench(*target, "-o", "reports", "-q", "--no-plots", *extra, cwd=work)
    assert first.code == (1 if fail else 0), first.text
    assert cases.is_dir()
    results = json.loads((work / "reports" / "results.json").read_text(encoding="utf-8"))
    printed = results["identification"]["command"]
    if report:
        page = (work / "reports" / "report.html").read_text(encoding="utf-8")
        section = page.split('<section id="reproduction">', 1)[1].split("</section>", 1)[0]
        shown = [html.unescape(x) for x in re.findall(r"<pre[^>]*>(.*?)</pre>", section, flags=re.S)]
        assert shown[0] == printed, (shown, printed)  # the report's text is the record's command
        assert f"bench {__version__}" in html.unescape(re.sub(r"<[^>]+>", "", section)), section
        printed = shown[0]
        rescore = _rerun(shown[1], tmp_path)  # the re-judging command runs as printed too
        assert rescore.returncode == first.code, (shown[1], rescore.stdout, rescore.stderr)
        assert (work / "reports" / "rescored" / "report.html").is_file(), shown[1]
    before = sorted(p.name for p in (work / "reports" / "recordings").rglob("*.mcap"))
    stamps = {p: p.stat().st_mtime_ns for p in (work / "reports" / "recordings").rglob("*.mcap")}
    again = _rerun(printed, work)  # where the suite ran
    assert again.returncode == first.code, (printed, again.stdout, again.stderr)
    assert "Traceback" not in again.stdout + again.stderr
    fresh = [p for p in work.iterdir() if p.name.startswith("reports-rerun-")]
    assert len(fresh) == 1 and (fresh[0] / "results.json").is_file(), sorted(os.listdir(work))
    assert sorted(p.name for p in (fresh[0] / "recordings").rglob("*.mcap")) == before
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # the first run's evidence untouched
    rerun = json.loads((fresh[0] / "results.json").read_text(encoding="utf-8"))
    assert [c["verdict"] for c in rerun["cases"]] == [c["verdict"] for c in results["cases"]]
