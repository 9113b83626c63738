"""An estimator that fails ends the run as the DUT's failure that says how, in process and
through the harness: an epoch later than the step time (named by its time of validity
and the step), an exception (its traceback on /dut/log, in the recording's metadata and
in the crash log beside it), something that is not an EstimatorOutput. The run still
finishes its recording with the epochs of the steps before; the run ends ``dut_failed``
and the verdict is FAIL with the reason, as for every DUT failure (a crashing external
DUT too); a MemoryError in process, which the bench cannot pin on the estimator, is
``dut_error``, ERROR."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.crashlog import LOG_NAME
from bench.dut.estimator import Estimator, EstimatorOutput, register_estimator
from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.scenario.loader import load_scenario
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from tests.dut.harness_util import drive_harness
from tests.run.robust_util import dut_command, log_texts, no_process_left
from tests.transport import netns

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"
AT_NS = 1_000_000_000


class _FailsAt1s(Estimator):
    """One epoch (and its quality) per step until 1 s, then what ``how`` says."""

    name = "fails_at_1s"

    def configure(self, config):
        self.how = config["how"]

    def step(self, inputs):
        t = inputs.t_ns
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        q = np.zeros(1, NAV_QUALITY_DTYPE)
        sol["t_ns"] = q["t_ns"] = t
        if t >= AT_NS:
            if self.how == "late_solution":
                sol["t_ns"] = t + 10_000_000
            elif self.how == "late_quality":
                q["t_ns"] = t + 1_000  # 1 us: the wire's resolution
            elif self.how == "raises":
                return self._diverge(t)
            elif self.how == "none":
                return None
            elif self.how == "not_records":
                return EstimatorOutput([1, 2, 3])
            elif self.how == "layout":
                bad = np.zeros(1, [("t_ns", "<i8"), ("lat", "U8")])
                bad["t_ns"], bad["lat"] = t, "north"
                return EstimatorOutput(bad)
        return EstimatorOutput(sol, q)

    def _diverge(self, t):
        raise ZeroDivisionError(f"innovation covariance singular at {t}")


register_estimator(_FailsAt1s.name, _FailsAt1s)

CASE = """
[case]
id = "F1"
title = "an estimator failing at 1 s"
requirements = ["R"]
shortened = "the estimator fails at 1 s"

[scenario]
script = "{script}"
duration = "3 s"

[sensors]
imu = {{ grade = "navigation", rate = "200 Hz" }}

[dut]
kind = "in_process"
name = "fails_at_1s"
config = {{ how = "{how}" }}

[[criterion]]
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "1000 km"
"""

REASONS = {
    "late_solution": "the estimator 'fails_at_1s' returned an epoch with time of validity 1.010000 s at the step "
                     "1.000000 s: later than the step time",
    "late_quality": "the estimator 'fails_at_1s' returned an epoch with time of validity 1.000001 s at the step "
                    "1.000000 s: later than the step time",
    "raises": "the estimator 'fails_at_1s' raised at bench time 1.000 s: ZeroDivisionError: innovation covariance "
              "singular at 1000000000",
    "none": "the estimator 'fails_at_1s' returned a NoneType at bench time 1.000 s, not an EstimatorOutput",
    "not_records": "the estimator 'fails_at_1s' raised at bench time 1.000 s: TypeError: EstimatorOutput.solutions: "
                   "expected a 1-D array of NAV_SOLUTION records, found a list",
    "layout": "the estimator 'fails_at_1s' at bench time 1.000 s: estimator output is not of the NAV record layout",
}


def _case(tmp_path: Path, how: str) -> Path:
    path = tmp_path / "case.toml"
    path.write_text(CASE.format(script=SHORT, how=how))
    return path


@pytest.mark.parametrize("how", list(REASONS))
def test_an_in_process_estimator_that_fails_ends_the_run_as_its_failure_saying_how(tmp_path, how):
    result = run_case(load_case(_case(tmp_path, how)), SuiteOptions(tmp_path / "out"))
    assert result.verdict is Verdict.FAIL  # the DUT failed: FAIL, never ERROR
    assert any(REASONS[how] in issue for issue in result.runs[0].dut_issues), result.runs[0].dut_issues
    assert not result.runs[0].bench_issues
    rec = RecordingReader(result.runs[0].recording)
    assert rec.complete
    end = rec.metadata()["run_end"]
    assert end["status"] == "dut_failed" and end["reason"].startswith(REASONS[how]), end
    sol = rec.read_columnar("/dut/nav_solution")
    assert sol["t_ns"].max() == AT_NS - 10_000_000 and len(sol) == 100  # every epoch of the steps before
    q = rec.read_columnar("/dut/nav_quality")
    assert q["t_ns"].max() == AT_NS - 10_000_000 and len(q) == 100
    np.testing.assert_array_equal(q["epoch"], sol["epoch"])


def test_an_estimator_that_raises_leaves_its_traceback_in_the_recording_and_the_crash_log(tmp_path):
    result = run_case(load_case(_case(tmp_path, "raises")), SuiteOptions(tmp_path / "out"))
    path = Path(result.runs[0].recording)
    rec = RecordingReader(path)
    reason = rec.metadata()["run_end"]["reason"]
    log = path.parent / LOG_NAME
    assert reason.endswith(f" (traceback in {log})"), reason
    stderr = [(d["t_ns"], d["text"]) for _, d in rec.iter_json("/dut/log") if d["stream"] == "stderr"]
    texts = [text for _, text in stderr]
    assert texts[0] == "Traceback (most recent call last):" and "in _diverge" in "\n".join(texts)
    assert texts[-1] == "ZeroDivisionError: innovation covariance singular at 1000000000"
    assert {t for t, _ in stderr} == {AT_NS}  # at the bench time of the step that raised
    assert "in _diverge" in rec.metadata()["dut_traceback"]["traceback"]
    crash = log.read_text()
    assert "DUT error (not the bench's): the estimator 'fails_at_1s' raised at bench time 1.000 s" in crash
    assert "in _diverge" in crash and "ZeroDivisionError: innovation covariance singular" in crash


class _BadStart(Estimator):
    name = "bad_start_api"

    def configure(self, config):
        raise KeyError("lever_arm")

    def step(self, inputs):  # pragma: no cover - never reached
        return EstimatorOutput()


def test_an_estimator_failing_to_start_leaves_its_traceback_on_the_dut_log(tmp_path):
    register_estimator(_BadStart.name, _BadStart)
    spec = RunSpec(scenario=load_scenario(SHORT), tables={"imu": {"grade": "navigation"}}, schedule=FaultSchedule(),
                   dut=DutSpec("in_process", name=_BadStart.name), out=tmp_path / "s.mcap", duration_ns=AT_NS)
    res = run(spec)
    assert res.status == "dut_failed" and "failed to start: KeyError: 'lever_arm'" in res.reason
    texts = [d["text"] for _, d in RecordingReader(res.path).iter_json("/dut/log") if d["stream"] == "stderr"]
    assert texts[-1] == "KeyError: 'lever_arm'" and any("in configure" in t for t in texts)
    assert "in configure" in (tmp_path / LOG_NAME).read_text()


# ----------------------------------------------------------------------- the harness
@pytest.mark.parametrize("how", list(REASONS))
def test_the_harness_ends_with_the_same_message_after_answering_the_steps_before(how):
    done = drive_harness(_FailsAt1s.name, {"how": how}, 150)
    assert done.error is not None and str(done.error).startswith(REASONS[how]), done.error
    assert ("in _diverge" in done.error.traceback) == (how == "raises")
    assert done.nav.ready_ns.max() == AT_NS - 10_000_000 and len(np.unique(done.nav.ready_ns)) == 100
    assert done.nav.solutions["t_ns"].max() == AT_NS - 10_000_000 and len(done.nav.solutions) == 100
    np.testing.assert_array_equal(done.nav.solutions["epoch"], np.arange(100))


@pytest.mark.slow
def test_an_estimator_returning_a_late_epoch_through_the_harness_ends_the_run_with_the_dut_exit(ns, tmp_path):
    pid_file = tmp_path / "pids"
    port = 43471
    dut = DutSpec("external", command=dut_command(ns, port), config={"mode": "late_epoch", "at_s": 1.0,
                                                                    "pid_file": str(pid_file)},
                  startup_timeout_s=60.0, shutdown_timeout_s=60.0)
    spec = RunSpec(scenario=load_scenario(SHORT), tables={"imu": {"grade": "navigation", "rate": "200 Hz"}},
                   schedule=FaultSchedule(), dut=dut, out=tmp_path / "late.mcap", duration_ns=2 * AT_NS,
                   links=LinkSpec(can={"interface": "udp_multicast", "channel": "239.74.164.71", "port": port}),
                   clock=ClockSpec(timeout_s=60.0))
    res = netns.call_in(ns, lambda: run(spec))
    assert res.status == "dut_failed"
    assert "the DUT process exited with code 1" in res.reason
    assert ("harness: the estimator 'misbehave' returned an epoch with time of validity 1.010000 s at the step "
            "1.000000 s: later than the step time") in res.reason
    assert RecordingReader(res.path).read_columnar("/dut/nav_solution")["t_ns"].max() == AT_NS - 10_000_000
    assert any("later than the step time" in text for _, text in log_texts(res.path))
    no_process_left(pid_file)
