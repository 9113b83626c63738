"""A misbehaving external DUT for the run engine's robustness tests.

It is the bench's reference harness (:mod:`bench.dut.harness`) around an estimator that
behaves (one NAV_SOLUTION per step) until bench time ``at_s`` and then does what its
``mode`` says. Mode and time come from the DUT configuration file (``{config}``)::

    crash_exit    print to stdout and stderr, then exit with code 3
    crash_abort   print, then abort (SIGABRT)
    crash_raise   raise RuntimeError (traceback on stderr, exit code 1)
    sigkill       SIGKILL itself, as the kernel's OOM killer or an operator would
    late_epoch    return an epoch 10 ms later than the step time (the harness exits, code 1)
    hang          stop answering (sleep), still alive
    flood         send ``flood_frames`` NAV_SOLUTION frames per step from then on
    exit_at_once  exit with code 2 before opening any link
    never_ready   never open the links (sleeps), so it never answers
    ignore_term   ignore SIGTERM and start a child that ignores it too; otherwise fine
    slow          behave, but take ``delay_s`` of wall time per step (long runs)
    daemon        start a daemon at start-up (``sleep 600``: double fork and ``setsid``,
                  spawn_daemon.py; its id appended to ``pid_file``), then behave

``daemon = true`` starts the daemon in any mode (before the mode's misbehaviour).

``pid_file``: where to write this process's id (and the child's, for ``ignore_term``),
one per line, as soon as it starts. ``progress_file``: rewritten with the bench time
reached (s) every second of bench time.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np

from bench.dut import harness
from bench.dut.estimator import DutInputs, Estimator, EstimatorOutput, register_estimator
from bench.topics import NAV_SOLUTION_DTYPE

MODES = ("crash_exit", "crash_abort", "crash_raise", "sigkill", "late_epoch", "hang", "flood", "exit_at_once",
         "never_ready", "ignore_term", "slow", "daemon")


def _say(text: str, stream=sys.stdout) -> None:
    print(text, file=stream, flush=True)


class Misbehave(Estimator):
    """Fine until ``at_s``, then the configured misbehaviour."""

    name = "misbehave"

    def configure(self, config):
        self.mode = config["mode"]
        assert self.mode in MODES, self.mode
        self.at_ns = round(float(config.get("at_s", 0.0)) * 1e9)
        self.flood_frames = int(config.get("flood_frames", 1000))
        self.delay_s = float(config.get("delay_s", 0.0))
        self.pid_file = config.get("pid_file")
        self.progress_file = config.get("progress_file")
        self._write_pids(os.getpid())
        _say(f"misbehave: pid {os.getpid()}, mode {self.mode} at {self.at_ns / 1e9:g} s")
        if self.mode == "exit_at_once":
            _say("misbehave: cannot open the IMU device: no such file", sys.stderr)
            sys.exit(2)
        if (self.mode == "daemon" or config.get("daemon")) and self.pid_file:
            from spawn_daemon import start_daemon  # beside this script

            _say(f"misbehave: started daemon {start_daemon(self.pid_file)}")
        if self.mode == "never_ready":
            _say("misbehave: warming up the gyros ...")
            time.sleep(600)
        self.started = False
        self.epoch = 0

    def _write_pids(self, *pids: int) -> None:
        if self.pid_file:
            with open(self.pid_file, "a") as fh:
                fh.write("".join(f"{p}\n" for p in pids))

    def _start_ignoring(self) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the harness had installed its own handler
        code = "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(600)"
        child = subprocess.Popen([sys.executable, "-c", code])
        self._write_pids(child.pid)
        _say(f"misbehave: ignoring SIGTERM, child {child.pid}")

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        t = inputs.t_ns
        if not self.started:
            self.started = True
            if self.mode == "ignore_term":
                self._start_ignoring()
        if self.delay_s:
            time.sleep(self.delay_s)
        if self.progress_file and t % 1_000_000_000 == 0:
            with open(self.progress_file, "w") as fh:
                fh.write(f"{t / 1e9:g}\n")
        n = 1
        if t >= self.at_ns:
            if self.mode == "crash_exit":
                _say(f"misbehave: step {t / 1e9:.2f} s")
                _say("misbehave: fatal: gyro channel X saturated", sys.stderr)
                sys.exit(3)
            if self.mode == "crash_abort":
                _say("misbehave: assertion failed in the filter update", sys.stderr)
                os.abort()
            if self.mode == "crash_raise":
                raise RuntimeError(f"filter diverged at {t / 1e9:.2f} s")
            if self.mode == "sigkill":
                os.kill(os.getpid(), signal.SIGKILL)
            if self.mode == "hang":
                _say(f"misbehave: hanging at {t / 1e9:.2f} s")
                time.sleep(600)
            if self.mode == "flood":
                n = self.flood_frames
        sol = np.zeros(n, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = t + 10_000_000 if t >= self.at_ns and self.mode == "late_epoch" else t
        sol["epoch"] = (self.epoch + np.arange(n)) % 256
        self.epoch += n
        return EstimatorOutput(sol)


if __name__ == "__main__":
    register_estimator("misbehave", Misbehave)
    sys.exit(harness.main())
