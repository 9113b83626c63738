"""The run engine against an external DUT that leaves a daemon behind (issue 32): the
misbehaving DUT (tests/run/duts/misbehave.py) in its ``daemon`` mode starts ``sleep 600``
with a double fork and ``setsid`` at start-up, then behaves. The run ends as it would
without the daemon; the daemon is ended, named in ``dut_exit`` ``left_running`` and in
the notes scoring makes of the recording; nothing of the DUT is left.

Also in a run the DUT ends badly (it hangs, and is killed at the shutdown): its daemon is
ended too (the verdict of such a run is not what this file is about).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.scenario.loader import load_scenario
from bench.scoring.data import load_run
from bench.scoring.integrity import check_integrity
from tests.run.robust_util import SHORT, TABLES, alive, dut_command, no_process_left, pids
from tests.transport import netns

HANG_S = 60.0  # hang guards, not speed bounds


def _run(ns: str, tmp_path: Path, port: int, mode: str, *, timeout_s: float = HANG_S, shutdown_s: float = HANG_S,
         **config):
    pid_file = tmp_path / "pids"
    dut = DutSpec("external", command=dut_command(ns, port), config={"mode": mode, "pid_file": str(pid_file), **config},
                  startup_timeout_s=HANG_S, shutdown_timeout_s=shutdown_s)
    spec = RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), dut=dut,
                   out=tmp_path / f"{mode}.mcap", clock=ClockSpec(timeout_s=timeout_s), duration_ns=2_000_000_000,
                   links=LinkSpec(can={"interface": "udp_multicast", "channel": f"239.74.169.{port % 250}",
                                       "port": port}))
    return netns.call_in(ns, lambda: run(spec)), pid_file


def _left_running(path: Path) -> list[dict]:
    return json.loads(RecordingReader(path).metadata()["dut_exit"]["left_running"])


@pytest.mark.slow
def test_a_dut_daemon_is_ended_named_and_noted_and_the_run_ends_as_without_it(ns, tmp_path):
    res, pid_file = _run(ns, tmp_path, 43481, "daemon")
    assert res.status == "complete", res.reason
    _dut, daemon = pids(pid_file)
    assert not alive(daemon)
    left = {"pid": daemon, "command": "sleep 600", "ended": "ended on SIGTERM"}
    assert res.dut_exit["left_running"] == [left] and _left_running(res.path) == [left]
    assert res.dut_exit["process_tracking"] in ("cgroup", "subreaper")
    assert res.dut_exit["ended"] == "exited on SIGTERM"  # the DUT itself, as before
    notes = check_integrity(load_run(res.path)).notes
    assert len(notes) == 1 and f"pid {daemon} `sleep 600` (ended on SIGTERM)" in notes[0]
    no_process_left(pid_file)


@pytest.mark.slow
def test_the_daemon_of_a_dut_killed_at_the_shutdown_is_ended_too(ns, tmp_path):
    res, pid_file = _run(ns, tmp_path, 43482, "hang", daemon=True, at_s=0.5, timeout_s=5.0, shutdown_s=0.5)
    assert res.status != "complete"
    _dut, daemon = pids(pid_file)
    assert not alive(daemon)
    assert [x["pid"] for x in _left_running(res.path)] == [daemon]
    assert res.dut_exit["ended"].startswith("killed")
    no_process_left(pid_file)
