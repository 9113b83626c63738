"""Every process a DUT starts ends with its run (bench/dut/reaper.py, issue 32): a daemon
(double fork and ``setsid``: tests/run/duts/spawn_daemon.py) is found, ended and named,
with a cgroup where this machine lets the bench make one and with the subreaper and the
token otherwise; the subreaper is on only while a DUT runs; what was adopted is reaped;
a process without the run's token -- another run's, or the host's own -- is never touched.

The waits are hang guards (a minute), never speed bounds.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from bench.dut.cgroup import RunCgroup
from bench.dut.process import DutProcess
from bench.dut.reaper import TOKEN_ENV, DutProcesses, subreaper_state
from bench.errors import DutError
from bench.exchange.batch import run_command
from tests.run.robust_util import alive, pids, proc_state, wait_for

SPAWN = Path(__file__).parent.parent / "run" / "duts" / "spawn_daemon.py"
HANG_S = 60.0


def _cgroup_available() -> bool:
    cg = RunCgroup.create("probe" + os.urandom(4).hex())
    if cg is None:
        return False
    cg.remove()
    return True


CGROUP = _cgroup_available()
#: both ways of tracking where this machine has a cgroup, the subreaper alone otherwise
MODES = [pytest.param(True, id="cgroup", marks=pytest.mark.skipif(not CGROUP, reason="no writable cgroup v2 here")),
         pytest.param(False, id="subreaper")]


def _dut(pid_file: Path, then: str = "import time; time.sleep(600)") -> list[str]:
    """A DUT that starts a daemon (its id appended to ``pid_file``), then runs ``then``."""
    return [sys.executable, "-c", f"import sys; sys.path.insert(0, {str(SPAWN.parent)!r}); "
            f"from spawn_daemon import start_daemon; start_daemon({str(pid_file)!r}); {then}"]


def _children_zombies() -> set[int]:
    """Zombie children of this process."""
    out = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            f = stat[stat.rindex(")") + 2 :].split()
            if f[0] == "Z" and int(f[1]) == os.getpid():
                out.add(int(d.name))
    return out


def _kill(pid: int) -> None:
    """Kill a process this test started outside any DUT (and reap it if it was adopted)."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        return
    wait_for(lambda: not alive(pid), HANG_S, f"process {pid} to die")
    with contextlib.suppress(ChildProcessError):  # adopted while a subreaper: reap it
        os.waitpid(pid, 0)


@pytest.mark.parametrize("cgroup", MODES)
def test_a_daemon_of_an_external_dut_is_ended_and_named(tmp_path, cgroup):
    pid_file = tmp_path / "pids"
    p = DutProcess(_dut(pid_file), shutdown_timeout_s=HANG_S, cgroup=cgroup)
    assert p.tracking == ("cgroup" if cgroup else "subreaper")
    (daemon,) = wait_for(lambda: pids(pid_file), HANG_S, "the daemon")
    assert alive(daemon)
    p.close()
    assert not alive(daemon)
    (left,) = p.left_running
    assert (left.pid, left.command, left.ended) == (daemon, "sleep 600", "ended on SIGTERM")
    # its group had been ended first: the DUT itself is not counted as left running
    assert proc_state(p.pid) is None and p.ended == "exited on SIGTERM"
    assert daemon not in _children_zombies()  # adopted (subreaper) then reaped, or never ours (cgroup)
    assert p.close() == p.exit_code and p.left_running == [left]  # idempotent


def test_the_bench_is_a_subreaper_only_while_a_dut_runs_and_reaps_what_it_adopted(tmp_path):
    if subreaper_state():
        pytest.skip("the process running the tests is a subreaper already")
    pid_file = tmp_path / "pids"
    assert subreaper_state() is False
    procs = DutProcesses(cgroup=False)
    leader = procs.popen(_dut(pid_file, then="pass"))  # starts the daemon and exits: an orphan
    assert procs.tracking == "subreaper" and subreaper_state() is True
    (daemon,) = wait_for(lambda: pids(pid_file), HANG_S, "the daemon")
    leader.wait()
    # the orphan was reparented to this process, not to init
    wait_for(lambda: Path(f"/proc/{daemon}/stat").read_text().rsplit(")", 1)[1].split()[1] == str(os.getpid()),
             HANG_S, "the daemon to be adopted")
    (left,) = procs.end(HANG_S)
    assert left.pid == daemon and left.ended == "ended on SIGTERM"
    assert proc_state(daemon) is None, "the adopted daemon was not reaped"
    assert subreaper_state() is False


def test_a_sigterm_ignoring_daemon_is_killed_after_the_grace(tmp_path):
    pid_file = tmp_path / "pids"
    code = (f"import sys; sys.path.insert(0, {str(SPAWN.parent)!r}); from spawn_daemon import start_daemon; "
            f"start_daemon({str(pid_file)!r}, ('sh', '-c', 'trap \"\" TERM; while :; do sleep 1; done'))")
    procs = DutProcesses(cgroup=False)
    procs.popen([sys.executable, "-c", code]).wait()
    (daemon,) = wait_for(lambda: pids(pid_file), HANG_S, "the daemon")
    left = {x.pid: x.ended for x in procs.end(0.2)}  # its `sleep 1` children too
    assert left[daemon] == "killed (SIGKILL) 0.2 s after SIGTERM"
    assert not alive(daemon)


@pytest.mark.parametrize("cgroup", MODES)
def test_a_process_without_the_runs_token_is_never_touched(tmp_path, cgroup):
    """An orphan of the host's own work (adopted while the subreaper is on) and another
    run's daemon live on; only this run's daemon is ended."""
    mine, other, host = tmp_path / "mine", tmp_path / "other", tmp_path / "host"
    a, b = DutProcesses(cgroup=cgroup), DutProcesses(cgroup=cgroup)
    a.popen(_dut(mine, then="pass")).wait()
    b.popen(_dut(other, then="pass")).wait()
    env = {k: v for k, v in os.environ.items() if k != TOKEN_ENV}
    subprocess.run(_dut(host, then="pass"), env=env, check=True)  # the host's own daemon, no token
    (d_mine,), (d_other,), (d_host,) = (wait_for(lambda f=f: pids(f), HANG_S, "a daemon") for f in (mine, other, host))
    try:
        left = a.end(HANG_S)
        assert [x.pid for x in left] == [d_mine]
        assert not alive(d_mine) and alive(d_other) and alive(d_host)
        if not cgroup:
            assert subreaper_state() is True  # b still runs
        assert [x.pid for x in b.end(HANG_S)] == [d_other]
        assert alive(d_host)
    finally:
        a.end(0), b.end(0)
        _kill(d_host)


def test_a_process_that_dropped_the_token_is_found_by_its_session(tmp_path):
    """A batch DUT whose background job (in its session, environment cleared) outlives it."""
    pid_file = tmp_path / "pids"
    # the job is a fork of the shell until it has run env, then sleep: the shell waits for that
    script = f'env -i sleep 600 & echo $! > "{pid_file}"; until grep -qx sleep /proc/$!/comm; do sleep 0.01; done'
    out = run_command(["sh", "-c", script], tmp_path, HANG_S, tmp_path, cgroup=False)
    assert out.failure is None and out.tracking == "subreaper"
    (job,) = pids(pid_file)
    assert [(x.pid, x.command) for x in out.left_running] == [(job, "sleep 600")]
    assert not alive(job)


@pytest.mark.parametrize("cgroup", MODES)
def test_a_batch_dut_daemon_is_ended_and_named_and_the_command_still_judged(tmp_path, cgroup):
    pid_file = tmp_path / "pids"
    out = run_command(_dut(pid_file, then="print('done')"), tmp_path, HANG_S, tmp_path, cgroup=cgroup)
    (daemon,) = pids(pid_file)
    assert out.failure is None and [ln.text for ln in out.lines] == ["done"]
    assert [(x.pid, x.command, x.ended) for x in out.left_running] == [(daemon, "sleep 600", "ended on SIGTERM")]
    assert out.tracking == ("cgroup" if cgroup else "subreaper")
    assert not alive(daemon)
    assert json.loads(out.run_start["dut_left_running"]) == [
        {"pid": daemon, "command": "sleep 600", "ended": "ended on SIGTERM"}]


def test_a_batch_dut_past_its_timeout_has_its_daemon_ended_too(tmp_path):
    pid_file = tmp_path / "pids"
    out = run_command(_dut(pid_file), tmp_path, 0.5, tmp_path)
    (daemon,) = pids(pid_file)
    assert out.failure is not None and "timeout" in out.failure
    assert [x.pid for x in out.left_running] == [daemon] and not alive(daemon)


def test_concurrent_runs_in_threads_each_end_their_own(tmp_path):
    """Two DUTs in two threads of one process (a Dask worker's tasks): each run ends its
    own daemon, not the other's, and the subreaper stays on until the last has ended."""
    files = [tmp_path / "a", tmp_path / "b"]
    results: dict[int, list] = {}
    started = threading.Barrier(2)

    def one(k: int) -> None:
        p = DutProcess(_dut(files[k]), shutdown_timeout_s=HANG_S, cgroup=False)
        wait_for(lambda: pids(files[k]), HANG_S, "the daemon")
        started.wait(HANG_S)
        if k == 1:  # the second ends after the first has
            wait_for(lambda: 0 in results, HANG_S, "the first run's end")
            results[2] = [subreaper_state()]
        p.close()
        results[k] = [x.pid for x in p.left_running]

    threads = [threading.Thread(target=one, args=(k,)) for k in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(HANG_S)
    (da,), (db,) = pids(files[0]), pids(files[1])
    assert results[0] == [da] and results[1] == [db]
    assert results[2] == [True]  # on while the second ran
    assert not alive(da) and not alive(db)


def test_no_cgroup_is_left_behind(tmp_path):
    if not CGROUP:
        pytest.skip("no writable cgroup v2 here")
    procs = DutProcesses()
    cg = procs._cgroup
    assert cg is not None and cg.folder.is_dir()
    procs.popen(_dut(tmp_path / "pids", then="pass")).wait()
    procs.end(HANG_S)
    assert not cg.folder.exists()
    # a run that never started its DUT removes it too
    procs = DutProcesses()
    folder = procs._cgroup.folder if procs._cgroup is not None else None
    assert procs.end(0) == [] and folder is not None and not folder.exists()


def test_a_dut_that_cannot_start_releases_everything():
    before = subreaper_state()
    with pytest.raises(DutError, match="cannot start"):
        DutProcess(["/nonexistent/dut"], cgroup=False)
    assert subreaper_state() == before


def test_children_of_a_killed_dut_adopted_by_the_bench_are_reaped():
    """A DUT ignoring SIGTERM with a child ignoring it too: both are killed with the group;
    the child, orphaned by the DUT's death and adopted by the bench (a subreaper), is
    reaped, not left a zombie."""
    code = (
        "import signal, subprocess, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
        "c = subprocess.Popen([sys.executable, '-c', "
        "'import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(600)']); "
        "print(c.pid, flush=True); time.sleep(600)"
    )
    p = DutProcess([sys.executable, "-c", code], shutdown_timeout_s=0.2, cgroup=False)
    child = wait_for(lambda: next((int(ln.text) for ln in p.take_lines() if ln.stream == "stdout"), None), HANG_S,
                     "the DUT's child")
    p.close()
    assert not p.terminated_in_time
    assert p.left_running == []  # ended with its group, not left running
    assert proc_state(child) is None, f"the DUT's child is {proc_state(child)}, not reaped"


def test_without_a_subreaper_a_daemon_out_of_the_benchs_descent_is_named_not_killed(tmp_path, monkeypatch):
    """Where no subreaper can be set (``token``), an orphan goes to init: it carries the
    run's token but no longer descends from the bench, so it is named, not signalled."""
    import bench.dut.reaper as reaper

    if subreaper_state():
        pytest.skip("the process running the tests is a subreaper already")
    monkeypatch.setattr(reaper, "_acquire_subreaper", lambda: False)
    pid_file = tmp_path / "pids"
    procs = DutProcesses(cgroup=False)
    procs.popen(_dut(pid_file, then="pass")).wait()
    assert procs.tracking == "token"
    (daemon,) = wait_for(lambda: pids(pid_file), HANG_S, "the daemon")
    try:
        (left,) = procs.end(HANG_S)
        assert (left.pid, left.ended) == (daemon, "not killed: no longer a descendant of the bench")
        assert alive(daemon)
    finally:
        _kill(daemon)
