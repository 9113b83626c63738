"""The step watchdog (bench.run.watchdog) and what it makes of an in-process estimator that
hangs, floods, exits or runs out of memory (bench.run.inprocess).

A watchdog that fails to stop a step would hang the test itself, so the hanging steps run
in a child process with a generous hang guard (``subprocess.run(timeout=...)``): the
assertions are on what happened (stopped, by which exception, the steps after untouched),
never on how long it took.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

from bench.dut.estimator import Estimator, EstimatorOutput, register_estimator
from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, RunSpec
from bench.run.watchdog import StepTimeout, StepWatchdog
from bench.scenario.loader import load_scenario
from bench.topics import NAV_SOLUTION_DTYPE
from tests.run.robust_util import SHORT, TABLES

GUARD_S = 120.0  # a hang guard for the child, not a speed bound


def _child(code: str) -> list[str]:
    """Run ``code`` in a fresh interpreter; its stdout lines."""
    p = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                       timeout=GUARD_S)
    assert p.returncode == 0, p.stdout + p.stderr
    return p.stdout.split()


@pytest.mark.parametrize("hang", ["time.sleep(3600)", "while True: pass", "threading.Event().wait()",
                                  "swallow()"])
def test_a_step_that_hangs_in_the_main_thread_is_stopped_and_the_steps_after_run(hang):
    out = _child(f"""
        import signal, threading, time
        from bench.run.watchdog import StepTimeout, StepWatchdog
        def swallow():  # an estimator catching every Exception: the timeout is no Exception
            while True:
                try:
                    time.sleep(3600)
                except Exception:
                    pass
        mine = lambda s, f: None
        signal.signal(signal.SIGALRM, mine)
        with StepWatchdog(0.3) as dog:
            try:
                with dog.step():
                    {hang}
                print("not-stopped")
            except StepTimeout:
                print("stopped")
            n = 0
            for _ in range(100000):
                with dog.step():
                    n += 1
            print("after", n)
        print("handler-restored", signal.getsignal(signal.SIGALRM) is mine)
    """)
    assert out == ["stopped", "after", "100000", "handler-restored", "True"]


def test_a_step_that_hangs_in_another_thread_is_stopped_and_the_steps_after_run():
    out = _child("""
        import threading
        from bench.run.watchdog import StepTimeout, StepWatchdog
        said = []
        def worker():
            with StepWatchdog(0.3) as dog:
                try:
                    with dog.step():
                        while True:
                            pass
                except StepTimeout:
                    said.append("stopped")
                n = 0
                for _ in range(100000):
                    token = dog.arm()
                    n += 1
                    dog.disarm(token)
                said.append(f"after {n}")
        t = threading.Thread(target=worker)
        t.start()
        t.join()
        print(" ".join(said))
    """)
    assert out == ["stopped", "after", "100000"]


def test_steps_in_time_are_never_stopped():
    with StepWatchdog(5.0) as dog:
        for _ in range(200_000):
            with dog.step():
                pass
        assert not dog.fired


def test_the_watchdog_needs_a_positive_timeout():
    with pytest.raises(ValueError, match="positive"):
        StepWatchdog(0.0)


def test_the_timeout_is_no_exception_an_estimator_can_swallow():
    assert issubclass(StepTimeout, BaseException) and not issubclass(StepTimeout, Exception)


def test_the_watchdog_leaves_the_signal_handler_as_it_found_it_outside_the_main_thread():
    before = signal.getsignal(signal.SIGALRM)
    done = []

    def worker():
        with StepWatchdog(1.0) as dog, dog.step():
            done.append(True)

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert done == [True] and signal.getsignal(signal.SIGALRM) is before


# ------------------------------------------------------------- in-process estimators
class _Misbehaves(Estimator):
    """Behaves until 1 s, then does what ``config["how"]`` says."""

    name = "misbehaves_at_1s"

    def configure(self, config):
        self.how = config["how"]

    def step(self, inputs):
        n = 1
        if inputs.t_ns >= 1_000_000_000:
            if self.how == "hang":
                import time

                time.sleep(3600)
            elif self.how == "exit":
                sys.exit(7)
            elif self.how == "memory":
                raise MemoryError("cannot allocate the covariance")
            elif self.how == "flood":
                n = 5000
        sol = np.zeros(n, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol)


def _run(tmp_path, how: str):
    register_estimator(_Misbehaves.name, _Misbehaves)
    spec = RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(),
                   dut=DutSpec("in_process", name=_Misbehaves.name, config={"how": how}),
                   out=tmp_path / f"{how}.mcap", duration_ns=2_000_000_000, clock=ClockSpec(timeout_s=0.5))
    return run(spec)


@pytest.mark.parametrize(
    ("how", "status", "reason"),
    [
        ("hang", "dut_failed", "did not return from its step at bench time 1.000 s within the step timeout of 0.5 s"),
        ("exit", "dut_failed", "called exit(7) at bench time 1.000 s"),
        ("flood", "dut_failed", "floods: 5000 epochs (solutions and qualities) in the step at bench time 1.000 s "
                                "(limit 200"),
        ("memory", "dut_error", "raised MemoryError at bench time 1.000 s (it runs in the bench's process, so the "
                                "bench cannot tell"),
    ],
)
def test_an_in_process_estimator_that_hangs_exits_floods_or_runs_out_of_memory_ends_the_run_saying_so(
        tmp_path, how, status, reason):
    before = signal.getsignal(signal.SIGALRM)
    res = _run(tmp_path, how)
    assert res.status == status and reason in res.reason, (res.status, res.reason)
    with RecordingReader(res.path) as r:
        assert r.intact and r.metadata()["run_end"]["status"] == status
        sol = r.read_columnar("/dut/nav_solution")
    assert sol["t_ns"].max() == 990_000_000 and len(sol) == 100  # every epoch of the steps before
    assert signal.getsignal(signal.SIGALRM) is before  # the watchdog's handler is gone with the run
