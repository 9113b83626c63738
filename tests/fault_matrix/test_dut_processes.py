"""The fault matrix (issue 32), a DUT's processes: an external DUT and a batch DUT that each
leave a daemon behind (double fork and ``setsid``: tests/run/duts/spawn_daemon.py). After
the run nothing the DUT started is left running (``bench()`` checks that no process with
the row's marker in its environment is), the daemon is named (pid, command line) in
results.json ``runs[].notes``, in summary.txt and in ``bench score`` of the recording, and
the verdict is the one the DUT earns without its daemon (PASS: leaving a daemon behind is
noted, not judged; docs/run_engine.md "How a run ends")."""

from __future__ import annotations

import json
from pathlib import Path

from tests.fault_matrix.matrix import HERE, bench
from tests.run.robust_util import alive, pids

SPAWN = HERE / "run" / "duts" / "spawn_daemon.py"
BATCH_DUT = HERE / "exchange" / "batch_dut.py"
SHORT = HERE / "data" / "short_drive.toml"

HARNESS = ("{python} -m bench.dut.harness --estimator dead_reckoning --can-interface {can_interface} "
           "--can-channel {can_channel} --can-port {can_port} --imu {imu_port} --gnss {gnss_port} --config {config}")

EXTERNAL = """
[case]
id = "DAEMON-EXT"
title = "an external DUT that leaves a daemon behind"
requirements = ["DR-POS"]

[scenario]
script = "{short}"
duration = "20 s"

[sensors]
imu = {{ grade = "seed000", rate = "200 Hz" }}
doppler = {{ model = "seed000" }}

[dut]
kind = "external"
command = "{{python}} {spawn} {pid_file} -- {harness}"
config = {{ initial_position = [34.246, 108.909, 380.0], alignment = "4 s" }}
startup_timeout = "60 s"  # hang guards, not speed bounds
shutdown_timeout = "60 s"

[dut.links]
can = {{ interface = "udp_multicast", channel = "239.74.168.1" }}

[clock]
mode = "lockstep"
step = "100 ms"
timeout = "60 s"

[scoring]
convergence = "5 s"

[run]
seeds = [3]

[[criterion]]
requirement = "DR-POS"
metric = "accuracy.horizontal.max"
window = {{ start = "10 s" }}
at_most = "5 m"
"""

BATCH = """
[case]
id = "DAEMON-BATCH"
title = "a batch DUT that leaves a daemon behind"
requirements = ["BATCH-POS"]
shortened = "a test of process hygiene, not of an estimator"

[scenario]
script = "S000"
duration = "10 s"

[sensors]
imu = {{ grade = "seed000", rate = "200 Hz" }}
doppler = "seed000"

[dut]
kind = "batch"
command = ["{{python}}", "{spawn}", "{pid_file}", "--", "{{python}}", "{batch_dut}", "{{input}}", "{{output}}", "truth"]
timeout = "120 s"

[scoring]
convergence = "1 s"

[[criterion]]
id = "POS"
requirement = "BATCH-POS"
metric = "accuracy.horizontal.rms"
window = "converged"
at_most = "1 m"
"""


def _daemon_named(out: Path, recording: Path, daemon: int, cwd: Path) -> None:
    """The daemon is named, with its command line, in results.json, summary.txt and
    ``bench score`` of the recording; the run's verdict is PASS."""
    results = json.loads((out / "results.json").read_text())
    (case,) = results["cases"]
    (run,) = case["runs"]
    assert run["verdict"] == "PASS" and case["verdict"] == "PASS", run
    named = [n for n in run["notes"] if f"pid {daemon} " in n and "sleep 600" in n]
    assert named, run["notes"]
    assert "left" in named[0] and "killed" in named[0], named[0]
    summary = (out / "summary.txt").read_text()
    assert f"pid {daemon} " in summary and "sleep 600" in summary, summary
    score = bench("score", str(recording), cwd=cwd, expect=0)
    assert f"pid {daemon} " in score.out and "sleep 600" in score.out, score.out


def test_an_external_dut_that_leaves_a_daemon_has_it_killed_and_named(ns, tmp_path):
    pid_file = tmp_path / "pids"
    case = tmp_path / "daemon_ext.toml"
    case.write_text(EXTERNAL.format(short=SHORT, spawn=SPAWN, pid_file=pid_file, harness=HARNESS))
    out = tmp_path / "out"
    bench("run", str(case), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, ns=ns, expect=0)
    (daemon,) = pids(pid_file)
    assert not alive(daemon)
    _daemon_named(out, out / "recordings" / "DAEMON-EXT" / "DAEMON-EXT-s3.mcap", daemon, tmp_path)


def test_a_batch_dut_that_leaves_a_daemon_has_it_killed_and_named(tmp_path):
    pid_file = tmp_path / "pids"
    case = tmp_path / "daemon_batch.toml"
    case.write_text(BATCH.format(spawn=SPAWN, pid_file=pid_file, batch_dut=BATCH_DUT))
    out = tmp_path / "out"
    bench("run", str(case), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, expect=0)
    (daemon,) = pids(pid_file)
    assert not alive(daemon)
    rec = next((out / "recordings" / "DAEMON-BATCH").glob("*.mcap"))
    _daemon_named(out, rec, daemon, tmp_path)
