"""The run engine against misbehaving DUTs (the ``bench`` command as a process, and
signals: test_robustness_cli.py).

External DUTs are real processes (tests/run/duts/misbehave.py: the reference harness
around an estimator that misbehaves on cue) on pty pairs and python-can udp_multicast
inside a network namespace. Every run must end with the reason in its recording, the
DUT's output on /dut/log, ``dut_exit`` metadata, and no process of the DUT's group left.

The start-up, lockstep and shutdown limits are hang guards (:data:`HANG_S`) wherever the
test is not about that limit, so a loaded machine is slower, never failed; where it is
(a DUT that never answers, hangs or ignores SIGTERM), the DUT never meets it, so the
outcome does not depend on the machine's speed either.
"""

from __future__ import annotations

import gc
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.dut.estimator import Estimator, EstimatorOutput, register_estimator
from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.run.traffic import BENCH_TIME_ID
from bench.scenario.loader import load_scenario
from bench.topics import NAV_SOLUTION_DTYPE
from tests.run.robust_util import (
    SHORT,
    TABLES,
    dut_command,
    log_texts,
    no_process_left,
    pids,
)
from tests.transport import netns

#: Hang guard, s: a DUT that does not start, answer or stop within a minute hangs.
HANG_S = 60.0


def _spec(out: Path, dut: DutSpec, *, port: int = 0, duration_s: float = 2.0, timeout_s: float = HANG_S) -> RunSpec:
    links = LinkSpec(can={"interface": "udp_multicast", "channel": f"239.74.164.{port % 250}", "port": port}) \
        if port else LinkSpec()
    return RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), dut=dut, out=out,
                   links=links, clock=ClockSpec(timeout_s=timeout_s), duration_ns=round(duration_s * 1e9))


def _external(ns: str, tmp_path: Path, port: int, mode: str, *, startup_s: float = HANG_S, shutdown_s: float = HANG_S,
              **config):
    """Run the misbehaving DUT in ``mode``; returns (result, pid file)."""
    pid_file = tmp_path / "pids"
    dut = DutSpec("external", command=dut_command(ns, port), config={"mode": mode, "pid_file": str(pid_file), **config},
                  startup_timeout_s=startup_s, shutdown_timeout_s=shutdown_s)
    spec = _spec(tmp_path / f"{mode}.mcap", dut, port=port)
    return netns.call_in(ns, lambda: run(spec)), pid_file


def _decoded(values: dict[str, str]) -> dict:
    """Metadata values as written (non-strings are stored as JSON)."""
    out = {}
    for k, v in values.items():
        try:
            out[k] = json.loads(v)
        except ValueError:
            out[k] = v
    return out


def _ended(path: Path) -> tuple[dict, dict]:
    """``run_end`` and ``dut_exit`` of a finished recording."""
    md = RecordingReader(path).metadata()
    assert RecordingReader(path).complete
    return md["run_end"], _decoded(md.get("dut_exit", {}))


# ---------------------------------------------------------------------------------- (a) crash
@pytest.mark.slow
@pytest.mark.parametrize(
    ("mode", "port", "exit_text", "last_line"),
    [
        ("crash_exit", 43411, "with code 3", "fatal: gyro channel X saturated"),
        ("crash_abort", 43412, "on signal SIGABRT", "assertion failed in the filter update"),
        ("crash_raise", 43413, "with code 1", "RuntimeError: filter diverged at 1.00 s"),
    ],
)
def test_a_dut_crashing_mid_run_ends_as_dut_failed_with_its_exit_and_last_output(
    ns, tmp_path, mode, port, exit_text, last_line
):
    res, pid_file = _external(ns, tmp_path, port, mode, at_s=1.0)
    assert res.status == "dut_failed"
    assert f"the DUT process exited {exit_text} at bench time 1.0" in res.reason
    assert last_line in res.reason  # the last output lines name the cause
    end, dut_exit = _ended(res.path)
    assert end == {"status": "dut_failed", "reason": res.reason}
    assert dut_exit["exit"] == exit_text and dut_exit["ended"] == "exited by itself"
    logged = log_texts(res.path)
    assert any(stream == "stderr" and last_line in text for stream, text in logged)
    assert any("misbehave: pid" in t for _, t in logged)
    # everything up to the crash was exchanged and recorded
    sol = RecordingReader(res.path).read_columnar("/dut/nav_solution")
    assert 0.9e9 <= sol["t_ns"].max() < 1.0e9 + 1
    no_process_left(pid_file)


@pytest.mark.slow
def test_a_dut_killed_by_a_sigkill_the_bench_did_not_send_is_an_ending_it_cannot_pin_on_the_dut(ns, tmp_path):
    """The OOM killer or an operator: whose fault it was the bench cannot tell, so the run
    ends dut_error (ERROR, "the bench cannot tell"), never FAIL, never a crash of the bench."""
    res, pid_file = _external(ns, tmp_path, 43415, "sigkill", at_s=1.0)
    assert res.status == "dut_error", (res.status, res.reason)
    assert "the DUT process exited on signal SIGKILL at bench time 1.0" in res.reason
    assert "the bench did not send" in res.reason and "cannot tell" in res.reason
    assert _ended(res.path)[0] == {"status": "dut_error", "reason": res.reason}
    no_process_left(pid_file)


@pytest.mark.slow
def test_a_dut_crashing_in_a_real_time_run_ends_it_at_once(ns, tmp_path):
    pid_file = tmp_path / "pids"
    dut = DutSpec("external", command=dut_command(ns, 43414), config={"mode": "crash_exit", "at_s": 1.0,
                                                                      "pid_file": str(pid_file)},
                  startup_timeout_s=HANG_S, shutdown_timeout_s=HANG_S)
    spec = _spec(tmp_path / "rt.mcap", dut, port=43414, duration_s=60.0)
    spec.clock = ClockSpec(mode="realtime", speed=4.0)
    spec.window_ns = 60_000_000_000  # one window: its end is not when the crash is seen
    res = netns.call_in(ns, lambda: run(spec))
    assert res.status == "dut_failed"
    assert "the DUT process exited with code 3 at bench time" in res.reason and "gyro channel X" in res.reason
    # seen by the checks during the emission (every 100 ms of bench time), not at the end of
    # the window; how soon after the step depends on how fast the DUT process dies (at 4x
    # real time the 59 s left are 15 s of wall time for it: a hang guard, not a speed bound)
    died = [float(t.split()[2]) for _, t in log_texts(res.path) if t.startswith("misbehave: step")]
    seen = float(res.reason.split("at bench time ")[1].split(" s")[0])
    assert len(died) == 1 and died[0] <= seen < 59.0
    assert _ended(res.path)[0]["status"] == "dut_failed"
    no_process_left(pid_file)


# ---------------------------------------------------------------------------------- (b) hang
@pytest.mark.slow
def test_a_hanging_dut_ends_as_dut_failed_after_the_lockstep_timeout(ns, tmp_path):
    pid_file = tmp_path / "pids"
    dut = DutSpec("external", command=dut_command(ns, 43421), config={"mode": "hang", "at_s": 0.5,
                                                                      "pid_file": str(pid_file)},
                  startup_timeout_s=HANG_S, shutdown_timeout_s=0.5)
    # the lockstep timeout is what is tested; 5 s leaves the healthy steps before 0.5 s room on a loaded machine
    res = netns.call_in(ns, lambda: run(_spec(tmp_path / "hang.mcap", dut, port=43421, timeout_s=5.0)))
    assert res.status == "dut_failed"
    assert "no DUT_READY for bench time 0.500 s within 5 s" in res.reason
    assert "misbehave: hanging at 0.50 s" in res.reason
    end, dut_exit = _ended(res.path)
    assert end["status"] == "dut_failed"
    # it sleeps through SIGTERM (the harness only sets a flag), so it is killed
    assert dut_exit["terminated_in_time"] is False and dut_exit["exit"] == "on signal SIGKILL"
    assert ("stdout", "misbehave: hanging at 0.50 s") in log_texts(res.path)
    no_process_left(pid_file)


# ---------------------------------------------------------------------------------- (c) never starts
@pytest.mark.slow
def test_a_dut_exiting_at_start_up_ends_as_dut_failed(ns, tmp_path):
    res, pid_file = _external(ns, tmp_path, 43431, "exit_at_once")
    assert res.status == "dut_failed"
    assert "the DUT process exited with code 2 during start-up, before answering BENCH_TIME(0 s)" in res.reason
    assert "cannot open the IMU device" in res.reason
    assert res.bench_s == 0.0
    end, dut_exit = _ended(res.path)
    assert end["status"] == "dut_failed" and dut_exit["exit_code"] == 2
    assert ("stderr", "misbehave: cannot open the IMU device: no such file") in log_texts(res.path)
    no_process_left(pid_file)


@pytest.mark.slow
def test_a_dut_that_never_answers_ends_as_dut_failed_at_the_start_up_timeout(ns, tmp_path):
    res, pid_file = _external(ns, tmp_path, 43432, "never_ready", startup_s=1.5)
    assert res.status == "dut_failed"
    assert "did not answer BENCH_TIME(0 s) with DUT_READY within 1.5 s of its start" in res.reason
    end, dut_exit = _ended(res.path)
    assert end["status"] == "dut_failed"
    # asleep (or not yet that far) before the harness installed its handler: SIGTERM's
    # default action ends it; how far it got in 1.5 s depends on the machine's load, so what
    # it printed is not asserted here (the crash tests check that a DUT's lines are recorded)
    assert dut_exit["exit"] == "on signal SIGTERM" and dut_exit["ended"] == "exited on SIGTERM"
    tx = RecordingReader(res.path).read_columnar("/wire/can/tx")
    assert np.count_nonzero(tx["can_id"] == BENCH_TIME_ID) >= 2  # BENCH_TIME(0) repeated while waiting, all recorded
    no_process_left(pid_file)


@pytest.mark.slow
def test_a_dut_that_cannot_be_started_ends_as_dut_failed(tmp_path):
    dut = DutSpec("external", command="/nonexistent/dut --imu {imu_port}")
    res = run(_spec(tmp_path / "none.mcap", dut))
    assert res.status == "dut_failed" and "cannot start the DUT '/nonexistent/dut'" in res.reason
    assert _ended(res.path)[0]["status"] == "dut_failed"


# ---------------------------------------------------------------------------------- (d) flood
@pytest.mark.slow
def test_a_dut_flooding_the_bus_ends_as_dut_failed(ns, tmp_path):
    res, pid_file = _external(ns, tmp_path, 43441, "flood", at_s=0.5, flood_frames=1000)
    assert res.status == "dut_failed"
    assert "the DUT floods the bus" in res.reason and "(limit 200)" in res.reason
    assert "within the step ending at 0.500 s" in res.reason
    end, dut_exit = _ended(res.path)
    assert end["status"] == "dut_failed" and dut_exit["terminated_in_time"] is True
    rx = RecordingReader(res.path).read_columnar("/wire/can/rx")
    assert len(rx) > 200  # what it sent is recorded
    no_process_left(pid_file)


# ---------------------------------------------------------------------------------- (e) orphans
@pytest.mark.slow
def test_a_dut_ignoring_sigterm_is_killed_with_its_children(ns, tmp_path):
    res, pid_file = _external(ns, tmp_path, 43451, "ignore_term", shutdown_s=1.0)
    assert res.ok, res.reason
    assert len(pids(pid_file)) == 2  # the DUT and its child
    end, dut_exit = _ended(res.path)
    assert end["status"] == "complete"
    assert dut_exit["terminated_in_time"] is False
    assert dut_exit["ended"] == "killed: still running 1 s after SIGTERM"
    no_process_left(pid_file)


# ---------------------------------------------------------------------------------- (f) in process
class _Raises(Estimator):
    name = "raises_at_1s"

    def step(self, inputs):
        if inputs.t_ns >= 1_000_000_000:
            raise ZeroDivisionError("innovation covariance is singular")
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol)


class _Says(Estimator):
    name = "says_at_close"

    def step(self, inputs):
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol)

    def close(self):
        print("summary: 200 epochs")
        print("diagnostics: {\"x\": 1}", file=sys.stderr)


def test_what_an_in_process_estimator_writes_at_close_is_on_the_dut_log(tmp_path):
    register_estimator("says_at_close", _Says)
    res = run(_spec(tmp_path / "says.mcap", DutSpec("in_process", name="says_at_close")))
    assert res.ok, res.reason
    logs = [m for _, m in RecordingReader(res.path).iter_json("/dut/log")]
    assert [(m["stream"], m["text"]) for m in logs] == [("stdout", "summary: 200 epochs"),
                                                       ("stderr", 'diagnostics: {"x": 1}')]
    assert logs[0]["t_ns"] == 2_000_000_000  # the last step's bench time


class _BadConfig(Estimator):
    name = "bad_config"

    def configure(self, config):
        raise KeyError("lever_arm")

    def step(self, inputs):  # pragma: no cover - never reached
        return EstimatorOutput()


def test_an_in_process_estimator_that_raises_ends_as_dut_failed(tmp_path):
    register_estimator("raises_at_1s", _Raises)
    res = run(_spec(tmp_path / "raises.mcap", DutSpec("in_process", name="raises_at_1s")))
    assert res.status == "dut_failed"
    assert "the estimator 'raises_at_1s' raised at bench time 1.000 s" in res.reason
    assert "ZeroDivisionError: innovation covariance is singular" in res.reason
    r = RecordingReader(res.path)
    md = r.metadata()
    assert md["run_end"]["status"] == "dut_failed"
    assert "raise ZeroDivisionError" in md["dut_traceback"]["traceback"]  # where in the estimator
    assert r.read_columnar("/dut/nav_solution")["t_ns"].max() == 990_000_000
    assert "solutions" in md["dut_output"]


def test_a_real_time_run_ending_in_error_gives_back_its_scheduling_and_the_garbage_collector(tmp_path):
    register_estimator("raises_at_1s", _Raises)
    policy = os.sched_getscheduler(0)
    spec = _spec(tmp_path / "rt.mcap", DutSpec("in_process", name="raises_at_1s"))
    spec.clock = ClockSpec(mode="realtime", speed=4.0)
    res = run(spec)
    assert res.status == "dut_failed" and "raised at bench time 1.000 s" in res.reason
    assert gc.isenabled() and os.sched_getscheduler(0) == policy


def test_an_in_process_estimator_that_fails_to_configure_ends_as_dut_failed(tmp_path):
    register_estimator("bad_config", _BadConfig)
    res = run(_spec(tmp_path / "bad.mcap", DutSpec("in_process", name="bad_config")))
    assert res.status == "dut_failed"
    assert "the estimator 'bad_config' failed to start: KeyError: 'lever_arm'" in res.reason
    assert _ended(res.path)[0]["status"] == "dut_failed"
