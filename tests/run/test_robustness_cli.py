"""The ``bench`` command as a process against misbehaving DUTs, and signals: a crashing
DUT ends ``bench run`` cleanly with the reason; SIGINT and SIGTERM finish the recording
and stop the DUT; SIGKILL leaves a recording readable up to its last chunk and a DUT
that exits when the bench hangs up its lines.

The DUT is tests/run/duts/misbehave.py on pty pairs and python-can udp_multicast inside a
network namespace (fixture ``ns``).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cli.app import interrupts
from bench.cli.app import run as bench_cli
from bench.cli.info import describe
from bench.errors import ConfigError, RecordingError
from bench.record.mcap_io import RecordingReader
from bench.shield import depth as shield_depth
from bench.shield import shielded
from tests.run.robust_util import (
    alive,
    dut_command,
    external_case,
    group_members,
    log_texts,
    no_process_left,
    pids,
    wait_for,
)

CLI = [sys.executable, "-c", "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
       "from bench.cli import main; sys.exit(main())"]


# ---------------------------------------------------------------------------------- signals
@pytest.fixture
def sigint_default():
    """SIGINT handled as in an interactive shell, whatever started this test process (a
    background job of a non-interactive shell inherits SIGINT ignored)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def test_sigterm_and_sigint_raise_keyboard_interrupt_once_then_are_reported_then_abort(capsys, sigint_default):
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    with interrupts():
        with pytest.raises(KeyboardInterrupt) as first:
            signal.raise_signal(signal.SIGTERM)
        assert first.value.args == ("SIGTERM",)
        signal.raise_signal(signal.SIGINT)  # second: reported, cleanup goes on
        assert "still finishing the recording" in capsys.readouterr().err
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)  # third: abort
    assert {s: signal.getsignal(s) for s in before} == before


def test_a_shielded_section_holds_the_first_signal_to_its_end_and_never_the_third(sigint_default):
    done = []
    with interrupts():
        with pytest.raises(KeyboardInterrupt) as held, shielded():
            with shielded():
                signal.raise_signal(signal.SIGTERM)
                done.append("inner")
            done.append("outer")  # the outermost section still runs to its end
        assert done == ["inner", "outer"] and held.value.args == ("SIGTERM",)
    with interrupts(), pytest.raises(KeyboardInterrupt), shielded():
        signal.raise_signal(signal.SIGINT)  # held
        signal.raise_signal(signal.SIGINT)  # reported
        signal.raise_signal(signal.SIGINT)  # the user insists: at once
        done.append("not reached")
    assert done == ["inner", "outer"] and shield_depth() == 0


def test_an_ignored_sigint_stays_ignored_as_nohup_asked():
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with interrupts():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            signal.raise_signal(signal.SIGINT)  # nothing happens
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)


def _case(tmp_path: Path, mode: str, **config) -> Path:
    """A test case running the misbehaving DUT over udp_multicast (default port) for 90 s."""
    cfg = ", ".join(f"{k} = {json.dumps(v)}" for k, v in {"mode": mode, **config}.items())
    return external_case(tmp_path / "robust.toml", case_id="ROBUST", command=dut_command(None, None),
                         config=f"{{ {cfg} }}", channel="239.74.164.201", run='truth_rate = "1000 Hz"')


def _bench_run(ns: str, case: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(["ip", "netns", "exec", ns, *CLI, "run", str(case), "-o", str(out), "-q", "--no-plots"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _recording(out: Path) -> Path:
    return out / "recordings" / "ROBUST" / "ROBUST-s1.mcap"


def _bench_time(progress: Path) -> float:
    """Bench time the DUT reports having reached, s (-1 before it wrote any)."""
    try:
        return float(progress.read_text() or -1)
    except (FileNotFoundError, ValueError):
        return -1.0


def _has_truth(path: Path) -> bool:
    """Whether the recording being written holds truth yet (polled while the bench writes:
    the file may exist before its header does, which the reader rightly refuses)."""
    if not path.exists():
        return False
    try:
        info = RecordingReader(path).topics().get("/truth")
    except (ConfigError, RecordingError):  # not an MCAP recording yet (empty, or the header half written)
        return False
    return info is not None and info.messages > 0


@pytest.mark.slow
def test_bench_run_with_a_crashing_dut_exits_cleanly_with_the_reason(ns, tmp_path):
    pid_file = tmp_path / "pids"
    case = _case(tmp_path, "crash_exit", at_s=1.0, pid_file=str(pid_file))
    p = _bench_run(ns, case, tmp_path / "out")
    stdout, stderr = p.communicate(timeout=120)
    assert "Traceback" not in stderr
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    run_json = results["cases"][0]["runs"][0]
    # a DUT that crashed during its acceptance run has failed it: FAIL, exit code 1 (issue 32)
    assert (results["cases"][0]["verdict"], p.returncode) == ("FAIL", 1), (stdout, stderr)
    assert any("gyro channel X saturated" in issue for issue in run_json["dut_issues"])  # the reason is reported
    assert not run_json["bench_issues"]
    end = describe(str(_recording(tmp_path / "out")))["ended"]
    assert end["status"] == "dut_failed" and "exited with code 3" in end["reason"]
    no_process_left(pid_file)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_finish_the_recording_and_stop_the_dut(ns, tmp_path, sig):
    pid_file = tmp_path / "pids"
    progress = tmp_path / "progress"
    case = _case(tmp_path, "slow", delay_s=0.003, pid_file=str(pid_file), progress_file=str(progress))
    out = tmp_path / "out"
    p = _bench_run(ns, case, out)
    try:
        wait_for(lambda: _bench_time(progress) >= 2.0, 60, "the run to reach 2 s of bench time")
        p.send_signal(sig)
        _, stderr = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == 3, stderr
    assert f"bench: interrupted by {sig.name}" in stderr and "Traceback" not in stderr
    d = describe(str(_recording(out)))
    assert d["complete"] is True
    assert d["ended"] == {"status": "interrupted", "reason": f"interrupted by {sig.name}"}
    assert d["metadata"]["dut_exit"]["ended"] == "exited on SIGTERM"
    sol = RecordingReader(_recording(out)).read_columnar("/dut/nav_solution")
    # the DUT got to step 2.0 s only after the bench had its answers up to 1.99 s
    assert d["topics"]["/dut/nav_solution"]["samples"] == len(sol) and sol["t_ns"].max() >= 1_990_000_000
    assert any("harness: stopped on a signal" in t for _, t in log_texts(_recording(out)))
    no_process_left(pid_file)


@pytest.mark.slow
def test_sigkill_leaves_a_readable_recording_and_the_harness_exits_on_hang_up(ns, tmp_path, capsys):
    pid_file = tmp_path / "pids"
    progress = tmp_path / "progress"
    case = _case(tmp_path, "slow", delay_s=0.003, pid_file=str(pid_file), progress_file=str(progress))
    out = tmp_path / "out"
    p = _bench_run(ns, case, out)
    try:
        dut = wait_for(lambda: pids(pid_file), 60, "the DUT to start")[0]  # (every wait here: a hang guard)
        wait_for(lambda: _has_truth(_recording(out)), 60, "the first chunk of the recording")
        wait_for(lambda: _bench_time(progress) >= 1.0, 60, "the run to reach 1 s of bench time")
        p.kill()
        p.wait(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == -signal.SIGKILL
    # bench info reads the unfinished file up to its last complete chunk
    assert bench_cli(["info", "--json", str(_recording(out))]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["complete"] is False
    assert d["ended"]["status"] == "unfinished"
    assert d["metadata"]["run_start"]["dut_kind"] == "external"
    truth = d["topics"]["/truth"]
    assert truth["samples"] > 1000 and truth["span_s"][0] == 0.0
    assert RecordingReader(_recording(out)).read_columnar("/truth")["t_ns"].size == truth["samples"]
    # nobody stops the DUT: it notices that the bench hung up its pty lines and exits
    wait_for(lambda: not alive(dut), 60, "the orphaned DUT to exit")
    wait_for(lambda: not group_members(dut), 60, "the DUT's group to end")


@pytest.mark.slow
def test_sigterm_finishes_a_bench_synth_recording(tmp_path):
    out = tmp_path / "s000.mcap"
    p = subprocess.Popen([*CLI, "synth", "S000", "-o", str(out), "-q"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: _has_truth(out), 120, "the first chunk of the recording")
        p.send_signal(signal.SIGTERM)
        _, stderr = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 3 and "bench: interrupted by SIGTERM" in stderr
    d = describe(str(out))
    assert d["complete"] is True and d["ended"]["status"] == "interrupted"
    assert 0 < d["span_s"][1] < 3600.0  # stopped early


def test_the_recording_poll_waits_for_a_file_still_without_its_header(tmp_path):
    """What the tests above poll: a file the bench has created but not yet written a
    header to is 'no truth yet', not an error (it failed them under load)."""
    path = tmp_path / "being_written.mcap"
    path.write_bytes(b"")
    assert _has_truth(path) is False
    path.write_bytes(b"\x89MC")  # a part of the magic
    assert _has_truth(path) is False
