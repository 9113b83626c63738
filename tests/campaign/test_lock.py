"""A campaign folder is held by one campaign at a time (bench.campaign.lock): a second one
is refused before it reads or writes anything; a lock left by a killed campaign is taken
over at once on its own kernel, and after a heartbeat watch when it names another host; a
run whose recording another process is still writing is waited for, never an ERROR; a
case judged ERROR says why. The SIGKILL and two-process cases, through `bench`, are rows of
tests/fault_matrix/test_campaign_lock.py."""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import threading
import time
from pathlib import Path

import pytest

from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.lock import LOCK_NAME, CampaignHeldError, acquire, lock_state, this_kernel
from bench.campaign.plan import plan_campaign
from bench.campaign.verdicts import judge_groups
from bench.campaign.work import RunBusyError, execute_run, load_record, record_path
from tests.campaign.conftest import bench_command, bench_env

HERE = Path(__file__).parent


def _copy(tmp_path: Path) -> Path:
    (tmp_path / "drive.toml").write_bytes((HERE / "drive.toml").read_bytes())
    case = tmp_path / "case.toml"
    case.write_bytes((HERE / "case.toml").read_bytes())
    return case


def _until(condition, what: str) -> None:
    end = time.monotonic() + 60.0  # a bound against a hang, not a timing assertion
    while not condition():
        assert time.monotonic() < end, what
        time.sleep(0.01)


def test_the_lock_names_its_holder_refuses_a_second_and_is_emptied_when_released(tmp_path):
    notes: list[str] = []
    with acquire(tmp_path, "bench campaign x", notice=notes.append) as held:
        info = json.loads((tmp_path / LOCK_NAME).read_text())
        assert info["pid"] == os.getpid() and info["host"] == this_kernel()["host"]
        assert info["boot_id"] == this_kernel()["boot_id"] and info["command"] == "bench campaign x"
        assert info["started_utc"] and info["bench_version"] and held.took_over is None
        with pytest.raises(CampaignHeldError) as refused:  # another open of the file: another holder
            acquire(tmp_path, notice=notes.append)
        assert f"pid {os.getpid()} on {info['host']}, since {info['started_utc']}" in str(refused.value)
        assert refused.value.holder == info
        assert lock_state(tmp_path) == ("held", info)
        assert json.loads((tmp_path / LOCK_NAME).read_text()) == info  # the refused one changed nothing
    assert (tmp_path / LOCK_NAME).read_text() == "" and lock_state(tmp_path) == ("free", None)
    assert notes == []
    with acquire(tmp_path, notice=notes.append):  # free again, nothing to say
        pass
    assert notes == []


def test_the_holder_beats(tmp_path):
    with acquire(tmp_path, notice=print, beat_s=0.01):
        _until(lambda: json.loads((tmp_path / LOCK_NAME).read_text() or "{}").get("beat", 0) >= 2, "no heartbeat")


def test_a_lock_left_on_this_kernel_is_taken_over_at_once(tmp_path):
    left = {**this_kernel(), "pid": 999999, "started_utc": "2026-01-01T00:00:00+00:00", "beat": 3}
    (tmp_path / LOCK_NAME).write_text(json.dumps(left))  # its holder killed: nobody holds its flock
    assert lock_state(tmp_path) == ("stale", left)
    notes: list[str] = []
    with acquire(tmp_path, notice=notes.append, watch_s=3600) as held:  # no watch: the kernel said it
        assert held.took_over == left
    (note,) = notes
    assert "taken over" in note and "pid 999999" in note


def test_a_lock_left_by_another_host_is_taken_over_when_no_heartbeat_is_seen(tmp_path):
    left = {"host": "node-17", "boot_id": "x", "pid": 4242, "started_utc": "2026-01-01T00:00:00+00:00", "beat": 9}
    (tmp_path / LOCK_NAME).write_text(json.dumps(left))
    notes: list[str] = []
    with acquire(tmp_path, notice=notes.append, watch_s=0.2) as held:
        assert held.took_over == left
    assert "watching its heartbeat" in notes[0] and "node-17" in notes[0]
    assert "taken over" in notes[1] and "pid 4242 on node-17" in notes[1]


def test_a_lock_of_another_host_whose_heartbeat_goes_on_is_refused(tmp_path):
    """A live campaign on a host whose locks this one cannot see (nolock NFS): its lock is
    free here, but it rewrites its lock file; the starter sees that and refuses."""
    path = tmp_path / LOCK_NAME
    alive = {"host": "node-17", "boot_id": "x", "pid": 4242, "started_utc": "2026-01-01T00:00:00+00:00", "beat": 0}
    path.write_text(json.dumps(alive))
    done = threading.Event()

    def beat() -> None:  # a holder that truncates its file before each rewrite: empty for an instant
        while not done.is_set():
            alive["beat"] += 1
            with open(path, "w") as fh:
                fh.flush()
                time.sleep(0.002)
                fh.write(json.dumps(alive))
            time.sleep(0.01)

    t = threading.Thread(target=beat)
    t.start()
    try:
        with pytest.raises(CampaignHeldError) as refused:
            acquire(tmp_path, notice=lambda m: None, watch_s=60)
    finally:
        done.set()
        t.join()
    assert "pid 4242 on node-17" in str(refused.value) and "does not share locks" in str(refused.value)
    assert json.loads(path.read_text())["host"] == "node-17"  # left to its holder


def test_a_held_folder_is_refused_before_anything_is_read_or_written(tmp_path):
    case = _copy(tmp_path)
    out = tmp_path / "out"
    (out / "runs").mkdir(parents=True)
    (out / "runs" / "0123.json").write_text("{}")  # a stale record --prune would delete
    with acquire(out, notice=print), pytest.raises(CampaignHeldError):
        run_campaign(CampaignOptions([str(case)], out, runs=1, prune=True, retry_errors=True))
    assert sorted(p.name for p in out.rglob("*")) == sorted(["runs", "0123.json", LOCK_NAME])


def _recording(out: Path, key: str) -> Path:
    return out / load_record(out, key)["recording"]


def test_a_run_being_written_by_another_process_is_no_error_of_the_run(tmp_path):
    (run,) = plan_campaign([_copy(tmp_path)], runs=1)
    out = tmp_path / "out"
    execute_run(run, str(out))
    recording = _recording(out, run.key)
    record_path(out, run.key).unlink()
    fd = os.open(recording, os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)  # a worker of a killed campaign, still writing this run
    try:
        with pytest.raises(RunBusyError) as busy:
            execute_run(run, str(out))
    finally:
        os.close(fd)
    assert busy.value.path == str(recording) and f"pid {os.getpid()}" in str(busy.value)
    assert not record_path(out, run.key).exists() and not list(out.rglob("bench-error.log"))


@pytest.mark.parametrize("leaves_record", [True, False], ids=["its-record-taken", "run-again"])
def test_a_campaign_waits_for_a_run_another_process_is_writing(tmp_path, leaves_record):
    case = _copy(tmp_path)
    out = tmp_path / "out"
    options = CampaignOptions([str(case)], out, runs=2, workers=1, env={"PYTHONPATH": bench_env()["PYTHONPATH"]})
    first = run_campaign(options)
    key = first["aggregate"]["keys"][0]
    saved = record_path(out, key).read_text()
    record_path(out, key).unlink()
    fd = os.open(out / json.loads(saved)["recording"], os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)  # a worker of a killed campaign, still writing the run
    notes: list[str] = []

    def notice(message: str) -> None:  # the campaign is waiting: the other process ends
        notes.append(message)
        if leaves_record:
            record_path(out, key).write_text(saved)
        os.close(fd)

    again = run_campaign(options, notice=notice)
    assert len(notes) == 1 and "being written by" in notes[0] and "waiting" in notes[0]
    inv = again["invocation"]
    assert (inv["executed"], inv["reused"]) == ((0, 2) if leaves_record else (1, 1))
    assert again["campaign"]["complete"] and again["aggregate"] == first["aggregate"]
    assert again["verdicts"] == first["verdicts"]
    assert not list(out.rglob("bench-error.log"))


def test_a_case_error_says_which_runs_were_error_and_why(tmp_path):
    case = _copy(tmp_path)
    plan = plan_campaign([case], runs=3)
    records = {r.key: execute_run(r, str(tmp_path / "out")) for r in plan}
    assert judge_groups(plan, records)["CMP-SYN"]["errors"] == []
    broken = dict(records)
    for r in plan[:2]:
        broken[r.key] = {**records[r.key], "verdict": "ERROR", "criteria": {}, "raw": {},
                         "bench_issues": ["the worker process died while running it (process 7 on n1): again"]}
    judged = judge_groups(plan, broken)["CMP-SYN"]
    assert judged["verdict"] == "ERROR"
    seeds = ", ".join(str(s) for s in sorted(broken[r.key]["seed"] for r in plan[:2]))
    assert judged["errors"] == [f"run ERROR (seeds {seeds}): the worker process died while running it "
                                "(process 7 on n1): again"]


def test_campaign_report_of_a_folder_a_campaign_holds_says_it_is_still_running(tmp_path):
    case = _copy(tmp_path)
    out = tmp_path / "out"
    run_campaign(CampaignOptions([str(case)], out, runs=1, workers=1, env={"PYTHONPATH": bench_env()["PYTHONPATH"]}))
    cmd = bench_command("campaign-report", str(out), "--no-pdf")
    with acquire(out, "bench campaign ...", notice=print) as held:
        during = subprocess.run(cmd, env=bench_env(), capture_output=True, text=True, timeout=300)
    assert during.returncode == 0, during.stderr
    assert "still running" in during.stderr and f"pid {os.getpid()}" in during.stderr
    html = (out / "campaign_report.html").read_text()
    assert 'id="running"' in html and held.info["started_utc"] in html
    after = subprocess.run(cmd, env=bench_env(), capture_output=True, text=True, timeout=300)
    assert after.returncode == 0 and "running" not in after.stderr
    assert 'id="running"' not in (out / "campaign_report.html").read_text()
